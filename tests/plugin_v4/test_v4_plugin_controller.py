"""The whole output path on the bench: the controller program in the bench's soft PLC, scanned
one scan at a time (tests/controller/stepped_controller.py), its located variables the image
tables of the stand-in runtime (the scan drains the plugin's journal at its start, as v4's
scan does), the v4 plugin stepped twice per scan (its 5 ms period against the 10 ms task),
the PCA9685 model on the simulated bus, and an MG996R model on each channel.

Checked at every plugin step: each channel of the chip carries the controller's present word
or no pulse; a powered channel's pulse moves by at most the output stage's step limit (plus
one PWM count, the word's rounding); a servo never moves faster over 40 ms than four scans'
steps allow; and the controller's own output monitor stays quiet. Then an I2C fault, at rest
and in the middle of a motion: the controller holds the arm on PwmDriverFault, so after the
fault, Relax and the next move no servo catches up with a motion that went on without it."""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
from v4_rig import ADDR, FakeClock, Loaded
from v4_standin import REPO, SimI2CBus, StandInRuntime, controller_locations

from armbench.plant.pca9685 import PCA9685
from armbench.plant.servo import MG996R
from armbench.softplc.loader import LoadedProgram

if str(REPO / "tests" / "controller") not in sys.path:
    sys.path.append(str(REPO / "tests" / "controller"))
from stepped_controller import (  # noqa: E402
    CHANNELS,
    HELLO,
    INIT_PWM,
    MOVE_JOINTS,
    OK,
    RELAX,
    Client,
    OutputMonitor,
    SteppedController,
    load_controller,
)

WINDOW_STEPS = 8  # 40 ms of plugin steps: four scans
DRIVER_FAULT = 111  # the controller's answer while PwmDriverFault holds the arm
DEADBAND_US = 5.0  # MG996R data sheet (the servo model's default)


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@dataclass
class Path:
    """Controller -> image -> plugin -> chip -> servos, advanced together."""

    ctl: SteppedController
    out: OutputMonitor
    client: Client
    runtime: StandInRuntime
    plugin: Any
    chip: PCA9685
    bus: SimI2CBus
    clock: FakeClock
    servos: list[MG996R] = field(default_factory=lambda: [MG996R() for _ in CHANNELS])
    prev: list[float] = field(default_factory=lambda: [0.0] * len(CHANNELS))
    angles: list[list[float]] = field(default_factory=lambda: [[] for _ in CHANNELS])
    torque: list[list[bool]] = field(default_factory=lambda: [[] for _ in CHANNELS])
    problems: list[str] = field(default_factory=list)
    steps: int = 0
    checking: bool = True  # the chip-word check (off while the chip cannot be reached)

    @property
    def tick(self) -> float:
        return (self.chip.prescale + 1) / 25e6 * 1e6

    def words(self) -> list[int]:
        return [int(self.ctl.program.image.qw[c]) for c in range(len(CHANNELS))]

    def scans(self, n: int) -> None:
        for _ in range(n):
            t_scan = self.ctl.now_ns / 1e9
            self.ctl.step()
            for offset in (0.001, 0.006):
                self.clock.t = max(self.clock.t, t_scan + offset)
                self.plugin.step(self.clock())
                self._observe()

    def command(self, code: int, args: tuple[float, ...] = (), max_scans: int = 50) -> int:
        self.client.send(code, args=args)
        for _ in range(max_scans):
            self.scans(1)
            result = self.client.result()
            if result is not None:
                return result
        raise AssertionError(f"no answer to command {code} in {max_scans} scans")

    def _observe(self) -> None:
        self.steps += 1
        words = self.words()
        for c, servo in enumerate(self.servos):
            p = self.chip.pulse_width_us(c)
            w = words[c]
            if self.checking and p > 0.0:
                if w & 0x1000 or w == 0 or round(p / self.tick) != w:
                    self.problems.append(f"step {self.steps} {CHANNELS[c]}: chip {p:.2f} us, "
                                         f"controller word {w}")
                if self.prev[c] > 0.0:
                    vstep = self.out.limits(self.ctl, c)[0]
                    if abs(p - self.prev[c]) > vstep + self.tick + 1e-6:
                        self.problems.append(
                            f"step {self.steps} {CHANNELS[c]}: {self.prev[c]:.2f} -> {p:.2f} us,"
                            f" limit {vstep:.2f} us + one count")
            self.prev[c] = p
            servo.step(0.005, p if p > 0.0 else None)
            self.angles[c].append(servo.angle_deg)
            self.torque[c].append(servo.torque_on)

    def servo_jumps(self, skip: range = range(0)) -> list[str]:
        """40 ms windows in which a powered servo moved more than four scans' steps allow."""
        found = []
        for c, servo in enumerate(self.servos):
            vstep = self.out.limits(self.ctl, c)[0]
            limit = (4 * vstep + 2 * self.tick + DEADBAND_US) * servo.params.deg_per_us
            a, on = self.angles[c], self.torque[c]
            for k in range(WINDOW_STEPS, len(a)):
                if k in skip or not all(on[k - WINDOW_STEPS:k + 1]):
                    continue
                if abs(a[k] - a[k - WINDOW_STEPS]) > limit + 1e-9:
                    found.append(f"{CHANNELS[c]} at step {k}: {a[k - WINDOW_STEPS]:.2f} -> "
                                 f"{a[k]:.2f} deg in 40 ms, limit {limit:.2f}")
        return found

    def flags(self) -> tuple[bool, bool]:
        ix = self.ctl.program.image.ix
        return bool(ix[0]), bool(ix[1])


