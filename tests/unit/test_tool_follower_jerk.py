"""ToolOrientationFollower (st/ToolOrientation.st) with a jerk limit (MaxJerkDps3 > 0): the
turning speed along the arc to the goal is jerk-limited.

Reference: Ruckig (PyPI `ruckig`), one axis, position interface, from rest at angle 0 to the
goal's angle at rest with the same limits (rate, acceleration, jerk): for a goal that holds
still the angle the follower has turned after each call is Ruckig's trajectory at that time
(the follower re-plans from its own state every call; the state is REAL, so within a small
multiple of float32's resolution). Also: the speed, acceleration and jerk along the arc from
the float32 outputs within the limits, the output comes to rest on the goal, the settings
are checked (a jerk without an acceleration limit, beyond 1e7, negative or NaN: 8), and
MaxJerkDps3 = 0 is the follower of before.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

ruckig = pytest.importorskip("ruckig")

IDENT = {"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}
AXIS = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


def quat(r: Rotation) -> dict[str, float]:
    x, y, z, w = r.as_quat()
    return {"W": float(w), "X": float(x), "Y": float(y), "Z": float(z)}


def rot(q: dict[str, float]) -> Rotation:
    return Rotation.from_quat([q["X"], q["Y"], q["Z"], q["W"]])


def f32(x: float) -> float:
    return float(np.float32(x))


def ruckig_angle(angle: float, rate: float, acc: float, jerk: float) -> Any:
    otg = ruckig.Ruckig(1)
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
    inp.target_position = [angle]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [rate], [acc], [jerk]
    traj = ruckig.Trajectory(1)
    assert str(otg.calculate(inp, traj)).endswith("Working")
    return traj


def follow(st_module: Any, angle: float, rate: float, acc: float, jerk: float,
           dt: float) -> tuple[list[float], Any]:
    """The angle turned after each call until the follower rests on the goal."""
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=rate, MaxAccDps2=acc, CycleTimeS=dt, MaxJerkDps3=jerk)
    goal = Rotation.from_rotvec(math.radians(angle) * AXIS)
    turned = [0.0]
    for _ in range(20000):
        fb(Reset=False, Target=quat(goal))
        assert not fb.Error
        turned.append(math.degrees(rot(fb.Orientation).magnitude()))
        if not fb.Tracking:
            break
    assert not fb.Tracking and (goal.inv() * rot(fb.Orientation)).magnitude() < 1e-6
    return turned, fb


@pytest.mark.parametrize(("angle", "rate", "acc", "jerk", "dt"), [
    (60.0, 90.0, 400.0, 3000.0, 0.01),
    (3.0, 90.0, 400.0, 3000.0, 0.01),       # short: no plateau of speed or acceleration
    (170.0, 720.0, 1000.0, 2.0e4, 0.005),
    (30.0, 90.0, 5000.0, 1.0e5, 0.02),      # huge jerk
    (20.0, 60.0, 200.0, 50.0, 0.01),        # tiny jerk: all ramps
])
def test_follower_turns_along_ruckigs_trajectory(st_module: Any, angle: float, rate: float,
                                                 acc: float, jerk: float, dt: float) -> None:
    turned, _ = follow(st_module, angle, rate, acc, jerk, dt)
    traj = ruckig_angle(angle, f32(rate), f32(acc), f32(jerk))
    dt32 = f32(dt)
    calls = len(turned) - 1
    # it lands in the call that reaches the plan's end (or up to two later: the REAL state's
    # rounding can leave a sliver of the plan for it; the all-ramps case lands two later,
    # 236 calls, on OpenPLC's own MatIEC build as in the bench)
    assert math.ceil(traj.duration / dt32 - 1e-9) <= calls <= math.ceil(traj.duration / dt32) + 2
    worst = 0.0
    for k, got in enumerate(turned[1:-1], start=1):
        p, _, _ = traj.at_time(k * dt32)
        worst = max(worst, abs(got - p[0]))
    # the state is re-planned from REALs every call: a few float32 ulps of the speed per call
    assert worst <= 2e-3, worst
    # along the arc, from the float32 outputs: speed, acceleration, jerk within the limits
    x = np.array(turned)
    v = np.diff(x) / dt
    noise = 4e-5 / dt  # an angle between float32 quaternions: ~1e-5 deg is noise
    assert np.max(np.abs(v)) <= rate + noise
    a = np.diff(v) / dt
    assert np.max(np.abs(a)) <= acc * 1.001 + 2 * noise / dt
    j = np.diff(a) / dt
    assert np.max(np.abs(j)) <= jerk * 1.01 + 4 * noise / dt ** 2


def test_follower_without_jerk_is_unchanged(st_module: Any) -> None:
    """MaxJerkDps3 = 0 (the default) is the acceleration-limited follower: the same outputs
    as a call that leaves the input out."""
    a, _ = follow(st_module, 40.0, 90.0, 400.0, 0.0, 0.01)
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=90.0, MaxAccDps2=400.0, CycleTimeS=0.01)
    goal = Rotation.from_rotvec(math.radians(40.0) * AXIS)
    b = [0.0]
    while True:
        fb(Reset=False, Target=quat(goal))
        b.append(math.degrees(rot(fb.Orientation).magnitude()))
        if not fb.Tracking:
            break
    assert a == b
    # and its turning acceleration jumps (no jerk limit): from rest (no turn in the two
    # calls before) straight to the acceleration limit
    acc = np.diff(np.array([0.0, 0.0, *a]), 2) / 0.01 ** 2
    assert np.max(np.abs(np.diff(acc))) > 300.0


@pytest.mark.parametrize(("acc", "jerk"), [(0.0, 1000.0), (400.0, -1.0), (400.0, math.nan),
                                           (400.0, 1.01e7), (400.0, math.inf)])
def test_follower_refuses_a_bad_jerk(st_module: Any, acc: float, jerk: float) -> None:
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=90.0, MaxAccDps2=0.0, CycleTimeS=0.01, MaxJerkDps3=0.0)
    before = dict(fb.Orientation)
    goal = Rotation.from_rotvec(math.radians(30.0) * AXIS)
    fb(Reset=False, Target=quat(goal), MaxAccDps2=acc, MaxJerkDps3=jerk)
    assert fb.Error and fb.ErrorId == 8 and dict(fb.Orientation) == before


def test_goal_jump_inside_the_braking_distance_lands_without_overshoot(st_module: Any) -> None:
    """Turning fast towards a far goal, the goal jumps to just ahead: the output lands on
    it (the speed drops at once, as the header says) and never passes it."""
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=90.0, MaxAccDps2=400.0, CycleTimeS=0.01,
       MaxJerkDps3=3000.0)
    far = Rotation.from_rotvec(math.radians(120.0) * AXIS)
    for _ in range(60):
        fb(Reset=False, Target=quat(far))
    now = math.degrees(rot(fb.Orientation).magnitude())
    near = Rotation.from_rotvec(math.radians(now + 1.0) * AXIS)
    angles = []
    for _ in range(50):
        fb(Reset=False, Target=quat(near))
        angles.append(math.degrees(rot(fb.Orientation).magnitude()))
    assert max(angles) <= now + 1.0 + 1e-4
    assert angles[-1] == pytest.approx(now + 1.0, abs=1e-4) and not fb.Tracking


def test_a_braking_state_never_turns_away_from_a_far_goal(st_module: Any) -> None:
    """A turning state the plans never make but REAL rounding could leave (0.2 deg/s while
    braking at 400 deg/s^2) with the goal far ahead: the plan from it would dip backwards;
    the follower instead holds for that call and starts again from rest, turning towards
    the goal in every call after it (never away, never stalled)."""
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=90.0, MaxAccDps2=400.0, CycleTimeS=0.01,
       MaxJerkDps3=3000.0)
    goal = Rotation.from_rotvec(math.radians(60.0) * AXIS)
    fb(Reset=False, Target=quat(goal))
    fb.SpeedDps = 0.2
    fb.AccDps2 = -400.0
    last = (goal.inv() * rot(fb.Orientation)).magnitude()
    for k in range(30):
        fb(Reset=False, Target=quat(goal))
        now = (goal.inv() * rot(fb.Orientation)).magnitude()
        assert now <= last if k == 0 else now < last, (k, math.degrees(last), math.degrees(now))
        last = now
