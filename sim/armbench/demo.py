"""``armbench demo``: the 360-point circle of SEEDS document 000, driven over Modbus.

Compiles the library and ``plc_project/Controller.st``, runs the soft PLC in real time with
its Modbus server on a free loopback port, and talks to it only through Modbus: one command
per point with the request/acknowledge handshake. Each point's 16 PCA9685 words go into the
PCA9685 device model, its pulse widths into three MG996R servo models, and the settled servo
angles through the numpy reference kinematics: the achieved tool position, compared with the
commanded one (the difference includes the 12-bit PWM quantisation).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TextIO

from .controller_client import ArmControllerClient
from .plant import arm
from .plant.pca9685 import PCA9685
from .plant.servo import MG996R
from .registermap import SOURCES
from .softplc.loader import load_program
from .softplc.modbus_client import PlcClient
from .softplc.modbus_server import ModbusServer
from .softplc.scan import SoftPlc

# Servo zero offsets of Controller.st (ShoulderZeroDeg, ElbowZeroDeg; Base 0): joint angle =
# servo angle + offset. Channels 0, 1, 2 = Base, Shoulder, Elbow.
JOINT_ZERO_DEG = (0.0, 70.0, 65.0)
SERVO_CHANNELS = (0, 1, 2)
PCA9685_ADDRESS = 0x40


@dataclass
class RunningPlc:
    plc: SoftPlc
    server: ModbusServer
    host: str
    port: int


@contextmanager
def serve_controller(host: str = "127.0.0.1", port: int = 0) -> Iterator[RunningPlc]:
    """Soft PLC (real-time thread) + Modbus server with the controller; stops both on exit."""
    prog = load_program(list(SOURCES))
    plc = SoftPlc(prog)
    server = ModbusServer(prog.image, plc.lock, host=host, port=port)
    server.start()
    try:
        plc.start()
        try:
            yield RunningPlc(plc, server, host, server.port)
        finally:
            plc.stop()
    finally:
        server.stop()


def circle(n: int, centre: tuple[float, float, float], radius: float,
           plane: str) -> list[tuple[float, float, float]]:
    """n points on a circle; plane "xy" (horizontal) or "xz" (vertical)."""
    cx, cy, cz = centre
    pts = []
    for i in range(n):
        t = 2.0 * math.pi * i / n
        u, v = radius * math.cos(t), radius * math.sin(t)
        pts.append((cx + u, cy + v, cz) if plane == "xy" else (cx + u, cy, cz + v))
    return pts


class Plant:
    """PCA9685 model + three MG996R models + reference kinematics."""

    def __init__(self) -> None:
        self.pca = PCA9685(address=PCA9685_ADDRESS)
        self.servos = [MG996R() for _ in SERVO_CHANNELS]
        self.settle_s = 0.0

    def apply_init_frames(self, frames: Sequence[tuple[int, int]]) -> None:
        for i, (register, data) in enumerate(frames, start=1):
            self.pca.write(PCA9685_ADDRESS, register, bytes((data,)))
            # frame 4 wakes the oscillator: the controller waits >= 1 ms before frame 5
            self.pca.advance(0.001 if i == 4 else 0.0001)

    def drive(self, words: Sequence[int], dt_s: float = 0.02,
              max_s: float = 5.0) -> tuple[float, float, float]:
        """Load the words, run the servos until they settle; returns the joint angles."""
        self.pca.load_off_counts(list(words))
        pulses = [self.pca.pulse_width_us(ch) for ch in SERVO_CHANNELS]
        t = 0.0
        while True:
            for servo, pulse in zip(self.servos, pulses, strict=True):
                servo.step(dt_s, pulse if pulse > 0.0 else None)
            t += dt_s
            if not any(s.moving for s in self.servos) or t >= max_s:
                break
        self.settle_s += t
        a = [s.angle_deg + z for s, z in zip(self.servos, JOINT_ZERO_DEG, strict=True)]
        return a[0], a[1], a[2]


def _bar(done: int, total: int, width: int = 40) -> str:
    filled = width * done // total
    return f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


def run(points: int = 360, radius: float = 40.0, plane: str = "xy",
        centre: tuple[float, float, float] = (150.0, 0.0, 120.0),
        out: TextIO | None = None) -> int:
    stream = out if out is not None else sys.stdout
    write = stream.write
    t0 = time.perf_counter()
    with serve_controller() as running:
        compile_s = time.perf_counter() - t0
        write(f"soft PLC running (10 ms task), Modbus on {running.host}:{running.port}; "
              f"compile+load {compile_s:.2f} s\n")
        plant = Plant()
        with PlcClient(running.host, running.port) as modbus:
            ctl = ArmControllerClient(modbus)
            st = ctl.init_pwm()
            if st.error_id != 0:
                write(f"PCA9685 init failed: ErrorId {st.error_id}\n")
                return 1
            plant.apply_init_frames(ctl.init_frames())
            write(f"PCA9685 initialised: prescale {st.prescale}, "
                  f"{plant.pca.update_rate_hz:.2f} Hz, running={plant.pca.running}\n")
            running.plc.reset_stats()
            errs: list[float] = []
            echo_errs: list[float] = []
            failures = 0
            pts = circle(points, centre, radius, plane)
            t_start = time.perf_counter()
            for i, p in enumerate(pts, start=1):
                st = ctl.move_xyz(*p)
                if st.error_id != 0:
                    failures += 1
                    continue
                words = ctl.channel_words()
                joints = plant.drive(words)
                achieved = arm.forward(*joints)
                errs.append(math.dist(p, achieved))
                echo_errs.append(math.dist(p, st.echo_mm))
                if i % 4 == 0 or i == points:
                    write(_bar(i, points))
                    stream.flush()
            elapsed = time.perf_counter() - t_start
            write("\n")
            stats = running.plc.stats()
    write(f"points: {points} on a circle centre {centre} mm radius {radius} mm, plane {plane}; "
          f"rejected: {failures}\n")
    if errs:
        write(f"|commanded - achieved| (PWM + servo + reference FK): "
              f"max {max(errs):.3f} mm, mean {sum(errs) / len(errs):.3f} mm\n")
        write(f"|commanded - FK echo| (PLC REAL arithmetic): max {max(echo_errs):.5f} mm\n")
    write(f"throughput: {points / elapsed:.1f} points/s ({elapsed:.2f} s, "
          f"{ctl.polls} status polls); simulated servo settle time {plant.settle_s:.1f} s\n")
    for s in stats.values():
        write(f"PLC task {s.name}: {s.scans} scans every {s.interval_ns / 1e6:g} ms, "
              f"overruns {s.overruns}, execution mean {s.execution.mean_ns / 1e3:.1f} us "
              f"max {s.execution.max_ns / 1e3:.1f} us, jitter p50 {s.jitter.p50_ns / 1e3:.1f} us "
              f"p99 {s.jitter.p99_ns / 1e3:.1f} us max {s.jitter.max_ns / 1e3:.1f} us\n")
    ok = failures == 0 and bool(errs) and max(echo_errs) <= 0.05
    return 0 if ok else 1


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="armbench demo", description=__doc__)
    add_arguments(p)
    a = p.parse_args(argv)
    return run(points=a.points, radius=a.radius, plane=a.plane)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--points", type=int, default=360, help="points on the circle (360)")
    p.add_argument("--radius", type=float, default=40.0, help="mm (40)")
    p.add_argument("--plane", choices=("xy", "xz"), default="xy",
                   help="xy horizontal (default) or xz vertical, centre (150, 0, 120) mm")


if __name__ == "__main__":
    sys.exit(main())