@pytest.fixture
def path(loaded: Loaded, program: LoadedProgram) -> Iterator[Path]:
    ctl = SteppedController(program)
    out = OutputMonitor()
    ctl.observers.append(out)
    client = Client(ctl, 1, 4242)
    assert client.command(HELLO) == OK
    runtime = StandInRuntime(program.image, controller_locations(), lock=ctl.plc.lock,
                             config_path=loaded.tree.line.config_path)
    ctl.plc.io = runtime  # v4: the scan applies the plugins' journal at its start
    clock = FakeClock(t=ctl.now_ns / 1e9)
    chip = PCA9685(address=ADDR)
    bus = SimI2CBus(pca=chip, clock=clock)
    loaded.smbus2.BUSES[1] = bus
    module, shared = loaded.module, loaded.shared
    assert module.set_image_sizes(runtime.image_sizes()) == 0
    settings, _ = module.Settings.from_map({"imu_enabled": False}, loaded.psm)
    sink = module.runtime_log_sink(shared.PluginLogger(module.LOG_NAME, runtime))
    plugin = module.ArmIoPlugin.create(loaded.psm, settings, shared.SafeBufferAccess(runtime),
                                       sink, clock=clock, sleep=clock.sleep)
    p = Path(ctl, out, client, runtime, plugin, chip, bus, clock)
    p.scans(5)
    assert p.flags() == (True, False), runtime.shown()
    yield p
    plugin.stop()


def settle(p: Path, base: float, shoulder: float, elbow: float, scans: int = 300) -> None:
    assert p.command(MOVE_JOINTS, (base, shoulder, elbow)) == OK, p.ctl.scan_commands()
    p.scans(scans)


def test_controller_through_plugin_to_servos_never_jumps(path: Path) -> None:
    p = path
    assert p.command(INIT_PWM) == OK
    assert p.chip.prescale == int(p.ctl.read("PWMPRESCALE")) == 121
    writes_before = len(p.bus.writes_to(ADDR))
    settle(p, 0.0, 70.0, 65.0)
    settle(p, 30.0, 50.0, 90.0)
    assert p.command(RELAX) == OK
    p.scans(30)
    assert [p.chip.pulse_width_us(c) for c in range(3)] == [0.0] * 3
    settle(p, -20.0, 60.0, 80.0)
    assert p.problems == [], "\n".join(p.problems[:10])
    assert p.servo_jumps() == [], "\n".join(p.servo_jumps()[:10])
    assert not p.out.violations, p.out.failure()
    # the servos are where the controller put them: the chip's pulse, through the servo model
    for c in range(3):
        want = p.servos[c].params.angle_for_pulse(p.ctl.pulses()[c])
        assert p.servos[c].angle_deg == pytest.approx(want, abs=0.6)  # one count: 0.59 deg
    # only changed channels went over the bus: at most one block write per scan
    led_writes = [r for r, _d in p.bus.writes_to(ADDR)[writes_before:] if 0x06 <= r <= 0x45]
    assert len(led_writes) <= p.ctl.scan
    assert p.flags() == (True, False) and p.runtime.format_faults == []


