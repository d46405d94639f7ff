"""Teaching figures for docs/kinematics.md and docs/servo-pwm.md.

Everything is computed from the float64 reference kinematics (``armbench.plant.arm``) and
the datasheet numbers of the MG996R and PCA9685; no ST is compiled, so the script is quick:

    python -m armbench.plots.teaching            # docs/figures/<name>.png, see FIGURES
    python -m armbench.plots.teaching --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Arc, Circle

from armbench.plant import arm
from armbench.plots.cli import figure_target

GEO = arm.DEFAULT_GEOMETRY

# The sample pose of the frames figure and the target of the elbow-up/down figure.
SAMPLE_POSE = (0.0, 50.0, 110.0)  # Base, Shoulder, Elbow in degrees (elbow up)
ELBOW_TARGET = (170.0, 0.0, 150.0)  # mm

# MG996R and PCA9685 numbers used by the servo figure (docs/servo-pwm.md).
OSC_HZ = 25.0e6
PRESCALE = 121
COUNT_US = (PRESCALE + 1) / OSC_HZ * 1e6  # 4.88 us
US_PER_DEG = 500.0 / 60.0  # 1000..2000 us = -60..+60 deg


def _plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Radial (signed X for Base = 0) and Z coordinates of joint points for a side view."""
    return points[:, 0], points[:, 2]


def _arrow(ax: Axes, x: float, z: float, dx: float, dz: float, text: str, color: str) -> None:
    ax.annotate("", xy=(x + dx, z + dz), xytext=(x, z),
                arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.6})
    ax.text(x + 1.18 * dx, z + 1.18 * dz, text, color=color, fontsize=10,
            ha="center", va="center")


def _out_of_page(ax: Axes, x: float, z: float, text: str, color: str,
                 offset: tuple[float, float]) -> None:
    """Symbol for an axis pointing at the reader (a dot in a circle), labelled at offset."""
    ax.add_patch(Circle((x, z), 4.0, fill=False, color=color, lw=1.4))
    ax.plot([x], [z], marker=".", color=color, markersize=5)
    ax.text(x + offset[0], z + offset[1], text, color=color, fontsize=10, ha="center",
            va="center")


def _angle_arc(ax: Axes, centre: tuple[float, float], radius: float, start_deg: float,
               end_deg: float, text: str, color: str, text_radius: float | None = None) -> None:
    """Arc counter-clockwise from start_deg to end_deg (end_deg >= start_deg)."""
    lo, hi = start_deg, end_deg
    ax.add_patch(Arc(centre, 2 * radius, 2 * radius, theta1=lo, theta2=hi, color=color, lw=1.4))
    mid = math.radians((lo + hi) / 2.0)
    r = text_radius if text_radius is not None else radius + 12.0
    ax.text(centre[0] + r * math.cos(mid), centre[1] + r * math.sin(mid), text, color=color,
            fontsize=10, ha="center", va="center")


