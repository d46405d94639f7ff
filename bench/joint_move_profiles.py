"""MotionJointMove's profile 4 (time-optimal jerk-limited) against Ruckig and against the
quintic (profile 3) on random joint moves (prints figures; exit 1 when a move differs).

Per move (3 or 5 joints, random group limits and Velocity/Acceleration/Jerk inputs, from rest
or from a moving start with an acceleration): the Execute scan of MotionJointMove with
profile 4 and, on a fresh group, with profile 3 and with profile 2 (the trapezoid, the
time-optimal move without a jerk limit). Printed: profile 4's duration against Ruckig's
(PyPI `ruckig`, phase synchronisation, the block's latched inputs), and the ratios
profile 3 / profile 4 (what the quintic costs) and profile 4 / profile 2 (what limiting
the jerk costs). With --full N the first N moves also run scan by scan and every setpoint is
compared with Ruckig's trajectory (float32 tolerance), as tests/unit/test_motion_joint_jerk.py
does on its sample.

Run: .venv/bin/python bench/joint_move_profiles.py [--moves 2000] [--full 50] [--seed 1]
(PYTHONPATH=sim from a worktree).
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "unit"))

from jerk_support import ruckig_plan  # noqa: E402
from joint_jerk_support import JointCase, check_against_ruckig, random_case  # noqa: E402
from motion_support import GroupSim  # noqa: E402

from armbench.compiler import compile_files  # noqa: E402


def execute_duration(module: Any, case: JointCase, profile: int) -> tuple[bool, float, int]:
    """(planned, Duration, ErrorId) of one Execute scan with `profile`."""
    sim = GroupSim(case.group())
    fb = module.new_fb("MotionJointMove")
    sim.call(fb, **{**case.inputs(), "Profile": profile})
    return (not fb.Error), float(fb.Duration), int(fb.ErrorId)


def summary(values: list[float]) -> str:
    if not values:
        return "none"
    return (f"min {min(values):.3f}, median {statistics.median(values):.3f}, "
            f"max {max(values):.3f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=2000, help="moves per kind")
    ap.add_argument("--full", type=int, default=50, help="moves per kind run scan by scan")
    ap.add_argument("--seed", type=int, default=1)
    opts = ap.parse_args()
    module = compile_files(sorted((ROOT / "st").glob("*.st")))
    ok = True
    print("| moves | n | refused | duration rel. err. vs ruckig worst | median | "
          "quintic / profile 4 | profile 4 / trapezoid | scan-by-scan runs | worst position "
          "err / f32 tol. | time |")
    print("|---|---:|---:|---:|---:|---|---|---:|---:|---:|")
    for kind in ("rest", "moving"):
        for joints in (3, 5):
            rng = random.Random(opts.seed * 100 + joints + (50 if kind == "moving" else 0))
            t0 = time.monotonic()
            rel: list[float] = []
            q_ratio: list[float] = []
            t_ratio: list[float] = []
            refused = 0
            worst_pos = 0.0
            full = 0
            for k in range(opts.moves):
                case = random_case(rng, kind, joints)
                planned, dur4, code = execute_duration(module, case, 4)
                ref = ruckig_plan(case.axes(), "Phase")
                if not planned or not ref.ok:
                    refused += 1
                    if planned != ref.ok:
                        ok = False
                        print(f"    FAIL {case}: ST planned {planned} (ErrorId {code}), "
                              f"Ruckig {ref.result}")
                    continue
                rel.append(abs(dur4 - ref.duration) / ref.duration)
                if rel[-1] > 1e-4:
                    ok = False
                    print(f"    FAIL {case}: duration {dur4!r} vs Ruckig's {ref.duration!r}")
                planned3, dur3, _ = execute_duration(module, case, 3)
                planned2, dur2, _ = execute_duration(module, case, 2)
                if planned3 and dur4 > 0.0:
                    q_ratio.append(dur3 / dur4)
                if planned2 and dur2 > 0.0:
                    t_ratio.append(dur4 / dur2)
                if k < opts.full:
                    try:
                        _, pos = check_against_ruckig(module, case)
                        worst_pos = max(worst_pos, pos)
                        full += 1
                    except AssertionError as exc:
                        ok = False
                        print(f"    FAIL scan by scan {case}: {exc}")
            print(f"| {kind}, {joints} joints | {opts.moves} | {refused} | "
                  f"{max(rel, default=0.0):.2e} | {statistics.median(rel or [0.0]):.2e} | "
                  f"{summary(q_ratio)} | {summary(t_ratio)} | {full} | {worst_pos:.2e} | "
                  f"{time.monotonic() - t0:.0f} s |", flush=True)
    print("\nchecks: " + ("profile 4 agrees with Ruckig" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