def test_an_i2c_fault_holds_the_arm_and_it_comes_back_through_relax(path: Path) -> None:
    p = path
    settle(p, 10.0, 60.0, 80.0)
    held = [p.chip.pulse_width_us(c) for c in range(3)]
    # at rest (nothing to write): the bus fails for 1.5 s; the plugin sees it at its next
    # read-back of MODE1 (once per retry_s); the chip cannot be told anything, keeps its pulses
    p.bus.down = True
    p.checking = False
    p.scans(150)
    assert [p.chip.pulse_width_us(c) for c in range(3)] == held
    assert p.flags() == (False, True)
    p.bus.down = False
    p.scans(120)  # the retry (1 s) re-initialises the chip: every servo relaxed
    assert p.chip.running and p.chip.pulse_widths_us() == (0.0,) * 16
    assert p.flags() == (True, True), "\n".join(t for _l, t in p.runtime.lines[-12:])
    p.checking = True
    assert p.command(RELAX) == OK
    p.scans(3)
    assert p.flags() == (True, False)
    settle(p, 10.0, 60.0, 80.0, scans=100)  # powered again where it was relaxed: no motion
    assert [p.chip.pulse_width_us(c) for c in range(3)] == pytest.approx(held)

    # in the middle of a motion
    start = p.steps
    assert p.command(MOVE_JOINTS, (-30.0, 90.0, 50.0)) == OK
    p.scans(10)
    p.bus.down = True
    p.checking = False
    reached = [p.chip.pulse_width_us(c) for c in range(3)]  # what the chip keeps
    p.scans(30)
    # the controller holds the arm on PwmDriverFault: the motion ended, nothing moves, and
    # a new motion is refused to its client
    assert int(p.ctl.read("MOTIONERRORID")) == DRIVER_FAULT
    assert int(p.ctl.read("DRIVERFAULTHELD")) == 1
    frozen = list(p.ctl.pulses()[:3])
    assert p.command(MOVE_JOINTS, (10.0, 60.0, 80.0)) == DRIVER_FAULT
    p.bus.down = False
    p.scans(250)  # the chip is re-initialised, relaxed; the plugin holds the servos relaxed
    assert p.chip.pulse_widths_us() == (0.0,) * 16 and p.flags() == (True, True)
    assert list(p.ctl.pulses()[:3]) == frozen
    assert p.command(MOVE_JOINTS, (10.0, 60.0, 80.0)) == DRIVER_FAULT
    p.checking = True
    relaxed_at = list(p.ctl.pulses()[:3])  # the output stage's pulses, not on the chip
    assert p.command(RELAX) == OK
    p.scans(3)
    assert p.flags() == (True, False)
    repowered = p.steps
    settle(p, -30.0, 90.0, 50.0, scans=200)
    # the plugin passed the controller's words through unchanged (p.problems), the output
    # stage powered each servo at the pulse it relaxed it at (p.out), which is where the chip
    # left the servo (the stage stood still from the scan that read the fault: one step
    # beyond at most), and the move went on from there to its end
    assert p.problems == [], "\n".join(p.problems[:10])
    assert not p.out.violations, p.out.failure()
    for c in range(3):
        assert p.chip.pulse_width_us(c) == pytest.approx(p.ctl.pulses()[c], abs=p.tick)
        vstep = p.out.limits(p.ctl, c)[0]
        assert abs(relaxed_at[c] - reached[c]) <= vstep + p.tick, (CHANNELS[c], reached[c],
                                                                     relaxed_at[c])
    # everywhere, the re-power too, the servos keep to the stage's limits: no catch-up
    assert p.servo_jumps() == [], "\n".join(p.servo_jumps()[:10])
    for c in range(3):
        gap = abs(relaxed_at[c] - reached[c]) * p.servos[c].params.deg_per_us
        print(f"\n{CHANNELS[c]}: the stage stood {gap:.2f} deg from the chip's last pulse "
              f"after the mid-motion fault")
    assert start < repowered
    assert math.isfinite(sum(p.prev))
