"""ToolOrientationFollow5Axis (st/ToolOrientation5Axis.st): a filtered orientation drives the
5-axis arm's tool, the tip (or flange point) held, through a dead band and a rate limit.

References, independent of the ST: the closed-form FK of the 5-axis arm as a float64 numpy
product of elementary transforms Rz(base) Tz(A1) Tx(A2) Ry(-shoulder) Tx(A3) Ry(180 - elbow)
Tx(A4) Ry(-wrist pitch) Rx(roll) Tx(tool) (the joint conventions of st/Kinematics5Axis.st's
header); rotations and the follower's path (the shortest arc from the start orientation to the
goal, walked at MaxRateDps) with scipy's Rotation; the projection onto the arm plane written
out here (tool direction minus its component along the plane's normal (-sin B, cos B, 0)); the
reach shell |A3 - A4| .. A3 + A4 around the shoulder; the rate, acceleration and joint limits
themselves. Tolerances: the block computes in float32 (REAL) on a ~300 mm arm.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from armbench.plant import arm
from five_axis_ref import fk5

G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0
GEO5 = {"Arm": G.as_st(), "ToolMm": TOOL_MM}
DT = 0.01  # s, one filter sample per 10 ms scan
HEADING = 25.0  # deg: the base X axis 25 deg counter-clockwise from magnetic north
Q0 = [15.0, 80.0, 100.0, -20.0, 10.0]  # deg: tool pitch -20, roll 10
IDENT = {"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}
NAN = float("nan")
POS_TOL_MM = 0.02  # float32 IK: the held point within this
DIR_TOL = 1e-4  # float32: unit vectors within this
SETTLED_DEG = 0.01  # the follower on its goal: float32 angle of a quaternion to itself
# error codes: ArmAngles.st, Quaternion.st, Kinematics5Axis.st
SINGULAR, NOT_FINITE, BAD_PARAMETER, JOINT_LIMIT = 2, 3, 8, 10
OUT_OF_PLANE, FLANGE_UNREACHABLE, BAD_QUAT = 35, 37, 45


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def fk(q: list[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(flange point, tool tip, tool frame 3x3), float64, joints in deg
    (tests/five_axis_ref.py)."""
    flange, tool = fk5(q, G, TOOL_MM)
    return flange[:3, 3], tool[:3, 3], tool[:3, :3]


def quat(r: Rotation) -> dict[str, float]:
    w, x, y, z = r.as_quat(scalar_first=True)
    return {"W": float(w), "X": float(x), "Y": float(y), "Z": float(z)}


def base_to_earth(frame: np.ndarray) -> Rotation:
    """A tool frame given in the base frame, as an orientation in the earth frame."""
    return Rotation.from_matrix(_rz(math.radians(HEADING)) @ frame)


def tool_frame(base: float, pitch: float, roll: float, yaw_off: float = 0.0) -> np.ndarray:
    """Rz(base) Rz(yaw_off) Ry(-pitch) Rx(roll), deg: the arm's tool frame (yaw_off 0) or one
    turned yaw_off out of the arm plane."""
    return (_rz(math.radians(base + yaw_off)) @ _ry(-math.radians(pitch))
            @ _rx(math.radians(roll)))


