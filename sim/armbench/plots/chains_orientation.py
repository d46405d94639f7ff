"""Figures of docs/fixed-point.md (document 003's line) and docs/orientation-ik.md.

Compiles the ST library with the bench's compiler and runs the blocks themselves:

* ``chain-fixed-line-error.png``: path error of ``ChainResolvedRateFixed`` (fixed point)
  along document 003's line, beside numpy's pinv (float64) and the same algorithm in float32
  (``armbench.plant.redundant_chain``);
* ``orientation-ik-modes.png``: ``InverseKinematik5Axis`` in document 004's two modes, arm
  poses drawn in the arm plane from ``ForwardKinematic5Axis``.

    python -m armbench.plots.chains_orientation          # docs/figures/
    python -m armbench.plots.chains_orientation --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from armbench.plant import redundant_chain as rc
from armbench.plots.cli import figure_target

FIGURES = ("chain-fixed-line-error.png", "orientation-ik-modes.png")
GEO_5AXIS = {"Arm": {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}, "ToolMm": 60.0}


def line_joints(module: Any) -> NDArray[np.float64]:
    """Joints (rad) of the fixed-point block along the line, rows 0..100."""
    points = rc.line_points()
    init = rc.to_turn24(rc.start_configuration(points[0]))
    fb = module.new_fb("ChainResolvedRateFixed")
    rows = []
    for k, x in enumerate(points):
        xu, yu, zu = (int(round(float(v) * 1e6)) for v in x)
        fb(TargetXUm=xu, TargetYUm=yu, TargetZUm=zu, Geometry=rc.DEFAULT_CHAIN.as_st_um(),
           DampingUm=0, Reset=k == 0, InitJoints=init)
        if not fb.Valid:
            raise RuntimeError(f"ChainResolvedRateFixed refused step {k}: ErrorId {fb.ErrorId}")
        rows.append(rc.from_turn24(fb.Joints))
    return np.array(rows)


def arm_plane(module: Any, angles: dict[str, float]) -> NDArray[np.float64]:
    """Points (radial, z) of base, shoulder, elbow, flange and tip for one pose."""
    fk = module.new_fb("ForwardKinematic5Axis")
    fk(Angles=angles, Geometry=GEO_5AXIS)
    arm = GEO_5AXIS["Arm"]
    assert isinstance(arm, dict)
    s = math.radians(angles["Shoulder"])
    b = math.radians(angles["Base"])
    shoulder = (arm["A2"], arm["A1"])
    elbow = (shoulder[0] + arm["A3"] * math.cos(s), shoulder[1] + arm["A3"] * math.sin(s))

    def radial(x: float, y: float) -> float:
        return x * math.cos(b) + y * math.sin(b)

    return np.array([(0.0, 0.0), (0.0, arm["A1"]), shoulder, elbow,
                     (radial(fk.FlangeXMm, fk.FlangeYMm), fk.FlangeZMm),
                     (radial(fk.TipXMm, fk.TipYMm), fk.TipZMm)])


def main(argv: Sequence[str] | None = None) -> int:
    checkout, out = figure_target("armbench.plots.chains_orientation", argv)

    import matplotlib.pyplot as plt

    from armbench.compiler import compile_files

    module = compile_files(sorted(checkout.st_dir.glob("*.st")))

    # --- document 003's line
    points = rc.line_points()
    q0 = rc.from_turn24(rc.to_turn24(rc.start_configuration(points[0])))
    fixed = rc.path_errors(line_joints(module), points) * 1e6
    f64 = rc.path_errors(rc.track_pinv64(points, q0), points) * 1e6
    f32 = rc.path_errors(rc.track_float32(points, q0), points) * 1e6
    k = np.arange(1, len(points))
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    ax.plot(k, f64, label=f"float64, numpy pinv (max {f64.max():.1f} µm)", lw=2.5)
    ax.plot(k, f32, "--", label=f"float32, same algorithm (max {f32.max():.1f} µm)")
    ax.plot(k, fixed, label=f"fixed point ST, Q24/Q18 (max {fixed.max():.1f} µm)")
    ax.set_xlabel("interval k")
    ax.set_ylabel("|FK(q_k) − X_k|, µm")
    ax.set_title("Document 003's line, 100 intervals, resolved rate dq = J⁺ dX\n"
                 "(4-joint chain 0.5/0.1/0.8/0.6/0.3 m; error against the float64 FK)",
                 fontsize=10)
    ax.grid(True, color="0.9")
    ax.legend(fontsize=9)
    line_png = out / FIGURES[0]
    fig.savefig(line_png, dpi=110, bbox_inches="tight")
    plt.close(fig)

    # --- document 004's two modes
    ik = module.new_fb("InverseKinematik5Axis")
    common = {"RollDeg": 0.0, "DirX": 0.0, "DirY": 0.0, "DirZ": 0.0, "ElbowUp": True,
              "UseToolVector": False, "Geometry": GEO_5AXIS}
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.8), sharey=True)
    for ax, tip_fixed, point, title in (
            (axes[0], True, (170.0, 0.0, 80.0), "tip fixed (170, 0, 80) mm"),
            (axes[1], False, (150.0, 0.0, 140.0), "flange fixed (150, 0, 140) mm")):
        for pitch in np.linspace(-90.0, 60.0, 6):
            ik(XMm=point[0], YMm=point[1], ZMm=point[2], TipFixed=tip_fixed,
               PitchDeg=float(pitch), **common)
            if not ik.Valid:
                continue
            pts = arm_plane(module, ik.Angles)
            line, = ax.plot(pts[:5, 0], pts[:5, 1], "o-", lw=1.5, ms=3,
                            label=f"pitch {pitch:+.0f}°")
            ax.plot(pts[4:, 0], pts[4:, 1], "-", lw=3, color=line.get_color())
        ax.plot(point[0], point[2], "k*", ms=12)
        ax.set_title(f"InverseKinematik5Axis, {title}", fontsize=10)
        ax.set_xlabel("radial distance, mm")
        ax.set_aspect("equal")
        ax.grid(True, color="0.9")
        ax.legend(fontsize=8, loc="lower left")
    axes[0].set_ylabel("Z, mm")
    modes_png = out / FIGURES[1]
    fig.savefig(modes_png, dpi=110, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {line_png} and {modes_png}")
    print(f"003 line path error, um: float64 {f64.max():.2f}, float32 {f32.max():.2f}, "
          f"fixed {fixed.max():.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
