"""Reference model of the redundant 4-joint chain of document 003's line test, in numpy.

The chain (``st/KinematicsChainFixed.st``): joint 1 yaw about Z, joints 2..4 pitch of the
links A3, A4, A5 (relative angles), shoulder at height A1 and radial offset A2. Written from
the closed form (radial distance and height as sums of link projections), not from the ST.

Two resolved-rate integrators over the seed's line, both closed loop
(``dX = X_k - FK(q_(k-1))``, the ST block's rule):

* :func:`track_pinv64` -- float64 with ``numpy.linalg.pinv`` (the tests' reference);
* :func:`track_float32` -- the ST block's algorithm (adjugate of ``J J^T``, determinant,
  ``J^T``) with every value rounded to float32, i.e. what a REAL implementation computes.

Lengths in metres, angles in radians at every function.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# Document 003's test line, metres, 100 equal intervals
LINE_START = (0.522689, -0.818450, 0.472752)
LINE_END = (0.771439, -0.965700, 0.721502)
LINE_INTERVALS = 100
TURN24 = 2 ** 24  # the ST block's angle unit: 2^24 = one turn


@dataclass(frozen=True)
class ChainGeometry:
    """Link lengths of the chain, metres (defaults: the chain of the 003 line test)."""

    a1: float = 0.5  # shoulder height
    a2: float = 0.1  # shoulder offset from the base axis
    a3: float = 0.8  # upper arm
    a4: float = 0.6  # forearm
    a5: float = 0.3  # wrist link

    def as_st_um(self) -> dict[str, int]:
        """The geometry as the ST struct ``ChainGeometryFixed`` (micrometres)."""
        return {f"A{i}Um": round(v * 1e6)
                for i, v in enumerate((self.a1, self.a2, self.a3, self.a4, self.a5), start=1)}


DEFAULT_CHAIN = ChainGeometry()


def line_points(n: int = LINE_INTERVALS) -> FloatArray:
    """The n + 1 points of the seed's straight line (row 0 = start), metres."""
    start, end = np.array(LINE_START), np.array(LINE_END)
    points: FloatArray = start + (end - start) * (np.arange(n + 1)[:, None] / n)
    return points


