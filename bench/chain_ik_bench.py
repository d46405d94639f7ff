"""IK time per pose: the generic damped-least-squares chain solver (compiled ST) against the
analytic solvers (compiled ST) and the Robotics Toolbox's ikine_LM (Python) and ik_LM (C++),
on the same poses and seeds, in one run (prints figures; not a test).

Cases (200 random reachable poses each, seeds within +/-0.5 rad of a solution):
  3-axis  document 002's arm: InverseKinematik_V1 vs the DLS chain (position task, its DH
          table) vs ikine_LM / ik_LM with a position mask;
  4-axis  document 001's arm: InverseKinematik_4Axis vs the DLS chain (MDH table, position
          task, 4 joints: redundant) vs the toolbox;
  Puma560 6 joints, whole pose: the DLS chain vs the toolbox.
Every answer is checked with the toolbox's float64 fkine (residual printed). The ST runs
through the bench's ST->C compiler at -O2 (MatIEC-like C), REAL = float32.
Run: .venv/bin/python bench/chain_ik_bench.py [--poses N] [--repeat R]
"""

from __future__ import annotations

import argparse
import math
import sys
import timeit
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import roboticstoolbox as rtb
from spatialmath import SE3

from armbench.compiler import compile_files

HERE = Path(__file__).parent
ROOT = HERE.parent
MAX_POSES = 200          # the kernel's array size
GEO3 = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}
GEO4 = {"BaseHeightMm": 100.0, "ShoulderOffsetMm": 20.0, "UpperArmMm": 120.0,
        "ForearmMm": 130.0, "WristLinkMm": 40.0, "ToolDropMm": 15.0}


@dataclass
class Case:
    name: str
    robot: Any                   # toolbox model in mm
    chain: dict[str, Any]        # the same as a KinematicChain
    position_only: bool
    analytic: int                # kernel solver id of the analytic IK, 0 = none
    targets: np.ndarray          # (n, 4, 4) mm
    seeds: np.ndarray            # (n, joints) rad


@dataclass
class Row:
    case: str
    method: str
    us_per_pose: float
    converged: int
    poses: int
    worst_mm: float


def link(a: float = 0.0, alpha: float = 0.0, d: float = 0.0, offset: float = 0.0
         ) -> dict[str, Any]:
    return {"A": a, "AlphaDeg": alpha, "D": d, "ThetaOffsetDeg": offset, "Prismatic": False,
            "LowerLimit": 0.0, "UpperLimit": 0.0}


