"""The whole OpenPLC v3 output path on the bench, with I2C faults: the controller in the
bench's soft PLC scanned one scan at a time (stepped_controller.py), the PSM's PCA9685Driver
(plc_project/psm/arm_io_psm.py) polled once after every scan over the process image
(psm_script.ImageVars: what OpenPLC's psm module does), the PCA9685 model on a bus that can
fail, and an MG996R model on each arm channel.

The PSM raises PwmDriverFault (%IX0.1) for the cycle whose writes failed and, at its next
cycle, re-initialises the chip and writes every channel's present word. The chip keeps its
registers meanwhile, so the servo holds the last pulse the chip took. Checked: the chip's
pulse never steps by more than the output stage's step limit plus one PWM count (the word's
rounding), whatever the fault's length, and the servos never move faster than that."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
from stepped_controller import (
    ARM_CHANNELS,
    CHANNELS,
    HELLO,
    JOG_START,
    MOVE_JOINTS,
    MOVE_JOINTS_PROFILE,
    OK,
    Client,
    OutputMonitor,
    SteppedController,
    load_controller,
)

from armbench.plant.pca9685 import PCA9685
from armbench.plant.servo import MG996R
from armbench.softplc.loader import LoadedProgram
from psm_script import ImageVars, SimBus, load_psm_script

DRIVER_FAULT = 111
ADDR = 0x40
DT = 0.01


@dataclass
class FlakyBus(SimBus):
    """SimBus whose every transfer fails while ``down``."""

    down: bool = False

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Any) -> None:
        if self.down:
            raise OSError(121, "Remote I/O error")
        super().write_i2c_block_data(i2c_addr, register, data)


@dataclass
class Chain:
    ctl: SteppedController
    out: OutputMonitor
    client: Client
    chip: PCA9685
    bus: FlakyBus
    driver: Any
    servos: list[MG996R] = field(
        default_factory=lambda: [MG996R() for _ in range(ARM_CHANNELS)])
    prev: list[float] = field(default_factory=lambda: [0.0] * ARM_CHANNELS)
    angles: list[list[float]] = field(default_factory=lambda: [[] for _ in range(ARM_CHANNELS)])
    problems: list[str] = field(default_factory=list)

    @property
    def tick(self) -> float:
        return (self.chip.prescale + 1) / 25e6 * 1e6

    def scans(self, n: int) -> None:
        for _ in range(n):
            self.ctl.step()
            self.driver.poll()  # the PSM cycle between this scan and the next
            for c in range(ARM_CHANNELS):
                p = self.chip.pulse_width_us(c)
                vstep = self.out.limits(self.ctl, c)[0]
                if p > 0.0 and self.prev[c] > 0.0 \
                        and abs(p - self.prev[c]) > vstep + self.tick + 1e-6:
                    self.problems.append(
                        f"scan {self.ctl.scan} {CHANNELS[c]}: the chip's pulse "
                        f"{self.prev[c]:.2f} -> {p:.2f} us, limit {vstep:.2f} us + one count")
                if p > 0.0:
                    self.prev[c] = p
                self.servos[c].step(DT, p if p > 0.0 else None)
                self.angles[c].append(self.servos[c].angle_deg)

    def command(self, code: int, int1: int = 0, args: tuple[float, ...] = ()) -> int:
        self.client.send(code, int1=int1, args=args)
        self.scans(1)
        result = self.client.result()
        assert result is not None, self.ctl.scan_commands()
        return result

    def worst_scan_move(self) -> list[float]:
        """Per servo, the largest move in one scan over the run, deg."""
        return [max((abs(a[k] - a[k - 1]) for k in range(1, len(a))), default=0.0)
                for a in self.angles]


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@pytest.fixture
def chain(program: LoadedProgram) -> Iterator[Chain]:
    psm = load_psm_script("arm_io_psm_fault_chain")
    ctl = SteppedController(program)
    out = OutputMonitor()
    ctl.observers.append(out)
    client = Client(ctl, 1, 7171)
    chip = PCA9685(address=ADDR)
    bus = FlakyBus(chip)
    driver = psm.PCA9685Driver(bus=bus, plc=ImageVars(ctl.program.image, ctl.plc.lock),
                               address=ADDR, sleep=chip.advance, log=lambda _m: None)
    c = Chain(ctl, out, client, chip, bus, driver)
    assert c.command(HELLO) == OK
    assert c.command(MOVE_JOINTS, args=(0.0, 80.0, 60.0)) == OK
    c.scans(150)
    yield c


def limit_deg(c: Chain, channel: int) -> float:
    vstep = c.out.limits(c.ctl, channel)[0]
    return (vstep + c.tick) * c.servos[channel].params.deg_per_us + 1e-9


@pytest.mark.parametrize("down_scans", [1, 2, 30, 100])
@pytest.mark.parametrize("motion", ["joints", "profile4", "jog"])
def test_an_i2c_fault_in_a_motion_makes_no_servo_jump(chain: Chain, motion: str,
                                                      down_scans: int) -> None:
    c = chain
    if motion == "joints":
        assert c.command(MOVE_JOINTS, args=(40.0, 50.0, 100.0)) == OK
    elif motion == "profile4":
        assert c.command(MOVE_JOINTS_PROFILE, int1=4,
                         args=(40.0, 50.0, 100.0, 150.0, 1000.0, 8000.0)) == OK
    else:
        assert c.command(JOG_START, args=(1.0, 0.0, 0.0, 80.0, 500.0)) == OK
    c.scans(20)
    c.bus.down = True
    c.scans(down_scans)
    c.bus.down = False
    c.scans(150)
    assert c.problems == [], "\n".join(c.problems[:10])
    assert int(c.ctl.read("MOTIONERRORID")) == DRIVER_FAULT
    held = [c.chip.pulse_width_us(k) for k in range(3)]
    c.scans(50)
    assert [c.chip.pulse_width_us(k) for k in range(3)] == held  # nothing moves by itself
    assert c.command(MOVE_JOINTS, args=(-20.0, 70.0, 65.0)) == OK
    c.scans(300)
    assert c.problems == [], "\n".join(c.problems[:10])
    assert not c.out.violations, c.out.failure()
    worst = c.worst_scan_move()
    for k in range(3):
        assert worst[k] <= limit_deg(c, k), (CHANNELS[k], worst[k], limit_deg(c, k))
    print(f"\n{motion}, bus down {down_scans} scans: worst servo move in one scan "
          + ", ".join(f"{CHANNELS[k]} {worst[k]:.2f}" for k in range(3)) + " deg")


def test_a_flapping_bus_makes_no_servo_jump(chain: Chain) -> None:
    c = chain
    for k in range(200):
        c.bus.down = k % 5 in (1, 2) or k % 11 == 0
        if k % 9 == 0:
            c.client.send(MOVE_JOINTS, args=(-40.0 + k % 80, 60.0 + k % 30, 70.0))
        c.scans(1)
    c.bus.down = False
    c.scans(300)
    assert c.problems == [], "\n".join(c.problems[:10])
    assert not c.out.violations, c.out.failure()
    worst = c.worst_scan_move()
    assert all(worst[k] <= limit_deg(c, k) for k in range(3)), worst