def frames_figure(out: Path) -> Path:
    """Side view of the arm at SAMPLE_POSE: links a1..a4, frames 0..3, Shoulder and Elbow."""
    base, shoulder, elbow = SAMPLE_POSE
    h10, h21, h32 = arm.link_transforms(base, shoulder, elbow, GEO)
    h20 = h10 @ h21
    h30 = h20 @ h32
    pts = arm.joint_points(base, shoulder, elbow, GEO)
    xs, zs = _plane(pts)

    fig = Figure(figsize=(8.0, 6.6))
    ax = fig.add_subplot()
    ax.axhline(0.0, color="0.55", lw=1.0)
    ax.fill_between([-60.0, 300.0], -12.0, 0.0, color="0.9")
    ax.axvline(0.0, color="0.6", lw=0.9, ls="--")
    ax.text(2.0, 262.0, "base axis (z0)", color="0.4", fontsize=9, ha="left")

    # Links: base column a1, shoulder offset a2, upper arm a3, forearm a4.
    ax.plot([0.0, 0.0, xs[1]], [0.0, GEO.a1, zs[1]], color="0.35", lw=5, solid_capstyle="round")
    ax.plot(xs[1:], zs[1:], color="tab:blue", lw=5, solid_capstyle="round")
    ax.plot(xs[1:], zs[1:], "o", color="k", markersize=7)
    ax.text(-5.0, GEO.a1 * 0.72, "a1", fontsize=11, ha="right")
    ax.text(xs[1] / 2.0, GEO.a1 + 5.0, "a2", fontsize=11, ha="center", va="bottom")
    ax.text((xs[1] + xs[2]) / 2.0 - 12.0, (zs[1] + zs[2]) / 2.0 + 4.0, "a3", fontsize=11,
            ha="right", color="tab:blue")
    ax.text((xs[2] + xs[3]) / 2.0 + 8.0, (zs[2] + zs[3]) / 2.0 + 6.0, "a4", fontsize=11,
            ha="left", color="tab:blue")

    length = 38.0
    # Frame 0 at the foot: x0 forward, z0 up, y0 into the page.
    _arrow(ax, 0.0, 0.0, length, 0.0, "x0", "tab:red")
    _arrow(ax, 0.0, 0.0, 0.0, length, "z0", "tab:red")
    ax.text(-6.0, -6.0, "y0 into the page", color="tab:red", fontsize=9, ha="right",
            va="top")
    # Frames 1..3: x and y axes in the arm's plane, z out of the page.
    for name, h, color, offset in (("1", h10, "tab:green", (-9.0, -11.0)),
                                   ("2", h20, "tab:purple", (-15.0, 3.0)),
                                   ("3", h30, "tab:orange", (0.0, -15.0))):
        ox, oz = h[0, 3], h[2, 3]
        _arrow(ax, ox, oz, length * h[0, 0], length * h[2, 0], f"x{name}", color)
        _arrow(ax, ox, oz, length * h[0, 1], length * h[2, 1], f"y{name}", color)
        _out_of_page(ax, ox, oz, f"z{name}", color, offset)

    # Shoulder: from the horizontal x1 to the upper arm.
    _angle_arc(ax, (xs[1], zs[1]), 26.0, 0.0, shoulder, f"Shoulder = {shoulder:g}°",
               "tab:green", text_radius=62.0)
    # Elbow: interior angle between the upper arm (back to the shoulder) and the forearm;
    # theta3' = Elbow - 180 from the extension of the upper arm to the forearm.
    back = shoulder + 180.0
    fore = shoulder + elbow - 180.0
    _angle_arc(ax, (xs[2], zs[2]), 20.0, back, back + elbow, f"Elbow = {elbow:g}°\n(interior)",
               "tab:purple", text_radius=46.0)
    ext_x = xs[2] + 45.0 * math.cos(math.radians(shoulder))
    ext_z = zs[2] + 45.0 * math.sin(math.radians(shoulder))
    ax.plot([xs[2], ext_x], [zs[2], ext_z], color="tab:purple", lw=1.0, ls=":")
    _angle_arc(ax, (xs[2], zs[2]), 34.0, fore, shoulder,
               f"θ3' = Elbow − 180°\n= {elbow - 180.0:g}°", "tab:purple", text_radius=78.0)

    ax.plot([xs[3]], [zs[3]], marker="*", color="tab:red", markersize=14)
    ax.text(xs[3], zs[3] - 26.0, f"tool point\n(X, Z) = ({xs[3]:.1f}, {zs[3]:.1f}) mm",
            fontsize=9, ha="center", va="top")
    ax.set_aspect("equal")
    ax.set_xlim(-60.0, 300.0)
    ax.set_ylim(-25.0, 275.0)
    ax.set_xlabel("X, mm (Base = 0: the arm's plane is the X-Z plane)")
    ax.set_ylabel("Z, mm")
    ax.set_title(f"Frames of the 3-DOF arm, Base = {base:g}°, Shoulder = {shoulder:g}°, "
                 f"Elbow = {elbow:g}°\n(a1, a2, a3, a4) = ({GEO.a1:g}, {GEO.a2:g}, "
                 f"{GEO.a3:g}, {GEO.a4:g}) mm; z1, z2, z3 point at the reader")
    ax.grid(True, color="0.92")
    path = out / "kinematics-frames.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def workspace_grid(step_mm: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Region codes on the plane Y = 0: 0 unreachable, 1 front solution, 2 only over the back."""
    low, high = arm.reach_limits(GEO)
    lim = GEO.a2 + high + 10.0
    xs = np.arange(-lim, lim + step_mm, step_mm)
    zs = np.arange(GEO.a1 - high - 10.0, GEO.a1 + high + 10.0 + step_mm, step_mm)
    gx, gz = np.meshgrid(xs, zs)
    radial = np.abs(gx)
    front = np.hypot(radial - GEO.a2, gz - GEO.a1)
    back = np.hypot(-radial - GEO.a2, gz - GEO.a1)
    front_ok = (front >= low) & (front <= high)
    back_ok = (back >= low) & (back <= high)
    code = np.where(front_ok, 1, np.where(back_ok, 2, 0))
    return xs, zs, code


