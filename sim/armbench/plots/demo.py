"""PNG plots of a demo run (matplotlib is imported only under armbench.plots, so the
compiler, the soft PLC and the CLI start without it). It uses the non-interactive Agg
backend, so it works without a display.

Each function takes plain sequences (one entry per commanded point) and writes one PNG;
:func:`demo_plots` writes all three and returns their paths.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402  (after the backend choice)
from matplotlib.ticker import MaxNLocator  # noqa: E402

Point = tuple[float, float, float]

JOINT_NAMES = ("Base", "Shoulder", "Elbow")
_DPI = 120


def _columns(points: Sequence[Point]) -> tuple[list[float], list[float], list[float]]:
    return [p[0] for p in points], [p[1] for p in points], [p[2] for p in points]


def path_3d(commanded: Sequence[Point], achieved: Sequence[Point], path: Path,
            title: str = "Tool path: commanded vs achieved") -> Path:
    """3-D path plus the per-point distance |commanded - achieved| in µm beside it."""
    fig = plt.figure(figsize=(11.0, 5.0))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot(*_columns(commanded), color="tab:blue", lw=2.5, label="commanded")
    ax.plot(*_columns(achieved), color="tab:orange", lw=1.0, ls="--",
            label="achieved (PWM + servo model + reference FK)")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_zlabel("Z (mm)")
    # a cube around the path: true proportions, so sub-mm deviations look sub-mm
    cols = _columns([*commanded, *achieved])
    half = max(max(c) - min(c) for c in cols) / 2.0 + 1.0
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), cols, strict=True):
        mid = (max(c) + min(c)) / 2.0
        set_lim(mid - half, mid + half)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title, fontsize=10)
    err = fig.add_subplot(1, 2, 2)
    dist_um = [1000.0 * sum((a - b) ** 2 for a, b in zip(c, h, strict=True)) ** 0.5
               for c, h in zip(commanded, achieved, strict=True)]
    err.plot(range(1, len(dist_um) + 1), dist_um, color="tab:red", lw=1.0)
    err.set_xlabel("point")
    err.set_ylabel("|commanded - achieved| (µm)")
    err.set_title("Position error per point (12-bit PWM quantisation + deadband)", fontsize=10)
    err.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def joint_angles(commanded: Sequence[Point], achieved: Sequence[Point], path: Path) -> Path:
    """Joint angles over the points: PLC's commanded (lines) and servo-achieved (dots)."""
    fig, axes = plt.subplots(3, 1, figsize=(9.0, 7.0), sharex=True)
    x = list(range(1, len(commanded) + 1))
    for j, ax in enumerate(axes):
        ax.plot(x, [c[j] for c in commanded], color="tab:blue", lw=1.5, label="commanded (PLC)")
        ax.plot(x, [a[j] for a in achieved], ".", color="tab:orange", ms=2.5,
                label="achieved (servo model)")
        ax.set_ylabel(f"{JOINT_NAMES[j]} (deg)")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("Joint angles over the path", fontsize=10)
    axes[-1].set_xlabel("point")
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def servo_pulses(pulses_us: Sequence[Point], counts: Sequence[Point], path: Path) -> Path:
    """Servo pulse widths the PLC computed (µs) and the PCA9685 OFF counts it output."""
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9.0, 6.0), sharex=True)
    x = list(range(1, len(pulses_us) + 1))
    for j, name in enumerate(JOINT_NAMES):
        ax.plot(x, [p[j] for p in pulses_us], lw=1.5, label=f"ch {j} {name}")
        bx.step(x, [c[j] for c in counts], lw=1.0, where="mid", label=f"ch {j} {name}")
    ax.set_ylabel("pulse width (µs)")
    ax.set_title("Servo pulses (MG996R: 1000..2000 µs = -60..+60 deg)", fontsize=10)
    bx.set_ylabel("PCA9685 OFF count (ticks)")
    bx.set_xlabel("point")
    for a in (ax, bx):
        a.grid(True, alpha=0.3)
        a.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def joint_velocities(scans: Sequence[int], set_vel: Sequence[Point], out_vel: Sequence[Point],
                     limit_vel: float, path: Path, scan_s: float = 0.01) -> Path:
    """Joint velocities over time as the motion layer recorded them every scan: the motion
    generator's setpoint velocity and the slew limiter's output (what the servos get)."""
    fig, axes = plt.subplots(3, 1, figsize=(9.0, 7.0), sharex=True)
    t = [(k - scans[0]) * scan_s for k in scans]
    for j, (ax, name) in enumerate(zip(axes, JOINT_NAMES, strict=True)):
        ax.plot(t, [v[j] for v in set_vel], lw=1.6, label="group setpoint (generator)")
        ax.plot(t, [v[j] for v in out_vel], lw=0.8, ls="--", label="slew limiter output")
        for sign in (1.0, -1.0):
            ax.axhline(sign * limit_vel, color="grey", lw=0.8, ls=":")
        ax.set_ylabel(f"{name} (deg/s)")
        ax.grid(True, alpha=0.3)
    axes[0].set_title(f"Joint velocities, sampled every scan (limit ±{limit_vel:g} deg/s dotted)",
                      fontsize=10)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def demo_plots(out_dir: Path, commanded_xyz: Sequence[Point], achieved_xyz: Sequence[Point],
               commanded_joints: Sequence[Point], achieved_joints: Sequence[Point],
               pulses_us: Sequence[Point], counts: Sequence[Point]) -> list[Path]:
    """Write path.png, joints.png and pulses.png into ``out_dir`` (created); their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        path_3d(commanded_xyz, achieved_xyz, out_dir / "path.png"),
        joint_angles(commanded_joints, achieved_joints, out_dir / "joints.png"),
        servo_pulses(pulses_us, counts, out_dir / "pulses.png"),
    ]
