"""Figures for docs/orientation.md: the orientation error of each ST method against the
simulated IMU's ground truth, and what the tool follower passes on to the arm.

Compiles st/ with the bench's compiler, simulates 60 s of hand motion (armbench.plant.imu,
seed 11 -- the same run as tests/unit/test_orientation_truth.py) and runs the ST blocks:

    python -m armbench.plots.orientation            # docs/figures/orientation-*.png
    python -m armbench.plots.orientation --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from armbench.orientation import METHODS, FilterRun, quat_dict, quat_row, run_filter, st_samples
from armbench.plant.imu import HandTrajectory, ImuModel, ImuRecord, quat_to_matrix, simulate
from armbench.plots.cli import figure_target

SEED = 11
DURATION_S = 60.0
RATE_HZ = 100.0
LABELS = {"gyro": "gyro only (q_G)", "complementary": "complementary, F = 0.98 (doc 004)",
          "madgwick_imu": "Madgwick IMU, beta = 0.033", "madgwick_marg":
          "Madgwick MARG, beta = 0.041"}


def tool_elevation_deg(quats: np.ndarray) -> np.ndarray:
    """Elevation of the tool direction (first matrix column) above the horizontal, deg."""
    return np.asarray(np.degrees(np.arcsin(np.clip(quat_to_matrix(quats)[:, 2, 0], -1, 1))))


def error_figure(path: Path, record: ImuRecord, runs: dict[str, FilterRun]) -> Path:
    fig = Figure(figsize=(8.0, 4.6))
    ax = fig.add_subplot()
    for method in METHODS:
        ax.plot(record.t, runs[method].error_deg(record.quat_true), lw=1.0,
                label=LABELS[method])
    ax.set_yscale("log")
    ax.set_ylim(0.01, 100.0)
    ax.set_xlabel("time, s")
    ax.set_ylabel("orientation error vs ground truth, deg")
    ax.set_title("Same noisy IMU samples (MPU6050 + HMC5883L model, gyro bias 0.56 deg/s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def follower_run(module: Any, target: np.ndarray, period_s: float) -> np.ndarray:
    fb = module.new_fb("ToolOrientationFollower")
    fb.set(Enable=True, DeadBandDeg=2.0, MaxRateDps=90.0, CycleTimeS=period_s,
           MountOffset=quat_dict([1.0, 0.0, 0.0, 0.0]))
    fb(Reset=True, InitialQuat=quat_dict(target[0]), Target=quat_dict(target[0]))
    out = []
    for q in target:
        fb(Reset=False, Target=quat_dict(q))
        out.append(quat_row(fb.Orientation))
    return np.array(out)


def follower_figure(path: Path, record: ImuRecord, runs: dict[str, FilterRun],
                    followed: np.ndarray) -> Path:
    fig = Figure(figsize=(8.0, 4.2))
    ax = fig.add_subplot()
    sel = (record.t >= 20.0) & (record.t <= 30.0)
    t = record.t[sel]
    ax.plot(t, tool_elevation_deg(record.quat_true)[sel], "k--", lw=1.0, label="true hand")
    ax.plot(t, tool_elevation_deg(runs["madgwick_marg"].quats)[sel], lw=0.8,
            label="Madgwick MARG output")
    ax.plot(t, tool_elevation_deg(followed)[sel], lw=1.4,
            label="ToolOrientationFollower (2 deg dead band, 90 deg/s)")
    ax.set_xlabel("time, s")
    ax.set_ylabel("tool direction elevation, deg")
    ax.set_title("From orientation to tool vector: the follower moves in steps of the dead band")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def make_runs(module: Any) -> tuple[ImuRecord, dict[str, FilterRun]]:
    record = simulate(HandTrajectory(), ImuModel(), duration_s=DURATION_S, rate_hz=RATE_HZ,
                      seed=SEED)
    samples = st_samples(module, record)
    runs = {m: run_filter(module, m, samples, record.period_s, record.quat_true[0])
            for m in METHODS}
    return record, runs


def main(argv: Sequence[str] | None = None) -> int:
    checkout, out = figure_target("armbench.plots.orientation", argv)
    from armbench.compiler import compile_files

    module = compile_files(sorted(checkout.st_dir.glob("*.st")))
    record, runs = make_runs(module)
    print(f"wrote {error_figure(out / 'orientation-error.png', record, runs)}")
    followed = follower_run(module, runs["madgwick_marg"].quats, record.period_s)
    print(f"wrote {follower_figure(out / 'orientation-follower.png', record, runs, followed)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
