"""The jerk-limited generator (st/MotionJerk*.st) against Ruckig (PyPI `ruckig`) on 10,000
cases per interface, and on synchronised axes (prints figures; exit 1 when a case differs).

The checks of CI's sample (tests/unit/test_motion_jerk_ruckig.py, ``check_plan`` in
tests/unit/jerk_support.py) on the full set: the same verdict as Ruckig, the duration within
1e-4 relative, every axis' position along the trajectory within float32 tolerance of Ruckig's
(--samples + 2 times per case, the ST's MotionJerkAt), the end state and the velocity,
acceleration and jerk limits from the phases integrated in float64 (exact extrema) and at the
sampled times (the ST's evaluation). The case families are jerk_support.FAMILIES, equally
many of each.

Printed per case set: cases, refused by both (with the same ErrorId class), the worst and
median relative duration error, the worst position error as a fraction of its float32
tolerance, the largest reached/limit ratio of velocity, acceleration and jerk, and the
failures. Also the quintic's shortest rest-to-rest duration (MotionQuinticMinTime) over the
time-optimal one for the rest-to-rest family.

Run: .venv/bin/python bench/jerk_vs_ruckig.py [--cases 10000] [--samples 16]
(PYTHONPATH=sim from a worktree; about 7 minutes for the default: 10,000 single-axis cases per
interface, 10,000 each of 3 and 6 time-synchronised axes (position) and of 3 axes (velocity),
2,000 collinear phase-synchronised cases).
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "unit"))

import jerk_support as js  # noqa: E402

from armbench.compiler import compile_files  # noqa: E402


def run_set(runner: js.StRunner, name: str,
            cases: list[tuple[tuple[js.AxisCase, ...], str, str]], samples: int) -> bool:
    t0 = time.monotonic()
    checks = []
    failed = []
    for axes, sync, interface in cases:
        c = js.check_plan(runner, axes, sync, interface, samples)
        checks.append(c)
        if c.problems:
            failed.append((axes, c.problems))
    planned = [c for c in checks if not c.agreed_error]
    rel = [c.rel_duration_error for c in planned]
    pos = [c.pos_error_rel_tol for c in planned]
    lim = [c.limit_ratio for c in planned]
    print(f"| {name} | {len(checks)} | {len(checks) - len(planned)} | "
          f"{max(rel, default=0.0):.2e} | {statistics.median(rel or [0.0]):.2e} | "
          f"{max(pos, default=0.0):.2e} | {max(lim, default=0.0):.12f} | {len(failed)} | "
          f"{time.monotonic() - t0:.0f} s |", flush=True)
    for axes, problems in failed[:3]:
        print(f"    FAIL {axes}: {problems[:2]}")
    return not failed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=10000, help="cases per interface / set")
    ap.add_argument("--samples", type=int, default=16, help="times sampled along each case")
    ap.add_argument("--seed", type=int, default=1)
    opts = ap.parse_args()
    module = compile_files(sorted((ROOT / "st").glob("*.st")))
    runner = js.StRunner(module)
    per = max(1, opts.cases // len(js.FAMILIES))
    n_multi = max(1, opts.cases)
    sets: list[tuple[str, list[tuple[tuple[js.AxisCase, ...], str, str]]]] = [
        ("1 axis, position", [((c,), "Time", "Position")
                              for _, c in js.axis_cases(opts.seed, per)]),
        ("1 axis, velocity", [((c,), "Time", "Velocity")
                              for _, c in js.axis_cases(opts.seed + 1, per)]),
    ]
    for dofs, sync, interface in ((3, "Time", "Position"), (6, "Time", "Position"),
                                  (3, "Time", "Velocity")):
        rng = random.Random(opts.seed * 7 + dofs)
        sets.append((f"{dofs} axes, {sync} sync, {interface.lower()}",
                     [(js.multi_case(rng, js.FAMILIES[k % len(js.FAMILIES)], dofs).axes, sync,
                       interface) for k in range(n_multi)]))
    rng = random.Random(opts.seed * 11)
    sets.append(("3 axes collinear, Phase sync, position",
                 [(js.collinear_case(rng, 3, k % 2 == 1).axes, "Phase", "Position")
                  for k in range(max(1, n_multi // 5))]))
    print("| cases | n | refused by both | duration rel err worst | median | "
          "position err / f32 tol worst | max reached/limit | failures | time |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    ok = True
    for name, cases in sets:
        ok = run_set(runner, name, cases, opts.samples) and ok

    # the quintic of MotionProfiles.st against the time-optimal profile, rest to rest
    ratios = []
    for _, c in js.axis_cases(opts.seed + 2, per, ("rest",)):
        plan = runner.plan((c,))
        quintic = module.call("MotionQuinticMinTime", float(c.pf - c.p0), float(c.vmax),
                              float(c.amax), float(c.jmax))
        if plan.valid and plan.duration > 0.0 and quintic > 0.0:
            ratios.append(quintic / plan.duration)
    if ratios:
        print(f"\nquintic (MotionQuinticMinTime, REAL) / time-optimal, {len(ratios)} rest-to-rest "
              f"moves: min {min(ratios):.3f}, median {statistics.median(ratios):.3f}, "
              f"max {max(ratios):.3f}")
    print("\nchecks: " + ("all cases agree with Ruckig" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
