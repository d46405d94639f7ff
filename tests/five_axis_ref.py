"""Reference forward kinematics of the 5-axis arm (st/Kinematics5Axis.st), shared by
tests/unit and tests/modbus.

A float64 numpy product of elementary transforms Rz(base) Tz(A1) Tx(A2) Ry(-shoulder) Tx(A3)
Ry(180 - elbow) Tx(A4) Ry(-wrist pitch) Rx(wrist roll) Tx(tool), written from the joint
conventions in st/Kinematics5Axis.st's header and independent of the ST and of armbench's
code: only numpy, so that tests/modbus can use it against a real PLC. It is itself checked
against a Robotics Toolbox DHRobot in tests/unit/test_five_axis.py. Joints in degrees
(base, shoulder, elbow, wrist pitch, wrist roll), lengths in mm; the columns of a tool frame's
rotation are the tool's x (approach), y, z axes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np


class ArmLengths(Protocol):
    """The arm's link lengths (mm); armbench.plant.arm.ArmGeometry is one."""

    @property
    def a1(self) -> float: ...  # shoulder axis height above the floor
    @property
    def a2(self) -> float: ...  # shoulder axis offset from the base axis
    @property
    def a3(self) -> float: ...  # upper arm
    @property
    def a4(self) -> float: ...  # forearm


def _rot(axis: str, a: np.ndarray) -> np.ndarray:
    """Batch of elementary homogeneous rotations (N, 4, 4), angles in radians."""
    c, s = np.cos(a), np.sin(a)
    m = np.zeros((len(a), 4, 4))
    m[:, 3, 3] = 1.0
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    k = 3 - i - j
    m[:, k, k] = 1.0
    m[:, i, i], m[:, i, j], m[:, j, i], m[:, j, j] = c, -s, s, c
    return m


def _trans(x: float, y: float, z: float, n: int) -> np.ndarray:
    m = np.tile(np.eye(4), (n, 1, 1))
    m[:, :3, 3] = (x, y, z)
    return m


def _joints_rad(q_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    q = np.radians(np.atleast_2d(np.asarray(q_deg, dtype=np.float64)))
    if q.shape[1] < 5:
        raise ValueError(f"5-axis joints need 5 angles per row, got shape {q.shape}")
    return q


def fk_flange_and_tool(q_deg: Sequence[float] | np.ndarray, geom: ArmLengths,
                       tool_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(flange poses, tool poses), each (N, 4, 4), for joint rows q_deg (N, >= 5), deg."""
    q = _joints_rad(q_deg)
    n = len(q)
    flange = (_rot("z", q[:, 0]) @ _trans(geom.a2, 0.0, geom.a1, n) @ _rot("y", -q[:, 1])
              @ _trans(geom.a3, 0.0, 0.0, n) @ _rot("y", -(q[:, 2] - math.pi))
              @ _trans(geom.a4, 0.0, 0.0, n))
    tool = flange @ _rot("y", -q[:, 3]) @ _rot("x", q[:, 4]) @ _trans(tool_mm, 0.0, 0.0, n)
    return flange, tool


def fk_elementary(q_deg: Sequence[float] | np.ndarray, geom: ArmLengths,
                  tool_mm: float) -> np.ndarray:
    """Tool poses (N, 4, 4) for joint rows q_deg (N, >= 5), deg."""
    return fk_flange_and_tool(q_deg, geom, tool_mm)[1]


def fk5(q_deg: Sequence[float] | np.ndarray, geom: ArmLengths,
        tool_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(flange frame, tool frame), 4x4 each, for one joint set (base, shoulder, elbow, wrist
    pitch, wrist roll), deg; extra trailing joints (e.g. a gripper) are ignored."""
    flange, tool = fk_flange_and_tool(np.asarray(q_deg, dtype=np.float64)[:5], geom, tool_mm)
    return flange[0], tool[0]


def tool_pitch(q_deg: Sequence[float] | np.ndarray) -> float:
    """Elevation of the tool's x axis above the floor plane (deg, -90..90), from the FK frame.

    The rotation alone decides it, so the link lengths do not enter."""
    q = _joints_rad(np.asarray(q_deg, dtype=np.float64)[:5])
    r = (_rot("z", q[:, 0]) @ _rot("y", -q[:, 1]) @ _rot("y", -(q[:, 2] - math.pi))
         @ _rot("y", -q[:, 3]) @ _rot("x", q[:, 4]))[0]
    x = r[:3, 0]
    return math.degrees(math.atan2(x[2], math.hypot(x[0], x[1])))


def pitch_from_joints(q_deg: Sequence[float] | np.ndarray) -> float:
    """The tool pitch (deg) as the sum of the three pitch joints: shoulder + elbow - 180 +
    wrist pitch (the rotations about y add up); equals tool_pitch modulo the wrap to -90..90
    of an elevation."""
    return float(q_deg[1]) + float(q_deg[2]) - 180.0 + float(q_deg[3])