def workspace_figure(out: Path) -> Path:
    """Reachable region in the X-Z plane (Y = 0) for the default geometry."""
    low, high = arm.reach_limits(GEO)
    xs, zs, code = workspace_grid()
    colors = np.array([[1.0, 1.0, 1.0], [0.62, 0.80, 0.95], [0.98, 0.68, 0.35]])

    fig = Figure(figsize=(11.0, 5.6))
    ax, zoom = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.1, 1.0]})
    for a in (ax, zoom):
        a.imshow(colors[code], origin="lower", extent=(xs[0], xs[-1], zs[0], zs[-1]),
                 interpolation="nearest")
        a.axvline(0.0, color="tab:red", lw=1.6)
        a.axhline(0.0, color="0.4", lw=1.0, ls="--")
        for sx in (GEO.a2, -GEO.a2):
            a.plot([sx], [GEO.a1], "k+", markersize=9)
        a.set_aspect("equal")
        a.set_xlabel("X, mm (plane Y = 0)")
    # Outer shell: for X >= 0 the shoulder sits at +a2 (Base = 0), for X <= 0 at -a2
    # (Base = 180 deg); draw each half-circle on its own side.
    for sign, start in ((1.0, -math.pi), (-1.0, 0.0)):
        t = np.linspace(start, start + 2.0 * math.pi, 721)  # each kept half in one piece
        cx = sign * GEO.a2 + high * np.cos(t)
        keep = sign * cx >= 0.0
        ax.plot(cx[keep], GEO.a1 + high * np.sin(t)[keep], color="k", lw=1.0)
    ax.set_ylabel("Z, mm")
    ax.text(GEO.a2 + 6.0, GEO.a1 + 10.0, "shoulder\n(Base = 0)", fontsize=8)
    ax.text(-GEO.a2 - 6.0, GEO.a1 + 10.0, "shoulder\n(Base = 180°)", fontsize=8, ha="right")
    ax.annotate(f"outer shell: Cp = a3 + a4 = {high:g} mm", xy=(GEO.a2 + high * 0.71,
                GEO.a1 + high * 0.71), xytext=(xs[-1] - 4.0, zs[-1] - 4.0), fontsize=8,
                ha="right", va="top", arrowprops={"arrowstyle": "->"})
    ax.annotate("base axis:\nBase undefined,\nErrorId 2 Singular", xy=(0.0, -60.0),
                xytext=(xs[0] + 4.0, zs[0] + 4.0), fontsize=8, color="tab:red", ha="left",
                va="bottom", arrowprops={"arrowstyle": "->", "color": "tab:red"})
    ax.text(-240.0, 4.0, "floor Z = 0 (not checked by the IK)", fontsize=8, color="0.3",
            va="bottom")
    ax.set_title("Reachable targets in the plane Y = 0, default geometry\n(blue: front "
                 "solution, Base = atan2(Y, X); white: ErrorId 1 Unreachable)", fontsize=10)

    zoom.set_xlim(-4.0, 44.0)
    zoom.set_ylim(GEO.a1 - 24.0, GEO.a1 + 24.0)
    zoom.add_patch(Circle((GEO.a2, GEO.a1), low, fill=False, color="k", lw=1.0))
    zoom.text(GEO.a2, GEO.a1 - low - 2.5, f"inner shell\nCp = |a3 − a4| = {low:g} mm",
              fontsize=8, ha="center", va="top")
    zoom.text(GEO.a2 + 2.0, GEO.a1 + 1.5, "shoulder", fontsize=8)
    zoom.text(-2.0, GEO.a1 + 22.5, "orange: the front side cannot\nreach; the IK turns the "
              "base\nby 180° and reaches over the axis", fontsize=8, va="top")
    zoom.set_title("Zoom: around the shoulder", fontsize=10)
    path = out / "kinematics-workspace.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def elbow_figure(out: Path) -> Path:
    """Elbow-up and elbow-down solutions for ELBOW_TARGET, with the shoulder-target line."""
    x, y, z = ELBOW_TARGET
    fig = Figure(figsize=(7.6, 6.0))
    ax = fig.add_subplot()
    ax.axhline(0.0, color="0.55", lw=1.0)
    ax.axvline(0.0, color="0.6", lw=0.9, ls="--")
    ax.plot([0.0, 0.0, GEO.a2], [0.0, GEO.a1, GEO.a1], color="0.35", lw=5,
            solid_capstyle="round")
    for up, color in ((True, "tab:blue"), (False, "tab:orange")):
        b, s, e = arm.inverse(x, y, z, GEO, elbow_up=up)
        pts = arm.joint_points(b, s, e, GEO)
        name = "elbow up" if up else "elbow down"
        ax.plot(pts[1:, 0], pts[1:, 2], "-o", color=color, lw=4, markersize=6,
                label=f"{name}: Shoulder = {s:.1f}°, Elbow = {e:.1f}°")
        ax.text(pts[2, 0] + (6.0 if up else 8.0), pts[2, 2] + (6.0 if up else -10.0), name,
                color=color, fontsize=10)
    ax.plot([GEO.a2, x], [GEO.a1, z], color="k", lw=1.0, ls="--")
    phi = math.degrees(math.atan2(z - GEO.a1, x - GEO.a2))
    cp = math.hypot(x - GEO.a2, z - GEO.a1)
    ax.text((GEO.a2 + x) / 2.0 + 4.0, (GEO.a1 + z) / 2.0 - 10.0,
            f"Cp = {cp:.1f} mm\natan2(Zp, Xp) = {phi:.1f}°", fontsize=9, va="top")
    ax.plot([x], [z], marker="*", color="tab:red", markersize=15, zorder=5)
    ax.text(x + 6.0, z + 6.0, f"target ({x:g}, {y:g}, {z:g}) mm", fontsize=9)
    ax.set_aspect("equal")
    ax.set_xlim(-30.0, 260.0)
    ax.set_ylim(-15.0, 260.0)
    ax.set_xlabel("X, mm")
    ax.set_ylabel("Z, mm")
    ax.set_title("Two solutions for one target (Base = 0°):\nShoulder = atan2(Zp, Xp) ± α; "
                 "Elbow = β (up) or 360° − β (down)", fontsize=10)
    ax.legend(loc="upper left", fontsize=9)
    ax.grid(True, color="0.92")
    path = out / "kinematics-elbow-up-down.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def servo_figure(out: Path) -> Path:
    """MG996R angle -> pulse line with the PCA9685's 12-bit steps, and a zoom on them."""
    fig = Figure(figsize=(11.0, 4.6))
    ax, zoom = fig.subplots(1, 2)
    angles = np.linspace(-60.0, 60.0, 241)
    ax.plot(angles, 1500.0 + US_PER_DEG * angles, color="tab:blue")
    for deg, pulse, counts in ((-60.0, 1000.0, 205), (0.0, 1500.0, 307), (60.0, 2000.0, 410)):
        ax.plot([deg], [pulse], "o", color="tab:red")
        right = deg < 60.0
        ax.annotate(f"{pulse:g} µs = {deg:g}°\n→ {counts} counts = {counts * COUNT_US:.1f} µs",
                    xy=(deg, pulse), xytext=(deg + 6.0, pulse + 40.0) if right
                    else (deg - 6.0, pulse - 120.0), fontsize=9, ha="left" if right
                    else "right")
    ax.set_xlabel("servo angle, deg")
    ax.set_ylabel("pulse width, µs (period 20 ms, 50 Hz)")
    ax.set_title("MG996R: 1000..2000 µs = −60..+60° (8.33 µs/°)", fontsize=10)
    ax.grid(True, color="0.9")

    fine = np.linspace(-3.0, 3.0, 2001)
    fine_pulse = 1500.0 + US_PER_DEG * fine
    counts_fine = np.floor(fine_pulse / COUNT_US + 0.5)
    achieved = (counts_fine * COUNT_US - 1500.0) / US_PER_DEG
    zoom.plot(fine, fine, color="tab:blue", lw=1.0, label="wanted")
    zoom.step(fine, achieved, where="mid", color="tab:red", label="after rounding to counts")
    zoom.set_xlabel("wanted servo angle, deg")
    zoom.set_ylabel("achieved servo angle, deg")
    zoom.set_title(f"PCA9685 at prescale {PRESCALE}: 1 count = {COUNT_US:.2f} µs "
                   f"= {COUNT_US / US_PER_DEG:.3f}°", fontsize=10)
    zoom.legend(fontsize=9)
    zoom.grid(True, color="0.9")
    path = out / "servo-pwm-steps.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


FIGURES: dict[str, Callable[[Path], Path]] = {
    "kinematics-frames.png": frames_figure,
    "kinematics-workspace.png": workspace_figure,
    "kinematics-elbow-up-down.png": elbow_figure,
    "servo-pwm-steps.png": servo_figure,
}


def main(argv: Sequence[str] | None = None) -> int:
    _, out = figure_target("armbench.plots.teaching", argv)
    for make in FIGURES.values():
        print(f"wrote {make(out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
