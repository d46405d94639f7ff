"""Figures for the kinematic-chain chapters (docs/frames-dh.md, docs/jacobians.md), computed
by the ST library itself (st/KinematicsChain.st, st/Kinematics4Axis.st through the bench's
compiler):

    python -m armbench.plots.chains            # docs/figures/chains-*.png, see FIGURES
    python -m armbench.plots.chains --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from armbench.plots.cli import figure_target

SOURCES = ["ArmAngles.st", "Kinematics.st", "KinematicsChain.st", "Kinematics4Axis.st"]

# Puma 560, standard DH (Corke's published table, in mm and deg): a, alpha, d, offset
PUMA_DH = [(0.0, 90.0, 671.8), (431.8, 0.0, 0.0), (20.3, -90.0, 150.05),
           (0.0, 90.0, 431.8), (0.0, -90.0, 0.0), (0.0, 0.0, 0.0)]
GEO4 = {"BaseHeightMm": 100.0, "ShoulderOffsetMm": 20.0, "UpperArmMm": 120.0,
        "ForearmMm": 130.0, "WristLinkMm": 40.0, "ToolDropMm": 15.0}
TWO_LINK = (300.0, 200.0)  # mm, the planar arm of the Jacobian chapter


def link(a: float = 0.0, alpha: float = 0.0, d: float = 0.0) -> dict[str, Any]:
    return {"A": a, "AlphaDeg": alpha, "D": d, "ThetaOffsetDeg": 0.0, "Prismatic": False,
            "LowerLimit": 0.0, "UpperLimit": 0.0}


def puma_chain() -> dict[str, Any]:
    return {"Links": [link(a, al, d) for a, al, d in PUMA_DH], "Count": 6,
            "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0}


def two_link_chain() -> dict[str, Any]:
    return {"Links": [link(TWO_LINK[0]), link(TWO_LINK[1])] + [link()] * 4, "Count": 2,
            "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0}


def _draw_frames(ax: Any, frames: NDArray[np.float64], count: int, size: float,
                 tool: NDArray[np.float64] | None, title: str) -> None:
    origins = frames[: count + 1, :3, 3]
    pts = origins if tool is None else np.vstack([origins, tool[None, :]])
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="0.3", linewidth=3, zorder=1)
    for i in range(count + 1):
        o = frames[i, :3, 3]
        for axis, colour in zip(range(3), ("tab:red", "tab:green", "tab:blue"), strict=True):
            d = frames[i, :3, axis] * size
            ax.quiver(o[0], o[1], o[2], d[0], d[1], d[2], color=colour, linewidth=1.5)
        ax.text(o[0], o[1], o[2] + size * 0.3, f"{i}", fontsize=9)
    span = float(np.ptp(pts, axis=0).max()) / 2.0 + size
    mid = (pts.max(axis=0) + pts.min(axis=0)) / 2.0
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(mid[2] - span, mid[2] + span)
    ax.set_xlabel("X, mm")
    ax.set_ylabel("Y, mm")
    ax.set_zlabel("Z, mm")
    ax.set_title(title, fontsize=10)


def frames_figure(module: Any, out: Path) -> Path:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11.0, 5.2))
    q_puma = [20.0, 60.0, -150.0, 0.0, 45.0, 0.0]
    frames = np.array([f["Pose"] for f in
                       module.call("ChainFramePoses", Chain=puma_chain(), Joints=q_puma)])
    _draw_frames(fig.add_subplot(1, 2, 1, projection="3d"), frames, 6, 120.0, None,
                 "Puma 560, standard DH: frame i on joint i+1's axis\n"
                 f"q = {q_puma} deg (x red, y green, z blue)")
    chain: dict[str, Any] = {"Links": [link()] * 6}
    _, outs = module.call_full("Arm4AxisFillChain", Geometry=GEO4, Chain=chain)
    q4 = [30.0, 50.0, -100.0, 50.0, 0.0, 0.0]
    frames4 = np.array([f["Pose"] for f in
                        module.call("ChainFramePoses", Chain=outs["Chain"], Joints=q4)])
    tool = np.array(module.call("ForwardKinematic_4Axis", Geometry=GEO4, Joints=q4))[:3, 3]
    _draw_frames(fig.add_subplot(1, 2, 2, projection="3d"), frames4, 4, 30.0, tool,
                 "Document 001's 4-axis arm, modified DH: frame i on joint i's axis\n"
                 f"q = {q4[:4]} deg, last link horizontal")
    path = out / "chains-frames.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def manipulability_grid(module: Any, step_deg: float = 3.0
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                   NDArray[np.float64]]:
    """q2 (deg), sigma_min and sqrt(det(J J^T)) of the planar 2-link arm's 2x2 position
    Jacobian (ST's ChainJacobianPosition) at q1 = 0 -- they do not depend on q1."""
    chain = two_link_chain()
    q2s = np.arange(-180.0, 180.0 + step_deg, step_deg)
    sig = np.zeros(len(q2s))
    w = np.zeros(len(q2s))
    for i, q2 in enumerate(q2s):
        J = np.array(module.call("ChainJacobianPosition", Chain=chain,
                                 Joints=[0.0, float(q2), 0.0, 0.0, 0.0, 0.0]))[:2, :2]
        s = np.linalg.svd(J / 1000.0, compute_uv=False)  # m per rad
        sig[i] = s.min()
        w[i] = s.prod()
    return q2s, sig, w


def jacobian_figure(module: Any, out: Path) -> Path:
    import matplotlib.pyplot as plt

    q2s, sig, w = manipulability_grid(module)
    a1, a2 = (v / 1000.0 for v in TWO_LINK)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    left.plot(q2s, w, label=r"$w=\sqrt{\det JJ^T}$ (ST Jacobian)")
    left.plot(q2s, a1 * a2 * np.abs(np.sin(np.radians(q2s))), "k:",
              label=r"closed form $a_1 a_2 |\sin q_2|$")
    left.plot(q2s, sig, label=r"$\sigma_{min}$, m/rad")
    left.set_xlabel("elbow angle q2, deg")
    left.set_ylabel("m² / rad², m / rad")
    left.set_title(f"planar 2-link arm a1 = {TWO_LINK[0]:.0f}, a2 = {TWO_LINK[1]:.0f} mm:\n"
                   "singular at q2 = 0 (stretched) and ±180 (folded)", fontsize=10)
    left.legend(fontsize=8)
    left.grid(True, color="0.9")
    sigma = np.logspace(-4, 0, 400)
    right.loglog(sigma, 1.0 / sigma, "k:", label=r"pseudo-inverse $1/\sigma$")
    for lam in (0.01, 0.05, 0.2):
        right.loglog(sigma, sigma / (sigma**2 + lam**2), label=rf"DLS $\lambda$ = {lam}")
    right.set_xlabel(r"singular value $\sigma$ (scaled)")
    right.set_ylabel("gain from task error to joint step")
    right.set_title(r"DLS: gain $\sigma/(\sigma^2+\lambda^2) \leq 1/(2\lambda)$", fontsize=10)
    right.set_ylim(0.5, 1.0e4)
    right.legend(fontsize=8)
    right.grid(True, which="both", color="0.9")
    path = out / "chains-singularity.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def chain_pose(T: NDArray[np.float64]) -> dict[str, list[float]]:
    """InverseKinematik_Chain's Target, a ChainPose: the columns of the 4x4 pose ``T``."""
    return {"AxisX": T[:3, 0].tolist(), "AxisY": T[:3, 1].tolist(),
            "AxisZ": T[:3, 2].tolist(), "Origin": T[:3, 3].tolist()}


def convergence_runs(module: Any) -> list[tuple[str, list[float]]]:
    """Residual (mm) per iteration of InverseKinematik_Chain on the Puma 560, one scan per
    iteration, for seeds at increasing distance from a solution and near the wrist
    singularity (q5 = 0)."""
    chain = puma_chain()
    runs: list[tuple[str, list[float]]] = []
    goal = [30.0, 40.0, -120.0, 20.0, 50.0, 10.0]
    target = np.array(module.call("ForwardKinematic_Chain", Chain=chain, Joints=goal))
    singular_goal = [30.0, 40.0, -120.0, 20.0, 0.5, 10.0]
    singular_target = np.array(module.call("ForwardKinematic_Chain", Chain=chain,
                                           Joints=singular_goal))
    cases = [("seed 10° off", target, [g + 10.0 for g in goal]),
             ("seed 45° off", target, [g + 45.0 for g in goal]),
             ("seed 120° off", target, [g - 120.0 for g in goal]),
             ("target at q5 = 0.5° (wrist singular), seed 20° off", singular_target,
              [g + 20.0 for g in singular_goal])]
    for name, tgt, seed in cases:
        ik = module.new_fb("InverseKinematik_Chain")
        ik(Execute=True, Chain=chain, Target=chain_pose(tgt), Seed=seed, ItersPerScan=1,
           MaxIters=200, TolMm=1e-4, TolDeg=1e-4)
        res = [float(ik.ResidualMm)]
        while ik.Busy:
            ik(Execute=True)
            res.append(max(float(ik.ResidualMm), 1e-6))
        runs.append((f"{name}: {'converged' if ik.Done else f'ErrorId {ik.ErrorId}'} "
                     f"in {ik.Iterations}", res))
    return runs


def convergence_figure(module: Any, out: Path) -> Path:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for name, res in convergence_runs(module):
        ax.semilogy(range(len(res)), res, marker=".", label=name)
    ax.axhline(1e-4, color="grey", linestyle=":", label="tolerance 1e-4 mm")
    ax.set_xlabel("iteration (one per scan with ItersPerScan = 1)")
    ax.set_ylabel("position residual, mm")
    ax.set_title("InverseKinematik_Chain on the Puma 560 (6-D pose task, REAL)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", color="0.9")
    path = out / "chains-dls-convergence.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


FIGURES: dict[str, Callable[[Any, Path], Path]] = {
    "chains-frames.png": frames_figure,
    "chains-singularity.png": jacobian_figure,
    "chains-dls-convergence.png": convergence_figure,
}


def main(argv: Sequence[str] | None = None) -> int:
    checkout, out = figure_target("armbench.plots.chains", argv)


    from armbench.compiler import compile_files

    module = compile_files([checkout.st_dir / name for name in SOURCES])
    for make in FIGURES.values():
        print(f"wrote {make(module, out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
