"""``armbench demo``: the 360-point circle of document 000, driven over Modbus.

Compiles the library and ``plc_project/Controller.st``, runs the soft PLC in real time with
its Modbus server on a free loopback port, and talks to it only through Modbus. The servo
calibration is read back from the PLC (one copy of the zero offsets: the program's). The whole
path is first checked with SolveBatch commands (32 points per scan), then driven with one
MoveXyz per point (request/acknowledge handshake): the motion layer turns each into a
synchronised joint move through the slew-limited output stage, and the client waits for it to
end; a recorder samples the setpoints every scan for the velocity plot. Each point's 16
PCA9685 words go into the PCA9685 device model, its pulse widths into three MG996R servo
models, and the settled servo angles through the numpy reference kinematics: the achieved tool
position, compared with the commanded one (the difference includes the 12-bit PWM
quantisation). Plots of the run go to ``--out`` (default ``out/demo``) as PNGs.
"""

from __future__ import annotations

import argparse
import math
import sys
import textwrap
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from .controller_client import ArmControllerClient, Calibration, MotionRecorder
from .demo_options import DEFAULT_OUT, add_demo_arguments
from .plant import arm
from .plant.pca9685 import PCA9685
from .plant.servo import MG996R
from .registermap import SOURCES
from .softplc.loader import load_program
from .softplc.modbus_client import PlcClient
from .softplc.modbus_server import ModbusServer
from .softplc.openplc_v4 import V4Settings
from .softplc.scan import SoftPlc, TaskStats
from .softplc.serving import soft_plc

# Channels 0, 1, 2 = Base, Shoulder, Elbow (Controller.st).
SERVO_CHANNELS = (0, 1, 2)
PCA9685_ADDRESS = 0x40


@dataclass
class RunningPlc:
    plc: SoftPlc
    server: ModbusServer
    host: str
    port: int


@contextmanager
def serve_controller(host: str = "127.0.0.1", port: int = 0, flavor: str = "openplc",
                     v4: V4Settings | None = None) -> Iterator[RunningPlc]:
    """Soft PLC (real-time thread) + Modbus server with the controller, serving as
    ``flavor``'s server does (OpenPLC v3's map; ``"openplc-v4"``: OpenPLC v4's Modbus plugin,
    set up by ``v4``; ``"codesys"``: the CODESYS variant's layout); stops both on exit."""
    prog = load_program(list(SOURCES))
    plc, server = soft_plc(prog, flavor, v4=v4, host=host, port=port)
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
    """PCA9685 model + three MG996R models + reference kinematics. ``calibration`` says how
    each servo is mounted (joint angle at servo centre, direction): the PLC's read-back."""

    def __init__(self, calibration: Sequence[Calibration]) -> None:
        self.pca = PCA9685(address=PCA9685_ADDRESS)
        self.servos = [MG996R() for _ in SERVO_CHANNELS]
        self.calibration = list(calibration)
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
        a = [c.servo_to_joint(s.angle_deg)
             for s, c in zip(self.servos, self.calibration, strict=True)]
        return a[0], a[1], a[2]


def _bar(done: int, total: int, width: int = 40) -> str:
    filled = width * done // total
    return f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


@dataclass
class PathRun:
    """What driving a path through PLC and plant gave, point by point."""

    commanded: list[tuple[float, float, float]] = field(default_factory=list)
    achieved: list[tuple[float, float, float]] = field(default_factory=list)
    echo: list[tuple[float, float, float]] = field(default_factory=list)
    joints: list[tuple[float, float, float]] = field(default_factory=list)
    achieved_joints: list[tuple[float, float, float]] = field(default_factory=list)
    pulses: list[tuple[float, float, float]] = field(default_factory=list)
    counts: list[tuple[float, float, float]] = field(default_factory=list)
    rejected: int = 0
    elapsed_s: float = 0.0

    def errors_mm(self) -> list[float]:
        return [math.dist(c, a) for c, a in zip(self.commanded, self.achieved, strict=True)]

    def echo_errors_mm(self) -> list[float]:
        return [math.dist(c, e) for c, e in zip(self.commanded, self.echo, strict=True)]


def drive_path(ctl: ArmControllerClient, plant: Plant,
               points: Sequence[tuple[float, float, float]],
               progress: Callable[[int, int], None] | None = None) -> PathRun:
    """One MoveXyz per point (handshake), waiting until the motion layer has moved the
    servos there, then the plant: PCA9685 words -> pulses -> servo angles -> reference FK.
    Rejected points are counted and skipped."""
    run = PathRun()
    t_start = time.perf_counter()
    for i, p in enumerate(points, start=1):
        st = ctl.move_xyz(*p, wait=True)
        if st.error_id != 0:
            run.rejected += 1
            continue
        words = ctl.channel_words()
        joints = plant.drive(words)
        fk = arm.forward(*joints)
        run.commanded.append(p)
        run.achieved.append((float(fk[0]), float(fk[1]), float(fk[2])))
        run.echo.append(st.echo_mm)
        run.joints.append(st.joints_deg)
        run.achieved_joints.append(joints)
        run.pulses.append(st.pulses_us)
        run.counts.append((words[0] & 0xFFF, words[1] & 0xFFF, words[2] & 0xFFF))
        if progress is not None:
            progress(i, len(points))
    run.elapsed_s = time.perf_counter() - t_start
    return run


