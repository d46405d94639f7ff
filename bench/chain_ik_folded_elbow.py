"""InverseKinematik_Chain (compiled ST, REAL) against the Robotics Toolbox's ikine_LM (float64)
on targets next to the Puma 560's folded elbow: of the poses ikine_LM solves from a seed, how
many ours misses, per seed spread and iteration cap (prints figures; not a test).

Targets: q3 within 1e-4..5e-2 rad of the folded elbow (tan q3 = -d4 / a3, cos q3 < 0), the other
joints within the toolbox's limits; seeds within +/-spread rad in every joint; 120 poses per
generator seed, the set of tests/unit/chain_models.puma_folded_elbow_set. ikine_LM: 100
iterations, one search, tolerance E <= 5e-11 (|e| <= 1e-5 m, rad: 0.01 mm); ours: TolMm 0.005,
TolDeg 5e-4, MaxIters as given. Misses are listed with ours' ErrorId and residual, and the
iterations ikine_LM took.
Run: .venv/bin/python bench/chain_ik_folded_elbow.py [--first-seed S] [--sets N]
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import roboticstoolbox as rtb

from armbench.compiler import compile_files

ROOT = Path(__file__).parent.parent
# the pose set and the chain of the unit tests, so that bench and test draw the same targets
sys.path.insert(0, str(ROOT / "tests" / "unit"))
from chain_models import MM_PER_M, chain_of, chain_pose, puma_folded_elbow_set  # noqa: E402

POSES_PER_SET = 120
SPREADS = (0.5, 1.0, math.pi)
CAPS = (100, 200)
RTB_TOL = 5e-11


@dataclass
class Tally:
    solved_by_rtb: int = 0
    rtb_only: list[tuple[int, int, int, float, int]] = field(default_factory=list)
    ours_only: int = 0
    iterations: list[int] = field(default_factory=list)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first-seed", type=int, default=200, help="first generator seed")
    ap.add_argument("--sets", type=int, default=30, help=f"sets of {POSES_PER_SET} poses")
    args = ap.parse_args(argv)
    if args.sets < 1:
        ap.error("--sets must be >= 1")
    ik = compile_files(sorted((ROOT / "st").glob("*.st"))).new_fb("InverseKinematik_Chain")
    robot = rtb.models.DH.Puma560()
    chain = chain_of(robot, MM_PER_M)
    seeds = range(args.first_seed, args.first_seed + args.sets)
    print(f"Puma 560 folded elbow, generator seeds {seeds.start}..{seeds.stop - 1}, "
          f"{POSES_PER_SET} poses each; ikine_LM: 100 iterations")
    for spread in SPREADS:
        tallies = {cap: Tally() for cap in CAPS}
        for seed in seeds:
            for qt, q0 in puma_folded_elbow_set(robot, POSES_PER_SET, spread, seed):
                Tep = robot.fkine(qt).A
                sol = robot.ikine_LM(Tep, q0=q0, ilimit=100, slimit=1, tol=RTB_TOL,
                                     joint_limits=False)
                ok, rtb_its = bool(sol.success), int(sol.iterations)
                target = np.array(Tep)
                target[:3, 3] *= 1000.0
                for cap, tally in tallies.items():
                    ik(Execute=False)
                    ik(Execute=True, Chain=chain, Target=chain_pose(target),
                       Seed=[math.degrees(v) for v in q0], PositionOnly=False, TolMm=0.005,
                       TolDeg=5e-4, ItersPerScan=cap, MaxIters=cap)
                    tally.solved_by_rtb += ok
                    if ik.Done:
                        tally.iterations.append(int(ik.Iterations))
                        tally.ours_only += not ok
                    elif ok:
                        tally.rtb_only.append((seed, int(ik.ErrorId), int(ik.Iterations),
                                               float(ik.ResidualMm), rtb_its))
        n = len(seeds) * POSES_PER_SET
        for cap, t in tallies.items():
            its = np.array(t.iterations)
            print(f"seeds +/-{spread:.2f} rad, ours capped at {cap}: ikine_LM solved "
                  f"{t.solved_by_rtb}/{n}; ours missed {len(t.rtb_only)} of those, solved "
                  f"{t.ours_only} it did not; ours' iterations median {np.median(its):.0f}, "
                  f"95th percentile {np.percentile(its, 95):.0f}, max {its.max()}")
            for seed, code, iters, mm, rtb_its in t.rtb_only:
                print(f"    seed {seed}: ErrorId {code} after {iters} iterations, "
                      f"{mm:.4f} mm (ikine_LM: {rtb_its} iterations)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
