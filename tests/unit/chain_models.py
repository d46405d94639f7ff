"""Helpers for the kinematic-chain suites: Robotics Toolbox robots as KinematicChain dicts
(st/KinematicsChain.st), and the reference models the tests compare with (the toolbox's
Puma 560, document 001's 4-axis arm as a modified-DH DHRobot). The toolbox is imported inside
the functions that build robots, so that a suite can skip cleanly where it is absent.

The ST library works in mm and deg; the toolbox's Puma 560 is in metres and radians, so
lengths are scaled by 1000 on the way in and the toolbox's linear results on the way out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

MM_PER_M = 1000.0
FIELDS = ("A", "AlphaDeg", "D", "ThetaOffsetDeg", "Prismatic", "LowerLimit", "UpperLimit")


def empty_link() -> dict[str, Any]:
    return {"A": 0.0, "AlphaDeg": 0.0, "D": 0.0, "ThetaOffsetDeg": 0.0, "Prismatic": False,
            "LowerLimit": 0.0, "UpperLimit": 0.0}


def chain_of(robot: Any, scale: float = 1.0, limits: bool = False,
             tool: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> dict[str, Any]:
    """A toolbox DHRobot as a KinematicChain dict; lengths times ``scale``.

    Only the tool translation is carried over (the ST chain's tool is a point in the last
    frame); pass it explicitly in the chain's units.
    """
    links = []
    modified = bool(robot.mdh)
    for link in robot.links:
        prismatic = not link.isrevolute
        entry = {
            "A": float(link.a) * scale,
            "AlphaDeg": math.degrees(link.alpha),
            "D": float(link.d) * scale,
            "ThetaOffsetDeg": math.degrees(link.theta) if prismatic else
            math.degrees(link.offset),
            "Prismatic": prismatic,
            "LowerLimit": 0.0,
            "UpperLimit": 0.0,
        }
        if prismatic:
            entry["D"] = float(link.offset) * scale  # the toolbox adds its offset to q
        if limits and link.qlim is not None:
            lo, hi = (float(v) for v in link.qlim)
            conv = scale if prismatic else math.degrees(1.0)
            entry["LowerLimit"], entry["UpperLimit"] = lo * conv, hi * conv
        links.append(entry)
    while len(links) < 6:
        links.append(empty_link())
    return {"Links": links, "Count": robot.n, "Modified": modified,
            "ToolX": tool[0], "ToolY": tool[1], "ToolZ": tool[2]}


def joints_st(robot: Any, q: NDArray[np.float64], scale: float = 1.0) -> list[float]:
    """Toolbox joint values (rad / m) as a JointVector (deg / mm), padded to six."""
    out = [float(v) * scale if not link.isrevolute else math.degrees(float(v))
           for v, link in zip(q, robot.links, strict=True)]
    return out + [0.0] * (6 - len(out))


def joints_rtb(robot: Any, joints: list[float], scale: float = 1.0) -> NDArray[np.float64]:
    return np.array([v / scale if not link.isrevolute else math.radians(v)
                     for v, link in zip(joints, robot.links, strict=False)])


def pose_st(T: NDArray[np.float64], scale: float) -> list[list[float]]:
    """A toolbox pose (4x4, metres) as a Mat4 in mm."""
    out = np.array(T, dtype=float)
    out[:3, 3] *= scale
    rows: list[list[float]] = out.tolist()
    return rows


def chain_pose(T: Any, scale: float = 1.0) -> dict[str, list[float]]:
    """A 4x4 pose as InverseKinematik_Chain's Target, a ChainPose: the matrix's columns 1..4
    (rows 1..3) as AxisX, AxisY, AxisZ and Origin, the Origin times ``scale`` (MM_PER_M for
    a toolbox pose in metres)."""
    m = np.array(T, dtype=float)
    return {"AxisX": m[:3, 0].tolist(), "AxisY": m[:3, 1].tolist(),
            "AxisZ": m[:3, 2].tolist(), "Origin": (m[:3, 3] * scale).tolist()}


def rotation_angle_deg(Ra: NDArray[np.float64], Rb: NDArray[np.float64]) -> float:
    c = (np.trace(Ra @ Rb.T) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


# document 001's 4-axis arm (st/Kinematics4Axis.st's Arm4AxisGeometry), mm
FOUR_AXIS_GEO = {"BaseHeightMm": 100.0, "ShoulderOffsetMm": 20.0, "UpperArmMm": 120.0,
                 "ForearmMm": 130.0, "WristLinkMm": 40.0, "ToolDropMm": 15.0}


def four_axis_rtb(g: dict[str, float] = FOUR_AXIS_GEO) -> Any:
    """Document 001's modified-DH table as a toolbox DHRobot (float64, mm), the horizontal
    last link and the tool drop as its tool transform."""
    import roboticstoolbox as rtb
    import spatialmath as sm

    return rtb.DHRobot([
        rtb.RevoluteMDH(d=g["BaseHeightMm"]),
        rtb.RevoluteMDH(a=g["ShoulderOffsetMm"], alpha=math.pi / 2),
        rtb.RevoluteMDH(a=g["UpperArmMm"]),
        rtb.RevoluteMDH(a=g["ForearmMm"]),
    ], tool=sm.SE3(g["WristLinkMm"], -g["ToolDropMm"], 0.0))


def puma560() -> Any:
    """The toolbox's Puma 560 (metres, radians)."""
    import roboticstoolbox as rtb

    return rtb.models.DH.Puma560()


@dataclass
class PumaCase:
    """One IK problem on the Puma 560, in the ST's units: a target pose reached at joints
    ``qt`` (rad) and a seed ``seed_offset`` rad away from them in every joint."""

    robot: Any
    chain: dict[str, Any]
    qt: NDArray[np.float64]
    target: list[list[float]]
    seed: list[float]


def puma_case(seed_offset: float) -> PumaCase:
    robot = puma560()
    qt = np.array([0.3, 0.5, -0.4, 0.6, 0.7, -0.2])
    return PumaCase(robot=robot, chain=chain_of(robot, MM_PER_M), qt=qt,
                    target=pose_st(robot.fkine(qt).A, MM_PER_M),
                    seed=joints_st(robot, qt + seed_offset, MM_PER_M))


def puma_folded_elbow_set(robot: Any, n: int, spread: float, seed: int
                          ) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """``n`` Puma 560 targets ``qt`` (rad) within 1e-4..5e-2 rad of the folded elbow, each with a
    seed ``q0`` within +/-``spread`` rad of it in every joint, from ``numpy``'s generator
    ``seed``.

    The elbow is singular where the wrist centre's distance from the shoulder is extremal,
    tan q3 = -d4 / a3 (closed form): stretched where cos q3 > 0, folded (the wrist centre
    nearest the shoulder) where cos q3 < 0. The folded elbow lies beyond the real arm's q3
    limits; the other joints are drawn within theirs.
    """
    a3, d4 = float(robot.links[2].a), float(robot.links[3].d)
    folded = math.atan2(d4, -a3)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        qt = rng.uniform(robot.qlim[0], robot.qlim[1])
        qt[2] = folded + 10.0 ** rng.uniform(-4.0, -1.3) * rng.choice([-1.0, 1.0])
        out.append((qt, qt + rng.uniform(-spread, spread, robot.n)))
    return out