def make_cases(poses: int, rng: np.random.Generator) -> list[Case]:
    r3 = rtb.DHRobot([rtb.RevoluteDH(d=GEO3["A1"], a=GEO3["A2"], alpha=math.pi / 2),
                      rtb.RevoluteDH(a=GEO3["A3"]),
                      rtb.RevoluteDH(a=GEO3["A4"], offset=-math.pi)])
    c3 = {"Links": [link(GEO3["A2"], 90.0, GEO3["A1"]), link(GEO3["A3"]),
                    link(GEO3["A4"], offset=-180.0), link(), link(), link()],
          "Count": 3, "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0}
    r4 = rtb.DHRobot([rtb.RevoluteMDH(d=GEO4["BaseHeightMm"]),
                      rtb.RevoluteMDH(a=GEO4["ShoulderOffsetMm"], alpha=math.pi / 2),
                      rtb.RevoluteMDH(a=GEO4["UpperArmMm"]),
                      rtb.RevoluteMDH(a=GEO4["ForearmMm"])],
                     tool=SE3(GEO4["WristLinkMm"], -GEO4["ToolDropMm"], 0.0))
    c4 = {"Links": [link(d=GEO4["BaseHeightMm"]), link(GEO4["ShoulderOffsetMm"], 90.0),
                    link(GEO4["UpperArmMm"]), link(GEO4["ForearmMm"]), link(), link()],
          "Count": 4, "Modified": True, "ToolX": GEO4["WristLinkMm"],
          "ToolY": -GEO4["ToolDropMm"], "ToolZ": 0.0}
    puma_m = rtb.models.DH.Puma560()
    r6 = rtb.DHRobot([rtb.RevoluteDH(a=lk.a * 1000, d=lk.d * 1000, alpha=lk.alpha,
                                     offset=lk.offset) for lk in puma_m.links])
    c6 = {"Links": [link(lk.a * 1000, math.degrees(lk.alpha), lk.d * 1000,
                         math.degrees(lk.offset)) for lk in puma_m.links],
          "Count": 6, "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0}
    cases = []
    for name, robot, chain, pos_only, analytic in (
            ("3-axis (002)", r3, c3, True, 2), ("4-axis (001)", r4, c4, True, 3),
            ("Puma560 pose", r6, c6, False, 0)):
        q = np.zeros((poses, robot.n))
        if name.startswith("3-axis"):
            # elbow-up configurations (the analytic solver's branch), off the base axis
            q[:, 0] = rng.uniform(-math.pi, math.pi, poses)
            q[:, 1] = rng.uniform(-0.5, 2.0, poses)
            q[:, 2] = rng.uniform(0.3, 2.8, poses)
        elif name.startswith("4-axis"):
            q[:, 0] = rng.uniform(-math.pi, math.pi, poses)
            q[:, 1] = rng.uniform(-0.5, 2.0, poses)
            q[:, 2] = rng.uniform(-2.8, -0.3, poses)
            q[:, 3] = -(q[:, 1] + q[:, 2])
        else:
            q = rng.uniform(puma_m.qlim[0], puma_m.qlim[1], (poses, 6))
        targets = np.array([T.A for T in robot.fkine(q)])
        seeds = q + rng.uniform(-0.5, 0.5, q.shape)
        cases.append(Case(name, robot, chain, pos_only, analytic, targets, seeds))
    return cases


def best_time(fn: Callable[[], object], repeat: int) -> float:
    """Best of ``repeat`` single runs, s."""
    return min(timeit.repeat(fn, number=1, repeat=repeat))


def residual_mm(robot: Any, targets: np.ndarray, q_rad: np.ndarray, ok: np.ndarray) -> float:
    if not ok.any():
        return math.nan
    got = np.array([T.t for T in robot.fkine(q_rad[ok])])
    return float(np.linalg.norm(got - targets[ok, :3, 3], axis=1).max())


def run_st(kernel: Any, case: Case, solver: int, repeat: int) -> Row:
    n = len(case.targets)
    targets = np.zeros((MAX_POSES, 4, 4))
    targets[:n] = case.targets
    seeds = np.zeros((MAX_POSES, 6))
    seeds[:n, :case.robot.n] = np.degrees(case.seeds)
    kernel.set(Solver=solver, Count=n, Chain=case.chain, PositionOnly=case.position_only,
               Geometry=GEO3, Geometry4=GEO4, Targets=targets.tolist(), Seeds=seeds.tolist())
    t = best_time(lambda: kernel(), repeat)
    answers = np.radians(np.array(kernel.Answers)[:n, :case.robot.n])
    ok = np.abs(answers).sum(axis=1) > 0.0
    method = {1: "DLS chain (ST)", 2: "analytic V1 (ST)", 3: "analytic 4-axis (ST)"}[solver]
    return Row(case.name, method, t / n * 1e6, int(kernel.Converged), n,
               residual_mm(case.robot, case.targets, answers, ok))


def run_rtb(case: Case, cpp: bool, repeat: int) -> Row:
    robot = case.robot
    mask = np.array([1, 1, 1, 0, 0, 0]) if case.position_only else None
    tol = 5e-5  # mm model: |e| <= 0.01 (mm, rad), position and pose tasks alike
    n = len(case.targets)
    answers = np.zeros((n, robot.n))
    ok = np.zeros(n, dtype=bool)
    # the C++ solver on the robot's ETS, built once: DHRobot.ik_LM rebuilds it on every
    # call (about 5 ms per pose here), which would time the toolbox's set-up, not its IK
    ets = robot.ets()

    def go() -> None:
        for i in range(n):
            if cpp:
                sol = ets.ik_LM(case.targets[i], q0=case.seeds[i], ilimit=100, slimit=1,
                                  tol=tol, joint_limits=False, mask=mask)
            else:
                sol = robot.ikine_LM(case.targets[i], q0=case.seeds[i], ilimit=100, slimit=1,
                                     tol=tol, joint_limits=False, mask=mask)
            ok[i] = bool(sol.success)
            answers[i] = sol.q

    t = best_time(go, repeat)
    return Row(case.name, "ik_LM (C++)" if cpp else "ikine_LM (Python)", t / n * 1e6,
               int(ok.sum()), n, residual_mm(robot, case.targets, answers, ok))


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=MAX_POSES, help=f"1..{MAX_POSES}")
    ap.add_argument("--repeat", type=int, default=15,
                    help="best of R runs (the machine may be shared: take the best)")
    args = ap.parse_args(argv)
    if not 1 <= args.poses <= MAX_POSES or args.repeat < 1:
        ap.error(f"--poses must be 1..{MAX_POSES} and --repeat >= 1")
    files = sorted((ROOT / "st").glob("*.st")) + [HERE / "kernels" / "chain_ik_bench.st"]
    kernel = compile_files(files).new_fb("ChainIkBench")
    rng = np.random.default_rng(2026)
    rows: list[Row] = []
    for case in make_cases(args.poses, rng):
        if case.analytic:
            rows.append(run_st(kernel, case, case.analytic, args.repeat))
        rows.append(run_st(kernel, case, 1, args.repeat))
        iters = int(kernel.TotalIterations) / len(case.targets)
        rows[-1].method += f", {iters:.1f} it/pose"
        rows.append(run_rtb(case, cpp=True, repeat=args.repeat))
        rows.append(run_rtb(case, cpp=False, repeat=1))
    print(f"IK time per pose, {args.poses} poses per case, best of {args.repeat} "
          "(ikine_LM: one run); residual = |FK(answer) - target| by the toolbox, float64")
    print(f"{'case':14} {'method':38} {'us/pose':>10} {'converged':>10} {'worst mm':>10}")
    for r in rows:
        print(f"{r.case:14} {r.method:38} {r.us_per_pose:10.2f} "
              f"{r.converged:>5}/{r.poses:<4} {r.worst_mm:10.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