def projected(frame: np.ndarray, base: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The goal frame projected onto the arm plane at azimuth ``base``: (tool direction x,
    side axis y, off-plane angle deg), written out from the definition."""
    n = np.array([-math.sin(math.radians(base)), math.cos(math.radians(base)), 0.0])
    x = frame[:, 0]
    off = math.degrees(math.asin(min(1.0, abs(float(x @ n)))))
    xp = x - (x @ n) * n
    xp /= np.linalg.norm(xp)
    z0 = np.cross(xp, n)
    y = frame[:, 1]
    r = math.atan2(float(y @ z0), float(y @ n))
    return xp, math.cos(r) * n + math.sin(r) * z0, off


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(a.T @ b).magnitude()))


def started(st_module: Any, q: list[float] = Q0, flange: bool = False, **params: Any) -> Any:
    fb = st_module.new_fb("ToolOrientationFollow5Axis")
    settings: dict[str, Any] = {"Enable": True, "Joints": [*q, 0.0], "Geometry": GEO5,
                                "FlangeFixed": flange, "HeadingDeg": HEADING,
                                "MountOffset": IDENT, "DeadBandDeg": 2.0, "MaxRateDps": 90.0,
                                "SamplePeriodS": DT}
    fb.set(**{**settings, **params})
    fb(Start=True)
    assert (fb.Error, fb.ErrorId, fb.Active, fb.Valid) == (False, 0, True, True)
    fb(Start=False)
    return fb


def sample(fb: Any, orientation: dict[str, float]) -> list[float]:
    fb(NewSample=True, Orientation=orientation)
    return list(fb.SetJoints)


def held(q: list[float], flange: bool) -> np.ndarray:
    f, t, _ = fk(q)
    return f if flange else t


# --- start ------------------------------------------------------------------------------------

@pytest.mark.parametrize("flange", [False, True])
def test_start_takes_the_anchor_and_the_arms_tool_direction(st_module: Any,
                                                            flange: bool) -> None:
    fb = started(st_module, flange=flange)
    _, _, frame = fk(Q0)
    assert [fb.AnchorXMm, fb.AnchorYMm, fb.AnchorZMm] == pytest.approx(held(Q0, flange),
                                                                       abs=POS_TOL_MM)
    assert [fb.ToolDirection[k] for k in "XYZ"] == pytest.approx(frame[:, 0], abs=DIR_TOL)
    assert list(fb.SetJoints)[:5] == pytest.approx(Q0, abs=1e-4)
    assert (fb.PitchDeg, fb.RollDeg) == pytest.approx((-20.0, 10.0), abs=1e-3)
    # a goal equal to the arm's own orientation: nothing moves
    joints = sample(fb, quat(base_to_earth(frame)))
    assert joints[:5] == pytest.approx(Q0, abs=2e-3)
    assert fb.LagDeg == pytest.approx(0.0, abs=1e-2)


# --- following --------------------------------------------------------------------------------

@pytest.mark.parametrize(("flange", "yaw_off"), [(False, 0.0), (False, 12.0), (True, 12.0),
                                                 (True, -30.0)])
def test_settles_on_the_projected_goal_with_the_point_held(st_module: Any, flange: bool,
                                                           yaw_off: float) -> None:
    mount = Rotation.from_euler("ZYX", [20.0, -10.0, 5.0], degrees=True)
    goal = tool_frame(Q0[0], 5.0, -35.0, yaw_off)
    # the filter's orientation is sensor-to-earth: sensor (x) mount = the tool's goal
    sensor = base_to_earth(goal) * mount.inv()
    fb = started(st_module, flange=flange, MountOffset=quat(mount))
    anchor = held(Q0, flange)
    for k in range(300):
        joints = sample(fb, quat(sensor))
        assert not fb.Unreachable and not fb.Error
        assert np.linalg.norm(held(joints, flange) - anchor) < POS_TOL_MM
        if fb.LagDeg < SETTLED_DEG and k > 0:
            break
    else:
        pytest.fail("the follower never settled")
    xp, yp, off = projected(goal, Q0[0])
    _, _, frame = fk(joints)
    assert frame[:, 0] == pytest.approx(xp, abs=DIR_TOL)
    assert frame[:, 1] == pytest.approx(yp, abs=DIR_TOL)
    assert [fb.ToolDirection[k] for k in "XYZ"] == pytest.approx(xp, abs=DIR_TOL)
    assert fb.OffPlaneDeg == pytest.approx(off, abs=1e-3)
    assert fb.PitchDeg == pytest.approx(
        math.degrees(math.atan2(xp[2], math.hypot(xp[0], xp[1]))), abs=1e-3)
    assert fb.Steps == k + 1


def test_noise_below_the_dead_band_never_moves_the_joints(st_module: Any) -> None:
    goal = base_to_earth(tool_frame(Q0[0], 0.0, 30.0))
    fb = started(st_module)
    for _ in range(100):
        settled = sample(fb, quat(goal))
    assert fb.LagDeg < SETTLED_DEG
    rng = np.random.default_rng(11)
    for _ in range(400):
        axis = rng.normal(size=3)
        noise = Rotation.from_rotvec(axis / np.linalg.norm(axis)
                                     * math.radians(rng.uniform(0.0, 1.95)))
        assert sample(fb, quat(goal * noise)) == settled
        assert 0.0 < fb.LagDeg < 2.0


@pytest.mark.parametrize("acc", [0.0, 400.0])
def test_the_tool_never_turns_faster_than_the_rate(st_module: Any, acc: float) -> None:
    # a pitch-only goal: the shortest arc stays in the arm plane, so the arm's frame is the
    # follower's orientation and its steps are the follower's
    rate = 60.0
    fb = started(st_module, MaxRateDps=rate, MaxAccDps2=acc)
    goal_frame = tool_frame(Q0[0], 30.0, 10.0)
    anchor = held(Q0, False)
    frames = [fk(Q0)[2]]
    for _ in range(400):
        joints = sample(fb, quat(base_to_earth(goal_frame)))
        assert np.linalg.norm(held(joints, False) - anchor) < POS_TOL_MM
        frames.append(fk(joints)[2])
        if fb.LagDeg < SETTLED_DEG:
            break
    steps = np.array([angle_deg(a, b) for a, b in zip(frames[:-1], frames[1:], strict=True)])
    assert steps.max() <= rate * DT + 2e-3
    assert angle_deg(frames[-1], goal_frame) < 1e-2
    if acc == 0.0:
        assert steps[0] == pytest.approx(rate * DT, abs=2e-3)  # full rate at once
        assert len(steps) == math.ceil(50.0 / (rate * DT) - 1e-6)
    else:
        speed = steps / DT
        assert speed[0] <= acc * DT + 0.2
        # deg/s gained or lost per sample: at most acc * DT (plus float32 noise), the last
        # step excepted (it snaps onto the goal from the braking curve)
        assert np.abs(np.diff(speed[:-1])).max() <= acc * DT + 0.3
        assert speed.max() == pytest.approx(rate, abs=0.3)
        # the ramp costs time: at least rate / acc longer than at the plain rate
        assert len(steps) >= 50.0 / (rate * DT) + 0.9 * rate / acc / DT


# --- unreachable poses hold -------------------------------------------------------------------

def follower_path(start: Rotation, goal: Rotation, rate: float, samples: int) -> list[Rotation]:
    """The follower's orientations: the shortest arc from start to goal at rate deg/s."""
    rel = (start.inv() * goal).as_rotvec()
    total = float(np.degrees(np.linalg.norm(rel)))
    return [start * Rotation.from_rotvec(rel * min(1.0, (k + 1) * rate * DT / total))
            for k in range(samples)]


def test_a_direction_near_the_planes_normal_holds_the_last_pose(st_module: Any) -> None:
    start = base_to_earth(fk(Q0)[2])
    goal = base_to_earth(tool_frame(Q0[0], 0.0, 0.0, 89.0))  # 1 deg from the normal
    fb = started(st_module)
    n = np.array([-math.sin(math.radians(Q0[0])), math.cos(math.radians(Q0[0])), 0.0])
    last = list(fb.SetJoints)
    count = 0
    for ref in follower_path(start, goal, 90.0, 150):
        x_base = _rz(-math.radians(HEADING)) @ ref.as_matrix()[:, 0]
        off = math.degrees(math.asin(min(1.0, abs(float(x_base @ n)))))
        joints = sample(fb, quat(goal))
        assert fb.OffPlaneDeg == pytest.approx(off, abs=1e-2)
        if abs(off - 87.0) < 0.05:
            last = joints
            continue  # float32 at the 3 deg line: either verdict
        assert fb.Unreachable == (off > 87.0)
        if fb.Unreachable:
            count += 1
            assert fb.UnreachableId == OUT_OF_PLANE
            assert joints == last
        else:
            assert np.linalg.norm(held(joints, False) - held(Q0, False)) < POS_TOL_MM
        last = joints
    assert count >= 40 and fb.UnreachableCount >= count


def test_a_flange_outside_the_reach_holds_the_last_pose(st_module: Any) -> None:
    q = [0.0, 30.0, 175.0, 0.0, 0.0]  # nearly stretched: tool along the forearm
    start = base_to_earth(fk(q)[2])
    goal = base_to_earth(tool_frame(0.0, 5.0, 0.0))  # 20 deg down: the flange must go out
    fb = started(st_module, q=q)
    tip = held(q, False)
    shoulder = np.array([G.a2, 0.0, G.a1])
    last = list(fb.SetJoints)
    verdicts = []
    for ref in follower_path(start, goal, 90.0, 40):
        x_base = _rz(-math.radians(HEADING)) @ ref.as_matrix()[:, 0]
        reach = float(np.linalg.norm(tip - TOOL_MM * x_base - shoulder))
        joints = sample(fb, quat(goal))
        if abs(reach - (G.a3 + G.a4)) < 0.01:
            last = joints
            continue
        outside = reach > G.a3 + G.a4
        verdicts.append(outside)
        assert fb.Unreachable == outside
        if outside:
            assert fb.UnreachableId == FLANGE_UNREACHABLE
            assert joints == last
        else:
            assert np.linalg.norm(held(joints, False) - tip) < POS_TOL_MM
        last = joints
    assert any(verdicts) and not all(verdicts)


def test_joint_limits_and_the_callers_reject_hold_the_last_pose(st_module: Any) -> None:
    lower = [-170.0] * 6
    upper = [170.0] * 6
    upper[4 - 1] = Q0[3] + 8.0  # the wrist pitch may rise 8 deg
    fb = started(st_module, UseJointLimits=True, JointMinDeg=lower, JointMaxDeg=upper)
    goal = base_to_earth(tool_frame(Q0[0], 10.0, 10.0))
    seen_limit = False
    prev = list(fb.SetJoints)
    for _ in range(100):
        joints = sample(fb, quat(goal))
        assert joints[3] <= upper[3]
        if fb.Unreachable:
            assert fb.UnreachableId == JOINT_LIMIT
            assert joints == prev
            seen_limit = True
        prev = joints
    assert seen_limit
    # the caller's own check refuses a new pose: back to the one before
    fb2 = started(st_module)
    goal2 = base_to_earth(tool_frame(Q0[0], -10.0, 10.0))
    before = sample(fb2, quat(goal2))
    after = sample(fb2, quat(goal2))
    assert fb2.Solved and after != before
    fb2(NewSample=False, Reject=True, RejectCode=101)
    assert (fb2.Unreachable, fb2.UnreachableId, fb2.UnreachableCount) == (True, 101, 1)
    assert list(fb2.SetJoints) == before
    assert [fb2.ToolDirection[k] for k in "XYZ"] == pytest.approx(fk(before)[2][:, 0],
                                                                  abs=DIR_TOL)
    fb2(NewSample=False, Reject=True, RejectCode=101)  # only the last solve can be undone
    assert fb2.UnreachableCount == 1 and list(fb2.SetJoints) == before
    fb2(Reject=False)
    sample(fb2, quat(goal2))
    assert fb2.Solved and not fb2.Unreachable


# --- bad input --------------------------------------------------------------------------------

def outputs(fb: Any) -> list[float]:
    vals = [*fb.SetJoints, fb.PitchDeg, fb.RollDeg, fb.LagDeg, fb.OffPlaneDeg, fb.AnchorXMm,
            fb.AnchorYMm, fb.AnchorZMm, *(fb.ToolDirection[k] for k in "XYZ"), fb.Steps]
    assert all(math.isfinite(v) for v in vals)
    return vals


@pytest.mark.parametrize("bad", [{"W": NAN, "X": 0.0, "Y": 0.0, "Z": 0.0},
                                 {"W": 0.0, "X": 0.0, "Y": 0.0, "Z": 0.0},
                                 {"W": 1.0, "X": math.inf, "Y": 0.0, "Z": 0.0}])
def test_bad_quaternions_keep_the_last_output(st_module: Any, bad: dict[str, float]) -> None:
    fb = started(st_module)
    goal = quat(base_to_earth(tool_frame(Q0[0], 0.0, 0.0)))
    for _ in range(5):
        sample(fb, goal)
    kept = outputs(fb)
    sample(fb, bad)
    assert (fb.Error, fb.ErrorId) == (True, BAD_QUAT)
    assert outputs(fb) == kept
    fb.set(MountOffset=bad)
    sample(fb, goal)
    assert (fb.Error, fb.ErrorId) == (True, BAD_QUAT)
    assert outputs(fb) == kept
    fb.set(MountOffset=IDENT)
    sample(fb, goal)
    assert not fb.Error and fb.Steps == kept[-1] + 1


@pytest.mark.parametrize("param", [{"DeadBandDeg": NAN}, {"DeadBandDeg": 91.0},
                                   {"MaxRateDps": 0.0}, {"MaxRateDps": 4000.0},
                                   {"MaxAccDps2": -1.0}, {"SamplePeriodS": 0.0},
                                   {"SamplePeriodS": NAN}])
def test_bad_parameters_keep_the_last_output(st_module: Any, param: dict[str, float]) -> None:
    fb = started(st_module)
    goal = quat(base_to_earth(tool_frame(Q0[0], 0.0, 0.0)))
    sample(fb, goal)
    kept = outputs(fb)
    fb.set(**param)
    sample(fb, goal)
    assert (fb.Error, fb.ErrorId) == (True, BAD_PARAMETER)
    assert outputs(fb) == kept


def test_a_failed_start_leaves_the_follow_as_it_was(st_module: Any) -> None:
    fb = started(st_module, flange=True)
    goal = quat(base_to_earth(tool_frame(Q0[0], 0.0, 0.0)))
    sample(fb, goal)
    kept = outputs(fb)
    # the flange point on the base axis: A2 + A3 cos 90 + A4 cos f = 0
    fore = math.degrees(math.acos(-G.a2 / G.a4))
    on_axis = [0.0, 90.0, fore - 90.0 + 180.0, 0.0, 0.0]
    assert abs(fk(on_axis)[0][0]) < 1e-9
    for joints, code in [(on_axis, SINGULAR), ([NAN, *Q0[1:]], NOT_FINITE)]:
        fb(Start=True, Joints=[*joints, 0.0])
        assert (fb.Error, fb.ErrorId, fb.Active) == (True, code, True)
        assert outputs(fb) == kept
        fb(Start=False, NewSample=False)
    fb(Start=True, Joints=[*Q0, 0.0], HeadingDeg=NAN)
    assert (fb.Error, fb.ErrorId) == (True, BAD_PARAMETER)
    fb(Start=False, HeadingDeg=HEADING)
    sample(fb, goal)
    assert not fb.Error and fb.Steps == kept[-1] + 1


def test_samples_before_a_start_or_when_disabled_do_nothing(st_module: Any) -> None:
    fb = st_module.new_fb("ToolOrientationFollow5Axis")
    fb.set(Enable=True, Geometry=GEO5, MountOffset=IDENT, Joints=[*Q0, 0.0])
    sample(fb, quat(Rotation.identity()))
    assert (fb.Active, fb.Valid, fb.Solved, fb.Error, fb.Steps) == (False, False, False,
                                                                    False, 0)
    fb = started(st_module)
    fb(Enable=False)
    assert not fb.Active
    sample(fb, quat(base_to_earth(tool_frame(Q0[0], 0.0, 0.0))))
    assert fb.Steps == 0 and list(fb.SetJoints)[:5] == pytest.approx(Q0, abs=1e-4)


@pytest.mark.parametrize("acc", [-1.0, NAN, 2.0e6])
def test_the_followers_acceleration_limit_is_checked(st_module: Any, acc: float) -> None:
    fb = st_module.new_fb("ToolOrientationFollower")
    fb.set(Enable=True, MountOffset=IDENT, CycleTimeS=DT)
    fb(Reset=True, InitialQuat=IDENT, Target=IDENT)
    goal = quat(Rotation.from_euler("Z", 40.0, degrees=True))
    fb(Reset=False, Target=goal, MaxAccDps2=acc)
    assert (fb.Error, fb.ErrorId) == (True, BAD_PARAMETER)
    assert [fb.Orientation[k] for k in "WXYZ"] == [1.0, 0.0, 0.0, 0.0]
    fb(MaxAccDps2=0.0)  # off again: the plain rate limit, full speed at once
    assert not fb.Error
    o = fb.Orientation
    turned = math.degrees(2.0 * math.atan2(math.hypot(o["X"], o["Y"], o["Z"]), o["W"]))
    assert turned == pytest.approx(0.9, abs=1e-3)
