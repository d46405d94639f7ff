"""Scan time of the controller with each motion block active (prints figures, not
a test).

The packaged controller runs in the soft PLC at its real 10 ms task; a client starts one
motion of each kind (slow enough to last the whole measurement) and the soft PLC's own
execution time of the task (the compiled program's scan, nothing of Python's Modbus side)
is collected over the scans while that motion runs. Figures: median and p99 per scenario,
the extra time over the idle scan, and the longest scan from the command to its answer (the
scan that plans the motion: profile 4 plans its whole trajectory there). Goal: the blocks
together cost < 5 % of the 10 ms scan (500 us).

Run: .venv/bin/python bench/motion_scan_time.py [--scans 150]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass

from armbench.controller_client import ArmControllerClient
from armbench.demo import serve_controller
from armbench.softplc.modbus_client import PlcClient
from armbench.softplc.scan import SoftPlc

SCAN_US = 10_000.0
START = (-50.0, 60.0, 60.0)
FAR = (50.0, 120.0, 110.0)
LINE_A, LINE_B = (140.0, -60.0, 100.0), (140.0, 60.0, 140.0)


@dataclass(frozen=True)
class Figure:
    name: str
    scans: int
    p50_us: float
    p99_us: float
    still_busy: bool
    start_max_us: float = 0.0  # the longest scan from the command to its answer


def measure(plc: SoftPlc, ctl: ArmControllerClient, name: str, scans: int,
            start: Callable[[], object] | None, keep_alive: Callable[[], object] | None = None
            ) -> Figure:
    start_max = 0.0
    if start is not None:
        plc.reset_stats()
        start()
        start_max = next(iter(plc.stats().values())).execution.max_ns / 1e3
    plc.reset_stats()
    t_end = time.monotonic() + scans * SCAN_US / 1e6
    while time.monotonic() < t_end:
        if keep_alive is not None:
            keep_alive()
        time.sleep(0.05)
    task = next(iter(plc.stats().values()))
    busy = ctl.motion().busy if start is not None else True
    return Figure(name, task.execution.count, task.execution.p50_ns / 1e3,
                  task.execution.p99_ns / 1e3, busy, start_max)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", type=int, default=150, help="scans measured per scenario")
    args = ap.parse_args()
    n = args.scans
    figures: list[Figure] = []
    with serve_controller() as running, PlcClient(running.host, running.port) as modbus, \
            ArmControllerClient(modbus) as ctl:
        plc = running.plc

        def home() -> None:
            ctl.stop()
            ctl.wait_motion(timeout_s=30.0)
            ctl.move_joints(*START, wait=True)

        def line_home() -> None:
            ctl.stop()
            ctl.wait_motion(timeout_s=30.0)
            ctl.move_xyz(*LINE_A, wait=True)

        home()
        figures.append(measure(plc, ctl, "idle (no motion)", n, None))
        for profile, label in ((0, "constant speed per joint"), (1, "synchronised speed"),
                               (2, "trapezoid"), (3, "quintic"),
                               (4, "time-optimal jerk-limited")):
            home()
            figures.append(measure(plc, ctl, f"MotionJointMove profile {profile} ({label})", n,
                                   lambda p=profile: ctl.move_joints_profile(
                                       FAR, p, 20.0, 100.0, 1000.0)))
        for method, label in ((0, "Bresenham"), (1, "Bresenham + compensation"),
                              (2, "time-scaled path")):
            line_home()
            figures.append(measure(plc, ctl, f"MotionLinear method {method} ({label})", n,
                                   lambda m=method: ctl.move_linear(LINE_B, 8.0, 50.0, 2.0, m)))
        line_home()
        figures.append(measure(plc, ctl, "MotionJog (stick +y, 10 mm/s)", n,
                               lambda: ctl.jog_start((0.0, 1.0, 0.0), 10.0, 100.0),
                               lambda: ctl.jog_update((0.0, 1.0, 0.0))))
        ctl.jog_stop()
        line_home()
        figures.append(measure(plc, ctl, "MotionJog with a jerk limit (2000 mm/s^3)", n,
                               lambda: ctl.jog_start((0.0, 1.0, 0.0), 10.0, 100.0,
                                                     jerk=2000.0),
                               lambda: ctl.jog_update((0.0, 1.0, 0.0))))
        ctl.jog_stop()
        home()
        ctl.move_joints_profile(FAR, 1, 100.0, 800.0)
        ctl.wait_scans(40)
        figures.append(measure(plc, ctl, "MotionHalt (braking at 100 deg/s^2)", n,
                               lambda: ctl.stop(100.0)))
        ctl.stop()
        ctl.wait_motion(timeout_s=30.0)
        home()
        ctl.move_joints_profile(FAR, 4, 100.0, 800.0, 2000.0)
        ctl.wait_scans(40)
        figures.append(measure(plc, ctl, "MotionHalt jerk-limited (Stop of a profile 4)", n,
                               lambda: ctl.stop(100.0)))
        ctl.stop()
        ctl.wait_motion(timeout_s=30.0)

    idle = figures[0].p50_us
    print(f"controller scan time, soft PLC, 10 ms task, {n} scans per scenario "
          "(execution of the compiled scan: median / p99, extra over idle at the median)")
    for f in figures:
        flag = "" if f.still_busy else "   (motion ended early: figure covers fewer scans)"
        print(f"  {f.name:48s} {f.p50_us:8.1f} / {f.p99_us:8.1f} us   "
              f"+{f.p50_us - idle:6.1f} us   start scan {f.start_max_us:8.1f} us{flag}")
    kinds = {"MotionJointMove": 0.0, "MotionLinear": 0.0, "MotionJog": 0.0, "MotionHalt": 0.0}
    for f in figures[1:]:
        key = f.name.split()[0]
        kinds[key] = max(kinds[key], f.p50_us - idle)
    together = idle + sum(kinds.values())
    print("each kind's worst extra: " + ", ".join(f"{k} +{v:.1f} us" for k, v in kinds.items()))
    print(f"all together (idle scan + one of each kind active): {together:.1f} us = "
          f"{100.0 * together / SCAN_US:.2f} % of the 10 ms scan (goal < 5 %)")


if __name__ == "__main__":
    main()
