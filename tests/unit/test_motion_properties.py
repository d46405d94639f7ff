"""Property test of MotionJointMove takeovers: whatever the targets, profiles, speeds and the
scan at which a second move takes over, the group never jumps.

Checked against the group's own limits (the contract): every scan's velocity change is at most
MaxAccDeg * dt, every speed at most MaxVelDeg (and the position changes accordingly), no NaN,
the old block reports CommandAborted and the new one ends exactly at its target.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from motion_support import DT, GroupSim, make_group

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

MAX_VEL, MAX_ACC = 90.0, 300.0
angle = st.floats(-150.0, 150.0, allow_nan=False).map(lambda x: float(np.float32(x)))
joints3 = st.lists(angle, min_size=3, max_size=3)


@examples(40)
@given(start=joints3, first=joints3, second=joints3, p1=st.integers(0, 3),
       p2=st.integers(0, 3), v1=st.floats(5.0, 200.0), v2=st.floats(5.0, 200.0),
       a1=st.floats(20.0, 1000.0), a2=st.floats(20.0, 1000.0), k=st.integers(1, 80))
@example(start=[0.0, 0.0, 0.0], first=[0.0, 0.0, 0.0], second=[0.0, 0.0, 145.0], p1=0, p2=3,
         v1=5.0, v2=5.0, a1=20.0, a2=20.0, k=1)
def test_takeover_never_jumps(st_module: Any, start: list[float], first: list[float],
                              second: list[float], p1: int, p2: int, v1: float, v2: float,
                              a1: float, a2: float, k: int) -> None:
    sim = GroupSim(make_group(start, max_vel=MAX_VEL, max_acc=MAX_ACC))
    a = st_module.new_fb("MotionJointMove")
    b = st_module.new_fb("MotionJointMove")
    first_in = {"Execute": True, "Target": first + [0.0] * 3, "Profile": p1, "Velocity": v1,
                "Acceleration": a1, "Jerk": 5 * a1, "CycleTime": DT}
    second_in = {"Execute": True, "Target": second + [0.0] * 3, "Profile": p2,
                 "Velocity": v2, "Acceleration": a2, "Jerk": 5 * a2, "CycleTime": DT}
    for _ in range(k):
        sim.scan(a, **first_in)
    was_busy = a.Busy
    # the longest move drawn: a quintic's peak speed is 1.875 D / T, so 300 deg at 5 deg/s
    # takes 112.5 s = 11,250 scans, plus up to 4.5 s braking the first move (90 deg/s at
    # 20 deg/s^2); the soak's case below, 145 deg, needs 5,438
    for n in range(1, 16001):
        sim.scan(b, **second_in)
        if n == 1:
            sim.call(a, **first_in)
            assert a.CommandAborted == was_busy
        if not b.Busy:
            break
    assert b.Done and not b.Error
    pos = np.vstack([np.array(sim.start), sim.pos()])
    vel = np.vstack([np.zeros(3), sim.vel()])
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))
    assert np.max(np.abs(vel)) <= MAX_VEL * (1 + 1e-4)
    assert np.max(np.abs(np.diff(pos, axis=0))) <= MAX_VEL * DT * (1 + 1e-3) + 1e-4
    assert np.max(np.abs(np.diff(vel, axis=0))) <= MAX_ACC * DT * (1 + 1e-3) + 1e-3
    assert sim.positions[-1] == pytest.approx(second, abs=1e-4)
