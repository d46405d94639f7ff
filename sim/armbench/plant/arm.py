"""Reference kinematics of the 3-DOF arm of document 002, in numpy (float64).

Written from the document's homogeneous-transform table, not from the ST library, so the
tests can use it as an independent oracle; the plant simulation uses it for the arm pose.

Frames and conventions (the same contract as ``st/ArmAngles.st``):

* world frame 0: origin on the floor at the base axis, Z up, X forward (Base = 0), Y left;
* ``H30 = H10 @ H21 @ H32`` with the standard Denavit-Hartenberg rows

  ======  ==============  =====  =====  ========
  link    theta           d      a      alpha
  ======  ==============  =====  =====  ========
  1       Base            a1     a2     +90 deg
  2       Shoulder        0      a3     0
  3       Elbow - 180     0      a4     0
  ======  ==============  =====  =====  ========

  which gives document 002's ``R10 = [[c1,0,s1],[s1,0,-c1],[0,1,0]]``, ``d10 = [a2 c1, a2 s1,
  a1]``, ``R21 = Rz(t2)``, ``d21 = [a3 c2, a3 s2, 0]``, ``R32 = Rz(t3')``, ``d32 = [a4 c3',
  a4 s3', 0]``;
* Elbow is 180 deg for a straight arm; elbow-up solutions have Elbow in [0, 180] (the
  interior angle), elbow-down ones in [180, 360];
* tool joints: gripper pitch in the world = Shoulder + Elbow - 180 + GripperUpDown; roll
  commands = joint + Base - 90 (document 002: joint = 90 - Base + command).

Angles are degrees and lengths millimetres at every public function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ArmGeometry:
    """Link geometry of document 002, mm (defaults: the library's documented test arm)."""

    a1: float = 100.0  # shoulder axis height above the floor
    a2: float = 20.0  # shoulder axis offset from the base axis
    a3: float = 120.0  # upper arm
    a4: float = 130.0  # forearm

    def as_st(self) -> dict[str, float]:
        """The geometry as the ST struct ``ArmGeometry`` (field names A1..A4)."""
        return {"A1": self.a1, "A2": self.a2, "A3": self.a3, "A4": self.a4}


DEFAULT_GEOMETRY = ArmGeometry()


def dh_matrix(theta: float, d: float, a: float, alpha: float) -> FloatArray:
    """Standard Denavit-Hartenberg transform (angles in radians, lengths in mm)."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -ca * st, sa * st, a * ct],
            [st, ca * ct, -sa * ct, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_table(geometry: ArmGeometry = DEFAULT_GEOMETRY) -> list[tuple[float, float, float, float]]:
    """Rows (theta offset rad, d, a, alpha rad); joint variable theta = q + offset."""
    return [
        (0.0, geometry.a1, geometry.a2, math.pi / 2.0),
        (0.0, 0.0, geometry.a3, 0.0),
        (-math.pi, 0.0, geometry.a4, 0.0),
    ]


def link_transforms(
    base_deg: float, shoulder_deg: float, elbow_deg: float, geometry: ArmGeometry = DEFAULT_GEOMETRY
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """H10, H21, H32 for the given joint angles (degrees)."""
    q = (math.radians(base_deg), math.radians(shoulder_deg), math.radians(elbow_deg))
    mats = [
        dh_matrix(qi + offset, d, a, alpha)
        for qi, (offset, d, a, alpha) in zip(q, dh_table(geometry), strict=True)
    ]
    return mats[0], mats[1], mats[2]


def forward(
    base_deg: float, shoulder_deg: float, elbow_deg: float, geometry: ArmGeometry = DEFAULT_GEOMETRY
) -> FloatArray:
    """Tool point (x, y, z) in mm: the last column of H10 @ H21 @ H32."""
    h10, h21, h32 = link_transforms(base_deg, shoulder_deg, elbow_deg, geometry)
    h30 = h10 @ h21 @ h32
    return np.asarray(h30[:3, 3], dtype=np.float64)


def forward_batch(angles_deg: FloatArray, geometry: ArmGeometry = DEFAULT_GEOMETRY) -> FloatArray:
    """Vectorised tool points for an (N, 3) array of (Base, Shoulder, Elbow) in degrees."""
    q = np.radians(np.asarray(angles_deg, dtype=np.float64))
    t1, t2 = q[:, 0], q[:, 1]
    t3 = q[:, 2] - math.pi
    reach = geometry.a2 + geometry.a3 * np.cos(t2) + geometry.a4 * np.cos(t2 + t3)
    height = geometry.a1 + geometry.a3 * np.sin(t2) + geometry.a4 * np.sin(t2 + t3)
    return np.stack([reach * np.cos(t1), reach * np.sin(t1), height], axis=1)


def joint_points(
    base_deg: float, shoulder_deg: float, elbow_deg: float, geometry: ArmGeometry = DEFAULT_GEOMETRY
) -> FloatArray:
    """Points base foot, shoulder, elbow, tool as a (4, 3) array (for plots and the plant)."""
    h10, h21, h32 = link_transforms(base_deg, shoulder_deg, elbow_deg, geometry)
    h20 = h10 @ h21
    h30 = h20 @ h32
    return np.array([[0.0, 0.0, 0.0], h10[:3, 3], h20[:3, 3], h30[:3, 3]])


def wrap180(angle_deg: float) -> float:
    """Angle folded into (-180, 180] degrees."""
    folded = math.fmod(angle_deg, 360.0)
    if folded > 180.0:
        folded -= 360.0
    elif folded <= -180.0:
        folded += 360.0
    return folded


def reach_limits(geometry: ArmGeometry = DEFAULT_GEOMETRY) -> tuple[float, float]:
    """Smallest and largest distance (mm) from the shoulder axis the tool point can reach."""
    return abs(geometry.a3 - geometry.a4), geometry.a3 + geometry.a4


def shoulder_distance(
    x: float, y: float, z: float, geometry: ArmGeometry = DEFAULT_GEOMETRY
) -> float:
    """Distance Cp (mm) of the target from the shoulder axis in the arm's plane."""
    return math.hypot(math.hypot(x, y) - geometry.a2, z - geometry.a1)


def is_reachable(
    x: float, y: float, z: float, geometry: ArmGeometry = DEFAULT_GEOMETRY, margin: float = 0.0
) -> bool:
    """True when the target lies inside the reach shell shrunk by ``margin`` mm."""
    cp = shoulder_distance(x, y, z, geometry)
    low, high = reach_limits(geometry)
    return low + margin <= cp <= high - margin


def inverse(
    x: float,
    y: float,
    z: float,
    geometry: ArmGeometry = DEFAULT_GEOMETRY,
    elbow_up: bool = True,
) -> tuple[float, float, float]:
    """(Base, Shoulder, Elbow) in degrees by document 002's geometric method (two acos).

    Base = atan2(y, x), or that + 180 deg (reaching over the base axis) when only that side
    reaches the target; Base in (-180, 180], Shoulder folded into (-180, 180], Elbow the
    interior angle (elbow up) or 360 minus it (elbow down). Raises ValueError off the reach
    shell or on the base axis.
    """
    radial = math.hypot(x, y)
    if radial < 1e-9:
        raise ValueError("target on the base axis: Base is undefined")
    base = math.degrees(math.atan2(y, x))
    xp = radial - geometry.a2
    zp = z - geometry.a1
    cp = math.hypot(xp, zp)
    low, high = reach_limits(geometry)
    if not low <= cp <= high:
        # Front side out of reach: turn the base by 180 deg and reach over the axis.
        xp = -radial - geometry.a2
        cp = math.hypot(xp, zp)
        base = wrap180(base + 180.0)
    if not (low <= cp <= high) or cp < 1e-12:
        raise ValueError(f"target unreachable: Cp = {cp} mm outside [{low}, {high}]")
    a3, a4 = geometry.a3, geometry.a4
    cos_alpha = (a3 * a3 + cp * cp - a4 * a4) / (2.0 * a3 * cp)
    cos_beta = (a3 * a3 + a4 * a4 - cp * cp) / (2.0 * a3 * a4)
    alpha = math.acos(max(-1.0, min(1.0, cos_alpha)))
    beta = math.degrees(math.acos(max(-1.0, min(1.0, cos_beta))))
    phi = math.atan2(zp, xp)
    if elbow_up:
        shoulder, elbow = phi + alpha, beta
    else:
        shoulder, elbow = phi - alpha, 360.0 - beta
    return base, wrap180(math.degrees(shoulder)), elbow


def tool_joints(
    base_deg: float,
    shoulder_deg: float,
    elbow_deg: float,
    gripper_pitch_deg: float,
    elbow_roll_deg: float,
    gripper_roll_deg: float,
) -> tuple[float, float, float]:
    """Joint values (GripperUpDown, ElbowRotate, GripperRotate) for world-referenced commands."""
    return (
        wrap180(180.0 - (elbow_deg + shoulder_deg) + gripper_pitch_deg),
        wrap180(90.0 - base_deg + elbow_roll_deg),
        wrap180(90.0 - base_deg + gripper_roll_deg),
    )


def tool_commands(
    base_deg: float,
    shoulder_deg: float,
    elbow_deg: float,
    gripper_updown_deg: float,
    elbow_rotate_deg: float,
    gripper_rotate_deg: float,
) -> tuple[float, float, float]:
    """World-referenced (pitch, elbow roll, gripper roll) for joint values: tool_joints' inverse."""
    return (
        wrap180(gripper_updown_deg + shoulder_deg + elbow_deg - 180.0),
        wrap180(elbow_rotate_deg + base_deg - 90.0),
        wrap180(gripper_rotate_deg + base_deg - 90.0),
    )