def start_plant(ctl: ArmControllerClient) -> tuple[Plant, int]:
    """Read the calibration back, initialise the PCA9685 over Modbus and in the model.
    Returns the plant and the PLC's prescale (or raises with the PLC's ErrorId)."""
    plant = Plant(ctl.calibration())
    st = ctl.init_pwm()
    if st.error_id != 0:
        raise RuntimeError(f"PCA9685 init failed: ErrorId {st.error_id}")
    plant.apply_init_frames(ctl.init_frames())
    return plant, st.prescale


def run(points: int = 360, radius: float = 40.0, plane: str = "xy",
        centre: tuple[float, float, float] = (150.0, 0.0, 120.0),
        out: TextIO | None = None, out_dir: Path | None = DEFAULT_OUT,
        poll_ms: float = 0.5) -> int:
    if points < 1:
        raise ValueError(f"the circle needs at least 1 point, got {points}")
    stream = out if out is not None else sys.stdout
    write = stream.write

    tty = stream.isatty()

    def progress(done: int, total: int) -> None:
        if tty and (done % 4 == 0 or done == total):
            write(_bar(done, total))
            stream.flush()
        elif not tty and (done * 4 // total > (done - 1) * 4 // total):
            write(f"{done}/{total} points\n")  # a log gets a few lines, not a redrawn bar

    t0 = time.perf_counter()
    with serve_controller() as running:
        compile_s = time.perf_counter() - t0
        write(f"soft PLC running (10 ms task), Modbus on {running.host}:{running.port}; "
              f"compile+load {compile_s:.2f} s\n")
        with PlcClient(running.host, running.port) as modbus:
            ctl = ArmControllerClient(modbus, poll_interval_s=poll_ms / 1000.0)
            try:
                plant, prescale = start_plant(ctl)
            except RuntimeError as exc:
                write(f"{exc}\n")
                return 1
            write("servo calibration (read back): " + "; ".join(
                f"{name} zero {c.zero_offset_deg:g} deg dir {c.direction:+d} "
                f"{c.min_pulse_us:g}..{c.max_pulse_us:g} us = "
                f"{c.min_angle_deg:g}..{c.max_angle_deg:g} deg"
                for name, c in zip(("Base", "Shoulder", "Elbow"), plant.calibration,
                                   strict=True)) + "\n")
            write(f"PCA9685 initialised: prescale {prescale}, "
                  f"{plant.pca.update_rate_hz:.2f} Hz, running={plant.pca.running}\n")
            pts = circle(points, centre, radius, plane)
            tb = time.perf_counter()
            checked = ctl.batch_roundtrip(pts)
            batch_s = time.perf_counter() - tb
            unreachable = sum(1 for r in checked if r.error_id != 0)
            batch_echo = max((math.dist(p, r.echo_mm) for p, r in zip(pts, checked, strict=True)
                              if r.error_id == 0), default=math.inf)
            write(f"path check (SolveBatch, {ctl.batch_max} points/command): {points} points in "
                  f"{math.ceil(points / ctl.batch_max)} commands, {batch_s * 1000:.0f} ms, "
                  f"{unreachable} rejected, max |commanded - FK echo| {batch_echo:.5f} mm\n")
            running.plc.reset_stats()
            stats_t0 = time.perf_counter()
            ctl.polls = 0
            # the motion layer's setpoints, every scan, on a connection of their own
            recorder = MotionRecorder(running.host, running.port)
            recorder.start()
            try:
                result = drive_path(ctl, plant, pts, progress)
            finally:
                recording = recorder.stop()
            if tty:
                write("\n")
            stats = running.plc.stats()
            stats_wall_s = time.perf_counter() - stats_t0
    errs = result.errors_mm()
    echo_errs = result.echo_errors_mm()
    write(f"points: {points} on a circle centre {centre} mm radius {radius} mm, plane {plane}; "
          f"rejected: {result.rejected}\n")
    if errs:
        write(f"|commanded - achieved| (PWM + servo + reference FK): "
              f"max {max(errs):.3f} mm, mean {sum(errs) / len(errs):.3f} mm\n")
        write(f"|commanded - FK echo| (PLC REAL arithmetic): max {max(echo_errs):.5f} mm\n")
    write(f"throughput: {points / result.elapsed_s:.1f} points/s ({result.elapsed_s:.2f} s, "
          f"{ctl.polls} answer polls, poll interval {poll_ms:g} ms); "
          f"simulated servo settle time {plant.settle_s:.1f} s\n")
    largest_step: float | None = None
    if recording.samples:
        steps = [max(abs(b.out_deg[j] - a.out_deg[j]) for j in range(3))
                 for a, b in recording.consecutive()]
        largest_step = max(steps, default=0.0)
        peak = max(abs(v) for m in recording.samples for v in m.out_vel)
        write(f"motion layer: {len(recording.samples)} scans recorded ({recording.missed_scans} "
              f"missed), peak joint speed {peak:.1f} deg/s (limit "
              f"{max(recording.samples[0].limit_vel):g}), largest servo step in one scan "
              f"{largest_step:.3f} deg\n")
    for s in stats.values():
        write("".join(line + "\n" for line in scan_report(s, stats_wall_s, largest_step)))
    if out_dir is not None and result.commanded:
        from .plots.demo import demo_plots  # matplotlib is imported only when plotting

        for path in demo_plots(out_dir, result.commanded, result.achieved, result.joints,
                               result.achieved_joints, result.pulses, result.counts):
            write(f"plot: {path}\n")
        if recording.samples:
            from .plots.demo import joint_velocities

            vel_path = joint_velocities([m.scan for m in recording.samples],
                                        [m.set_vel for m in recording.samples],
                                        [m.out_vel for m in recording.samples],
                                        max(recording.samples[0].limit_vel),
                                        out_dir / "velocities.png")
            write(f"plot: {vel_path}\n")
    ok = (result.rejected == 0 and unreachable == 0 and bool(errs) and max(echo_errs) <= 0.05
          and batch_echo <= 0.05)
    return 0 if ok else 1


def _ms(ns: float) -> str:
    """A duration for a reader: microseconds below 1 ms, milliseconds below 1 s, else
    seconds (never an exponent: 1.06e+03 ms reads badly)."""
    if ns < 1e6:
        return f"{ns / 1e3:.0f} us"
    if ns < 999.5e6:
        return f"{ns / 1e6:.3g} ms"
    return f"{ns / 1e9:.3g} s" if ns < 999.5e9 else f"{ns / 1e9:.0f} s"


def scan_report(s: TaskStats, wall_s: float, largest_step_deg: float | None = None
                ) -> list[str]:
    """The task's figures, and what they mean, in plain words: the scan period, jitter, why
    a loaded machine shows large ones and why they do not change the demo's results (the
    controller's time is its scans, not the wall clock). ``wall_s``: the wall-clock time the
    statistics cover; ``largest_step_deg``: the largest servo step in one scan, if recorded."""
    period = _ms(s.interval_ns)
    controller_s = s.scans * s.interval_ns / 1e9
    j = s.jitter
    head = (f"PLC task {s.name}: {s.scans} scans every {period} = {controller_s:.2f} s of the "
            f"controller's time in {wall_s:.2f} s on the wall clock; execution mean "
            f"{_ms(s.execution.mean_ns)}, max {_ms(s.execution.max_ns)}; start jitter p50 "
            f"{_ms(j.p50_ns)}, p99 {_ms(j.p99_ns)}, max {_ms(j.max_ns)}; overruns {s.overruns}")
    if j.max_ns >= s.interval_ns:
        here = (f"Here the worst scan started {_ms(j.max_ns)} late, more than a period: the "
                f"{s.overruns} releases missed were skipped (overruns), not run in a burst, "
                f"which is why the controller's time is behind the wall clock.")
    else:
        here = f"Here even the worst scan started within the {period} period."
    step = ("" if largest_step_deg is None
            else f" (the largest servo step in one scan was {largest_step_deg:.3f} deg)")
    text = [
        f"The scan period, {period} (the TASK's INTERVAL), is how often the soft PLC runs the "
        f"controller's ST; execution is how long one scan took. Jitter is how late a scan "
        f"started against that timetable on this computer's clock: half the scans within "
        f"p50, 99 in 100 within p99, max is the single worst. The soft PLC is a thread of an "
        f"ordinary process, not a real-time runtime, so other work on a loaded or shared "
        f"machine delays it and max reaches tens or hundreds of ms. {here}",
        f"For the arm in this demo that changes nothing but the throughput: the controller "
        f"moves it one fixed {period} step per scan (ScanPeriodS in Controller.st), in its "
        f"own time, so a late scan pauses the motion on the wall clock without making it "
        f"jump{step}, and the servo models settle in simulated time, so the accuracy figures "
        f"are the same on a busy machine. On a real PLC driving real servos the wall clock "
        f"is the servos' clock: there a late scan is a hitch in the motion, and max jitter "
        f"must stay well below the period.",
    ]
    return [head] + [line for para in text
                     for line in textwrap.wrap(para, width=96, initial_indent="  ",
                                               subsequent_indent="  ")]


def run_from_args(a: argparse.Namespace) -> int:
    """Run with the options of :func:`armbench.demo_options.add_demo_arguments`."""
    return run(points=a.points, radius=a.radius, plane=a.plane,
               out_dir=None if a.no_plots else Path(a.out), poll_ms=a.poll_ms)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="armbench demo", description=__doc__)
    add_demo_arguments(p)
    return run_from_args(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