def forward(q: FloatArray, geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """Position of the chain's end point for joints q (rad), metres."""
    p2 = q[1]
    p3 = p2 + q[2]
    p4 = p3 + q[3]
    r = geo.a2 + geo.a3 * np.cos(p2) + geo.a4 * np.cos(p3) + geo.a5 * np.cos(p4)
    z = geo.a1 + geo.a3 * np.sin(p2) + geo.a4 * np.sin(p3) + geo.a5 * np.sin(p4)
    return np.array([r * np.cos(q[0]), r * np.sin(q[0]), z])


def jacobian(q: FloatArray, geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """3 x 4 position Jacobian, m/rad (analytic)."""
    phi = np.cumsum(q[1:])
    links = np.array([geo.a3, geo.a4, geo.a5], dtype=q.dtype)  # float32 stays float32
    sr = np.cumsum((links * np.cos(phi))[::-1])[::-1]  # sum over links k.. of A cos phi
    sz = np.cumsum((links * np.sin(phi))[::-1])[::-1]
    x, y, _ = forward(q, geo)
    jac = np.zeros((3, 4), dtype=q.dtype)
    jac[:, 0] = (-y, x, 0.0)
    jac[0, 1:] = -np.cos(q[0]) * sz
    jac[1, 1:] = -np.sin(q[0]) * sz
    jac[2, 1:] = sr
    return jac


def start_configuration(point: FloatArray, geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """Joints (rad) that reach ``point`` with the wrist link horizontal and the elbow up
    (document 001's reduced-DOF rule picks the redundant joint); ValueError if out of reach."""
    base = float(np.arctan2(point[1], point[0]))
    rho = float(np.hypot(point[0], point[1])) - geo.a2 - geo.a5
    height = float(point[2]) - geo.a1
    c = float(np.hypot(rho, height))
    cos_beta = (geo.a3 ** 2 + geo.a4 ** 2 - c * c) / (2 * geo.a3 * geo.a4)
    cos_alpha = (geo.a3 ** 2 + c * c - geo.a4 ** 2) / (2 * geo.a3 * c)
    if not (-1.0 <= cos_beta <= 1.0 and -1.0 <= cos_alpha <= 1.0):
        raise ValueError(f"point {point} is out of reach with a horizontal wrist link")
    shoulder = float(np.arctan2(height, rho)) + float(np.arccos(cos_alpha))
    elbow = -(np.pi - float(np.arccos(cos_beta)))
    return np.array([base, shoulder, elbow, -(shoulder + elbow)])


def track_pinv64(points: FloatArray, q0: FloatArray,
                 geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """Joints after each step (rows 1..n; row 0 = q0) with dq = pinv(J) (X_k - FK(q))."""
    qs = [np.array(q0, dtype=np.float64)]
    for target in points[1:]:
        q = qs[-1]
        qs.append(q + np.linalg.pinv(jacobian(q, geo)) @ (target - forward(q, geo)))
    return np.array(qs)


def track_float32(points: FloatArray, q0: FloatArray,
                  geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """The ST block's algorithm in float32: A = J J^T, its adjugate and determinant,
    dq = J^T adj(A) dX / det(A); every intermediate rounded to float32."""
    f = np.float32
    g32 = ChainGeometry(*(float(f(v)) for v in (geo.a1, geo.a2, geo.a3, geo.a4, geo.a5)))
    q = np.array(q0, dtype=np.float32)
    out = [q.astype(np.float64)]
    for target in points[1:].astype(np.float32):
        # the closed forms in float32: numpy keeps float32 through sin, cos and sums
        pos = forward(q, g32).astype(np.float32)  # type: ignore[arg-type]
        jac = jacobian(q, g32).astype(np.float32)  # type: ignore[arg-type]
        err = (target - pos).astype(np.float32)
        a = (jac @ jac.T).astype(np.float32)
        adj = np.array([
            [a[1, 1] * a[2, 2] - a[1, 2] * a[1, 2], a[0, 2] * a[1, 2] - a[0, 1] * a[2, 2],
             a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]],
            [a[0, 2] * a[1, 2] - a[0, 1] * a[2, 2], a[0, 0] * a[2, 2] - a[0, 2] * a[0, 2],
             a[0, 1] * a[0, 2] - a[0, 0] * a[1, 2]],
            [a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1], a[0, 1] * a[0, 2] - a[0, 0] * a[1, 2],
             a[0, 0] * a[1, 1] - a[0, 1] * a[0, 1]]], dtype=np.float32)
        det = f(a[0, 0] * adj[0, 0] + a[0, 1] * adj[0, 1] + a[0, 2] * adj[0, 2])
        dq = (jac.T @ (adj @ err).astype(np.float32)).astype(np.float32) / det
        q = (q + dq.astype(np.float32)).astype(np.float32)
        out.append(q.astype(np.float64))
    return np.array(out)


def path_errors(qs: FloatArray, points: FloatArray,
                geo: ChainGeometry = DEFAULT_CHAIN) -> FloatArray:
    """|FK(q_k) - X_k| in metres for k = 1..n, with the float64 FK (the true arm)."""
    return np.array([float(np.linalg.norm(forward(q, geo) - x))
                     for q, x in zip(qs[1:], points[1:], strict=True)])


def to_turn24(q: FloatArray) -> list[int]:
    """Radians to the ST block's Turn24 integers (rounded)."""
    return [int(round(float(v) * TURN24 / (2 * np.pi))) for v in q]


def from_turn24(q: list[int] | FloatArray) -> FloatArray:
    """The ST block's Turn24 integers to radians."""
    return np.asarray(q, dtype=np.float64) * (2 * np.pi / TURN24)
