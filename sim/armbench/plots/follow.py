"""Figure for docs/orientation.md section 11: the simulated hand drives the 5-axis arm through
the controller's FollowImu (the run of ``armbench demo-imu``: 20 s, heading 10 deg, seed 5,
tip-fixed): the hand's tool pitch and roll (ground truth) against the arm's (closed-form FK of
the slew limiter's joint outputs), the angle between the two tool directions and the tip's
drift.

    python -m armbench.plots.follow            # docs/figures/follow-imu.png
    python -m armbench.plots.follow --out DIR
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from armbench.follow_demo import FollowRun, paced_controller, print_report, run_follow, settled
from armbench.plots.cli import figure_target

DURATION_S = 20.0
HEADING_DEG = 10.0
SEED = 5
FIGURE = "follow-imu.png"


def follow_figure(path: Path, run: FollowRun) -> Path:
    fig = Figure(figsize=(9.0, 7.5))
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    ax1.plot(run.t, run.hand_pitch, color="0.6", lw=2.5, label="hand (ground truth)")
    ax1.plot(run.t, run.arm_pitch, color="C0", lw=1.0, label="arm (FK of the servo outputs)")
    ax1.set_ylabel("tool pitch, deg")
    ax1.legend(loc="upper right", fontsize=8)
    ax2.plot(run.t, run.hand_roll, color="0.6", lw=2.5, label="hand")
    ax2.plot(run.t, run.arm_roll, color="C1", lw=1.0, label="arm")
    ax2.set_ylabel("roll about the tool, deg")
    ax2.legend(loc="upper right", fontsize=8)
    ax3.plot(run.t, run.error_deg, color="C3", lw=1.0, label="tool direction error, deg")
    ax3.plot(run.t, run.drift_mm, color="C2", lw=1.0, label="tip drift, mm")
    ok = settled(run)
    ax3.set_title(f"after 2 s: error 95 % {np.percentile(run.error_deg[ok], 95):.2f} deg, "
                  f"max {run.error_deg[ok].max():.2f} deg; tip drift max "
                  f"{run.drift_mm.max():.2f} mm", fontsize=9)
    ax3.set_xlabel("time since FollowImu, s")
    ax3.legend(loc="upper right", fontsize=8)
    fig.suptitle("FollowImu: Madgwick MARG -> ToolOrientationFollower (dead band 2 deg, "
                 "90 deg/s, 400 deg/s^2) -> 5-axis IK, tip fixed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    _, out = figure_target("armbench.plots.follow", argv)
    with paced_controller() as ctl:
        run = run_follow(ctl.address, ctl.rig, duration_s=DURATION_S, heading_deg=HEADING_DEG,
                         seed=SEED)
    print_report(run, sys.stdout)  # the figures the page quotes
    print(follow_figure(out / FIGURE, run))
    return 0


if __name__ == "__main__":
    sys.exit(main())
