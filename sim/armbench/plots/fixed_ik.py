"""Error plots of the integer-only IK (st/KinematicsFixed.st) against float64.

Runs InverseKinematikFixed (through the bench's ST compiler) over a grid of integer targets
in the arm's vertical plane and over random 3-D targets, compares with the float64 reference
``armbench.plant.arm.inverse`` at the same targets, and writes PNGs for docs/fixed-point.md:

    python -m armbench.plots.fixed_ik            # docs/figures/fixed-ik-error-*.png
    python -m armbench.plots.fixed_ik --out DIR

Part of the plots package, the only one that imports matplotlib.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from armbench.plant import arm
from armbench.plots.cli import figure_target

SOURCES = ["ArmAngles.st", "Kinematics.st", "KinematicsFixed.st", "KinematicsFixedTables.st"]
GEO_FIXED = {"A1Mm100": 10000, "A2Mm100": 2000, "A3Mm100": 12000, "A4Mm100": 13000}


def _wrap(d: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.abs((d + 180.0) % 360.0 - 180.0)


def plane_errors(module: Any, step_mm: float = 2.0, elbow_up: bool = True
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Max joint error (deg) on a grid in the plane Y = 0 (X >= 0.01 mm); NaN off the shell."""
    geometry = arm.DEFAULT_GEOMETRY
    high = geometry.a3 + geometry.a4
    xs = np.arange(0.01, geometry.a2 + high + step_mm, step_mm)
    zs = np.arange(geometry.a1 - high - step_mm, geometry.a1 + high + step_mm, step_mm)
    ik = module.new_fb("InverseKinematikFixed")
    err = np.full((len(zs), len(xs)), np.nan)
    for i, z in enumerate(zs):
        for j, x in enumerate(xs):
            xi, zi = round(x * 100), round(z * 100)
            try:
                ref = arm.inverse(xi / 100, 0.0, zi / 100, geometry, elbow_up)
            except ValueError:
                continue
            ik(XMm100=xi, YMm100=0, ZMm100=zi, ElbowUp=elbow_up, Geometry=GEO_FIXED)
            if not ik.Valid:
                continue
            a = ik.Angles
            got = np.array([a["BaseDeg100"], a["ShoulderDeg100"], a["ElbowDeg100"]]) / 100
            err[i, j] = float(_wrap(got - np.array(ref)).max())
    return xs, zs, err


def random_errors(module: Any, count: int = 10_000, seed: int = 1
                  ) -> NDArray[np.float64]:
    """(count, 3) joint errors (deg) at random reachable integer targets, elbow up."""
    geometry = arm.DEFAULT_GEOMETRY
    rng = np.random.default_rng(seed)
    ik = module.new_fb("InverseKinematikFixed")
    out: list[NDArray[np.float64]] = []
    high = geometry.a2 + geometry.a3 + geometry.a4
    while len(out) < count:
        r, z, b = rng.uniform(0, high), rng.uniform(-high, high) + geometry.a1, \
            rng.uniform(-math.pi, math.pi)
        xi, yi, zi = round(r * math.cos(b) * 100), round(r * math.sin(b) * 100), round(z * 100)
        try:
            ref = arm.inverse(xi / 100, yi / 100, zi / 100, geometry, True)
        except ValueError:
            continue
        ik(XMm100=xi, YMm100=yi, ZMm100=zi, ElbowUp=True, Geometry=GEO_FIXED)
        if not ik.Valid:
            continue
        a = ik.Angles
        got = np.array([a["BaseDeg100"], a["ShoulderDeg100"], a["ElbowDeg100"]]) / 100
        out.append(_wrap(got - np.array(ref)))
    return np.array(out)


def main(argv: Sequence[str] | None = None) -> int:
    checkout, out = figure_target("armbench.plots.fixed_ik", argv)

    import matplotlib.pyplot as plt

    from armbench.compiler import compile_files

    module = compile_files([checkout.st_dir / name for name in SOURCES])

    xs, zs, err = plane_errors(module)
    fig, ax = plt.subplots(figsize=(7.0, 6.0))
    mesh = ax.pcolormesh(xs, zs, err, shading="nearest", cmap="viridis", vmin=0.0, vmax=0.01)
    fig.colorbar(mesh, ax=ax, label="max joint error, deg")
    ax.set_aspect("equal")
    ax.set_xlabel("X (radial), mm")
    ax.set_ylabel("Z, mm")
    ax.set_title("InverseKinematikFixed vs float64, plane Y = 0, elbow up\n"
                 f"max {np.nanmax(err):.4f} deg, mean {np.nanmean(err):.4f} deg "
                 "(output step 0.01 deg)")
    plane_png = out / "fixed-ik-error-plane.png"
    fig.savefig(plane_png, dpi=110, bbox_inches="tight")
    plt.close(fig)

    errs = random_errors(module)
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    bins = np.linspace(0.0, 0.006, 61).tolist()
    for j, name in enumerate(("Base", "Shoulder", "Elbow")):
        ax.hist(errs[:, j], bins=bins, histtype="step", label=f"{name}: max "
                f"{errs[:, j].max():.4f}, mean {errs[:, j].mean():.4f}")
    ax.axvline(0.005, color="grey", linestyle=":", label="half output step (0.005 deg)")
    ax.set_xlabel("joint error, deg")
    ax.set_ylabel("targets")
    ax.set_title(f"{len(errs)} random reachable targets, elbow up")
    ax.legend(fontsize=8)
    hist_png = out / "fixed-ik-error-hist.png"
    fig.savefig(hist_png, dpi=110, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {plane_png} and {hist_png}")
    print(f"plane: max {np.nanmax(err):.5f} mean {np.nanmean(err):.5f} deg; random: max "
          f"{errs.max(axis=0).round(5).tolist()} mean {errs.mean(axis=0).round(5).tolist()} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
