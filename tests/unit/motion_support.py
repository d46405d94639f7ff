"""Shared helpers of the motion block tests: a motion group passed between blocks scan by
scan, and a recorder of its setpoints.

The group lives in Python between scans (a dict copied into each block's VAR_IN_OUT and
read back), so several blocks can share it exactly as they share one MotionGroup variable
in a PLC program, in the order the test calls them.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np

DT = 0.01  # s, the controller's 10 ms task

# error codes: st/ArmAngles.st and st/MotionProfiles.st
UNREACHABLE, NOT_FINITE, BAD_GEOMETRY, BAD_PARAMETER, JOINT_LIMIT = 1, 3, 4, 8, 10
BAD_PROFILE, BAD_JOINT_COUNT, BAD_GROUP_LIMITS, BAD_GROUP_STATE = 20, 21, 22, 23
PATH_NOT_SMOOTH, TOO_MANY_STEPS = 24, 25


def make_group(position: list[float], joints: int = 3, lower: float = -170.0,
               upper: float = 170.0, max_vel: float = 120.0,
               max_acc: float = 400.0) -> dict[str, Any]:
    pos = list(position) + [0.0] * (6 - len(position))
    return {
        "Joints": joints,
        "Position": pos,
        "Velocity": [0.0] * 6,
        "Acceleration": [0.0] * 6,
        "Limits": {
            "LowerDeg": [lower] * 6,
            "UpperDeg": [upper] * 6,
            "MaxVelDeg": [max_vel] * 6,
            "MaxAccDeg": [max_acc] * 6,
        },
        "Owner": 0,
        "NextOwnerId": 0,
        "CartesianValid": False,
        "CartesianPos": [0.0, 0.0, 0.0],
        "PathParameter": 0.0,
    }


@dataclass
class GroupSim:
    """One MotionGroup shared by the blocks a test calls, with the setpoints of every scan."""

    group: dict[str, Any]
    positions: list[list[float]] = field(default_factory=list)
    velocities: list[list[float]] = field(default_factory=list)
    cartesian: list[list[float]] = field(default_factory=list)
    start: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.start:
            self.start = list(self.group["Position"][: self.group["Joints"]])

    def call(self, fb: Any, **inputs: Any) -> Any:
        fb(Group=self.group, **inputs)
        self.group = fb.Group
        return fb

    def record(self) -> None:
        n = self.group["Joints"]
        self.positions.append(list(self.group["Position"][:n]))
        self.velocities.append(list(self.group["Velocity"][:n]))
        self.cartesian.append(list(self.group["CartesianPos"]))

    def scan(self, fb: Any, **inputs: Any) -> Any:
        self.call(fb, **inputs)
        self.record()
        return fb

    def snapshot(self) -> dict[str, Any]:
        return copy.deepcopy(self.group)

    def assert_rejected(self, fb: Any, code: int, **inputs: Any) -> None:
        """One scan of ``fb`` with bad ``inputs``: Error with ``code``, not Busy, and the
        group exactly as before (bad input changes nothing)."""
        before = self.snapshot()
        self.scan(fb, **inputs)
        assert fb.Error and fb.ErrorId == code and not fb.Busy
        assert self.group == before

    def pos(self) -> np.ndarray:
        return np.array(self.positions)

    def vel(self) -> np.ndarray:
        return np.array(self.velocities)


def run_until_done(sim: GroupSim, fb: Any, max_scans: int = 20000, **inputs: Any) -> int:
    """Scans (Execute held TRUE) until the block is no longer Busy; returns the scan count."""
    for k in range(1, max_scans + 1):
        sim.scan(fb, **inputs)
        if not fb.Busy:
            return k
    raise AssertionError(f"block still busy after {max_scans} scans")
