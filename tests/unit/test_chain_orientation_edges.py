"""Edge cases of the chain and orientation blocks (st/KinematicsChain.st, st/Kinematics5Axis.st,
st/ToolOrientation.st, st/ToolOrientation5Axis.st), each checked against its header's promise.

References, independent of the ST: the Robotics Toolbox's Puma 560 (fkine, jacob0, ikine_LM in
float64), the closed-form FK of the 5-axis arm (tests/five_axis_ref.py, numpy), scipy's
Rotation for the follower's turning speed, and the closed-form position of the Puma's elbow
singularity (the wrist centre's distance from the shoulder is extremal where
tan q3 = -d4 / a3).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from chain_models import (
    MM_PER_M,
    chain_of,
    chain_pose,
    joints_rtb,
    joints_st,
    rotation_angle_deg,
)
from scipy.spatial.transform import Rotation

from armbench.plant import arm
from five_axis_ref import fk5

rtb = pytest.importorskip("roboticstoolbox")

G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0
GEO5 = {"Arm": G.as_st(), "ToolMm": TOOL_MM}
IDENT = {"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}
DT = 0.01
POS_TOL_MM = 0.02       # float32 IK on a ~300 mm arm
NAN, INF = float("nan"), float("inf")
# ErrorIds: st/ArmAngles.st, st/KinematicsChain.st, st/Kinematics5Axis.st, st/MotionJogWrist.st
NOT_FINITE, NOT_CONVERGED, SINGULAR = 3, 9, 32
PATH_NOT_SMOOTH, TOOL_VECTOR_ZERO = 24, 36


def quat(r: Rotation) -> dict[str, float]:
    w, x, y, z = r.as_quat(scalar_first=True)
    return {"W": float(w), "X": float(x), "Y": float(y), "Z": float(z)}


def rot(q: dict[str, float]) -> Rotation:
    return Rotation.from_quat([q["W"], q["X"], q["Y"], q["Z"]], scalar_first=True)


def tool_frame(base: float, pitch: float, roll: float) -> np.ndarray:
    """Rz(base) Ry(-pitch) Rx(roll), deg: the 5-axis arm's tool frame (Kinematics5Axis.st)."""
    return Rotation.from_euler("ZYX", [base, -pitch, roll], degrees=True).as_matrix()


def tip_of(q: list[float]) -> np.ndarray:
    return fk5(q, G, TOOL_MM)[1][:3, 3]


def flange_of(q: list[float]) -> np.ndarray:
    return fk5(q, G, TOOL_MM)[0][:3, 3]


def follow5(st_module: Any, q: list[float], flange: bool = False) -> Any:
    fb = st_module.new_fb("ToolOrientationFollow5Axis")
    fb.set(Enable=True, Joints=[*q, 0.0], Geometry=GEO5, FlangeFixed=flange, HeadingDeg=0.0,
           MountOffset=IDENT, DeadBandDeg=0.0, MaxRateDps=90.0, SamplePeriodS=DT)
    fb(Start=True)
    return fb


# --- 1. ToolOrientationFollow5Axis keeps the arm's IK branch --------------------------------

# the tool reaching back over the base axis: pitch 180, the tip 16 mm behind the axis, the
# flange 44 mm in front of it
BEHIND = [0.0, 100.0, 150.0, 110.0, 0.0]


def test_follow5_tip_behind_the_base_axis_keeps_the_base(st_module: Any) -> None:
    """Before: the Start was accepted and the first sample (lag 5e-6 deg) turned the base
    0 -> 180 deg and the wrist 110 -> -99 deg (the other branch of the same tip)."""
    assert tip_of(BEHIND)[0] < -10.0 and flange_of(BEHIND)[0] > 10.0
    fb = follow5(st_module, BEHIND)
    assert (fb.Error, fb.ErrorId, fb.Active) == (False, 0, True)
    fb(Start=False)
    anchor = tip_of(BEHIND)
    # the arm's own orientation first: nothing may move
    fb(NewSample=True, Orientation=quat(Rotation.from_matrix(tool_frame(0.0, 180.0, 0.0))))
    assert list(fb.SetJoints)[:5] == pytest.approx(BEHIND, abs=2e-3)
    # then a goal 25 deg lower (pitch 155): the flange stays in front of the axis
    goal = tool_frame(0.0, 155.0, 20.0)
    for _ in range(200):
        fb(NewSample=True, Orientation=quat(Rotation.from_matrix(goal)))
        joints = list(fb.SetJoints)[:5]
        assert not fb.Unreachable and fb.Solved
        assert joints[0] == pytest.approx(0.0, abs=1e-3)
        assert joints[2] <= 180.0   # elbow up, as at the Start
        assert np.linalg.norm(tip_of(joints) - anchor) < POS_TOL_MM
        if fb.LagDeg < 1e-2:
            break
    else:
        pytest.fail("never settled")
    frame = fk5(joints, G, TOOL_MM)[1][:3, :3]
    assert rotation_angle_deg(frame, goal) < 1e-2


def test_follow5_holds_the_pose_when_the_flange_would_cross_the_axis(st_module: Any) -> None:
    """Turning the tool up from BEHIND moves the flange (tip - 60 mm * direction) across the
    base axis at a pitch of about 106 deg: the IK's base would turn round. Before: the first
    sample already gave base 180."""
    fb = follow5(st_module, BEHIND)
    fb(Start=False)
    goal = quat(Rotation.from_matrix(tool_frame(0.0, 90.0, 0.0)))
    held: list[float] | None = None
    for _ in range(150):
        before = list(fb.SetJoints)
        fb(NewSample=True, Orientation=goal)
        joints = list(fb.SetJoints)[:5]
        assert joints[0] == pytest.approx(0.0, abs=1e-3)
        assert flange_of(joints)[0] >= -1e-3   # never a pose with the flange behind
        if fb.Unreachable:
            assert fb.UnreachableId == PATH_NOT_SMOOTH
            assert list(fb.SetJoints) == before
            held = joints
            break
    assert held is not None, "the flange never reached the axis"
    assert held[3] < 110.0  # it did follow before it held (the wrist turned up)


@pytest.mark.parametrize(("q", "flange"), [
    ([0.0, 150.0, 120.0, 0.0, 0.0], False),      # tip and flange both behind the axis
    ([0.0, 150.0, 120.0, 0.0, 0.0], True),       # flange-fixed, the flange behind the axis
    ([15.0, 80.0, 100.0, -20.0, 190.0], False),  # roll joint outside (-180, 180]
    ([15.0, 80.0, 100.0, 200.0, 10.0], False),   # wrist joint outside (-180, 180]
])
def test_follow5_refuses_a_start_off_the_iks_branch(st_module: Any, q: list[float],
                                                   flange: bool) -> None:
    """The samples' IK must give the present joints back (ErrorId 24, as MotionJogWrist);
    a refused Start leaves the block as it was. Before: every one was accepted, and its first
    sample jumped to other joints."""
    fb = follow5(st_module, q, flange)
    assert (fb.Error, fb.ErrorId, fb.Active, fb.Valid) == (True, PATH_NOT_SMOOTH, False, False)
    assert list(fb.SetJoints) == [0.0] * 6


def test_follow5_flange_fixed_in_front_with_the_tip_behind_is_followed(st_module: Any) -> None:
    """The held flange point lies in front of the axis: the angle mode holds this branch."""
    fb = follow5(st_module, BEHIND, flange=True)
    assert (fb.Error, fb.Active) == (False, True)
    fb(Start=False)
    fb(NewSample=True, Orientation=quat(Rotation.from_matrix(tool_frame(0.0, 170.0, 5.0))))
    joints = list(fb.SetJoints)[:5]
    assert fb.Solved and joints[0] == pytest.approx(0.0, abs=1e-3)
    assert np.linalg.norm(flange_of(joints) - flange_of(BEHIND)) < POS_TOL_MM


# --- 2. InverseKinematik_Chain near the Puma 560's singularities ----------------------------

def puma_singular_set(robot: Any, kind: str, n: int, spread: float,
                      seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Targets within 1e-4..5e-2 rad of a singularity, seeds within +/-spread rad of them.
    wrist: q5 = 0; elbow: the stretched elbow, tan q3 = -d4 / a3 with cos q3 > 0."""
    a3, d4 = float(robot.links[2].a), float(robot.links[3].d)
    elbow = math.atan2(-d4, a3)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        qt = rng.uniform(robot.qlim[0], robot.qlim[1])
        eps = 10.0 ** rng.uniform(-4.0, -1.3) * rng.choice([-1.0, 1.0])
        if kind == "wrist":
            qt[4] = eps
        else:
            qt[2] = elbow + eps
        out.append((qt, qt + rng.uniform(-spread, spread, 6)))
    return out


def test_chain_ik_converges_next_to_puma_singularities(st_module: Any) -> None:
    """Wherever ikine_LM (float64) converges on these near-singular targets, ours must too.
    Before: 180 of 200 (stalls with ErrorId 32 at 0.005 .. 0.03 mm)."""
    robot = rtb.models.DH.Puma560()
    a3, d4 = float(robot.links[2].a), float(robot.links[3].d)
    # the closed form's elbow singularity is the toolbox Jacobian's
    q = np.array([0.3, 0.5, math.atan2(-d4, a3), 0.6, 0.7, -0.2])
    assert np.linalg.svd(robot.jacob0(q), compute_uv=False)[-1] < 1e-9
    chain = chain_of(robot, MM_PER_M)
    ik = st_module.new_fb("InverseKinematik_Chain")
    rtb_ok = ours = 0
    misses: list[tuple[str, int, float]] = []
    for kind, spread, seed in (("wrist", 0.5, 3), ("wrist", 1.0, 4), ("elbow", 0.5, 5),
                               ("elbow", 1.0, 6)):
        for qt, q0 in puma_singular_set(robot, kind, 50, spread, seed):
            Tep = robot.fkine(qt)
            sol = robot.ikine_LM(Tep, q0=q0, ilimit=100, slimit=1, tol=5e-11,
                                 joint_limits=False)
            ik(Execute=False)
            ik(Execute=True, Chain=chain, Target=chain_pose(Tep.A, MM_PER_M),
               Seed=joints_st(robot, q0, MM_PER_M), PositionOnly=False, TolMm=0.005,
               TolDeg=5e-4, ItersPerScan=1000, MaxIters=1000)
            assert ik.Done != ik.Error and not ik.Busy
            if not sol.success:
                continue
            rtb_ok += 1
            if not ik.Done:
                misses.append((kind, ik.ErrorId, ik.ResidualMm))
                continue
            ours += 1
            T = robot.fkine(joints_rtb(robot, ik.Joints, MM_PER_M)).A
            assert np.linalg.norm(T[:3, 3] - Tep.A[:3, 3]) * MM_PER_M <= 0.01
            assert rotation_angle_deg(T[:3, :3], Tep.A[:3, :3]) <= 1e-3
    assert rtb_ok >= 180, f"only {rtb_ok} reference solutions"
    assert not misses, f"ours {ours}/{rtb_ok}; missed {misses[:5]}"


def test_chain_ik_iteration_cap_in_the_singular_band_is_9(st_module: Any) -> None:
    """The header: 9 when the iteration cap is reached, 32 only for a stall at a singularity.
    Before: 32 (the cap struck with SigmaMin inside the band)."""
    robot = rtb.models.DH.Puma560()
    seed = np.array([0.3, 0.5, -0.4, 0.6, 1e-3, -0.2])          # wrist singular
    assert np.linalg.svd(robot.jacob0(seed), compute_uv=False)[-1] < 1e-3
    Tep = robot.fkine(np.array([0.6, 0.2, -0.1, 0.9, 0.8, 0.1]))
    ik = st_module.new_fb("InverseKinematik_Chain")
    ik(Execute=True, Chain=chain_of(robot, MM_PER_M), Target=chain_pose(Tep.A, MM_PER_M),
       Seed=joints_st(robot, seed, MM_PER_M), PositionOnly=False, TolMm=0.005, TolDeg=5e-4,
       ItersPerScan=10, MaxIters=1)
    assert ik.Iterations == 1 and ik.SigmaMin < 0.05 and ik.ResidualMm > 1.0
    assert (ik.Error, ik.ErrorId) == (True, NOT_CONVERGED)


@pytest.mark.parametrize("bad", [NAN, INF, -INF, 2.0e30])
def test_chain_fk_with_a_bad_joint_is_the_identity(st_module: Any, bad: float) -> None:
    """Before: the identity frames plus the tool offset, translation (10, 20, 30) mm."""
    robot = rtb.models.DH.Puma560()
    chain = chain_of(robot, MM_PER_M, tool=(10.0, 20.0, 30.0))
    joints = joints_st(robot, np.array([0.3, 0.5, -0.4, 0.6, 0.7, -0.2]), MM_PER_M)
    good = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain, Joints=joints))
    assert not np.allclose(good, np.eye(4))
    joints[3] = bad
    T = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain, Joints=joints))
    assert np.array_equal(T, np.eye(4))


# --- 3. InverseKinematik5Axis: a tool direction of any length >= 1e-6 ------------------------

@pytest.mark.parametrize("length", [1.27e-6, 1.0e-5, 1.0, 3.0e29])
def test_five_axis_ik_takes_any_direction_length_from_1e_6(st_module: Any,
                                                           length: float) -> None:
    """Before: 1.27e-6 (largest component 9.0e-7) was refused with 36."""
    tip = np.array([180.0, 0.0, 150.0])
    unit = np.array([math.sqrt(0.5), 0.0, -math.sqrt(0.5)])   # pitch -45 deg
    ik = st_module.new_fb("InverseKinematik5Axis")
    d = unit * length
    ik(XMm=tip[0], YMm=tip[1], ZMm=tip[2], TipFixed=True, UseToolVector=True, PitchDeg=0.0,
       RollDeg=15.0, DirX=d[0], DirY=d[1], DirZ=d[2], ElbowUp=True, Geometry=GEO5)
    assert (ik.Error, ik.ErrorId, ik.Valid) == (False, 0, True)
    q = [ik.Angles[k] for k in ("Base", "Shoulder", "Elbow", "GripperUpDown", "GripperRotate")]
    flange_T, tool_T = fk5(q, G, TOOL_MM)
    assert np.linalg.norm(tool_T[:3, 3] - tip) < POS_TOL_MM
    assert np.abs(tool_T[:3, 0] - unit).max() < 1e-5
    assert rotation_angle_deg(tool_T[:3, :3], tool_frame(0.0, -45.0, 15.0)) < 1e-3
    assert flange_T[:3, 3] == pytest.approx(tip - TOOL_MM * unit, abs=POS_TOL_MM)


SHORT = 0.98e-6 / math.sqrt(2.0)   # length 0.98e-6


@pytest.mark.parametrize(("d", "code"), [((SHORT, 0.0, -SHORT), TOOL_VECTOR_ZERO),
                                         ((0.0, 0.0, 0.0), TOOL_VECTOR_ZERO),
                                         ((1e-30, 0.0, 1e-30), TOOL_VECTOR_ZERO),
                                         ((2e30, 0.0, 1.0), NOT_FINITE)])
def test_five_axis_ik_refuses_a_direction_below_1e_6(st_module: Any, d: tuple[float, ...],
                                                     code: int) -> None:
    ik = st_module.new_fb("InverseKinematik5Axis")
    ik(XMm=180.0, YMm=0.0, ZMm=150.0, TipFixed=True, UseToolVector=True, PitchDeg=0.0,
       RollDeg=0.0, DirX=d[0], DirY=d[1], DirZ=d[2], ElbowUp=True, Geometry=GEO5)
    assert (ik.Error, ik.ErrorId, ik.Valid) == (True, code, False)


# --- 4. ToolOrientationFollower: |change of turning speed| <= MaxAccDps2 * dt ----------------

@pytest.mark.parametrize(("acc", "rate", "dt", "angle"), [
    (200.0, 30.0, 0.01, 3.0), (400.0, 90.0, 0.01, 40.0), (1000.0, 720.0, 0.005, 179.0),
    (5000.0, 90.0, 0.05, 30.0), (200.0, 720.0, 0.01, 0.5),
])
def test_follower_speed_changes_by_at_most_acc_dt(st_module: Any, acc: float, rate: float,
                                                  dt: float, angle: float) -> None:
    """Speed per call from the angle between successive outputs (float64 from the float32
    quaternions). Before: the approach lost up to 1.125 * acc * dt in one call (the call
    before the snap onto the goal)."""
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=rate, MaxAccDps2=acc, CycleTimeS=dt)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    goal = Rotation.from_rotvec(math.radians(angle) * axis)
    prev, speeds = rot(fb.Orientation), [0.0]
    for _ in range(5000):
        fb(Reset=False, Target=quat(goal))
        cur = rot(fb.Orientation)
        speeds.append(math.degrees((prev.inv() * cur).magnitude()) / dt)
        prev = cur
        if not fb.Tracking:
            break
    speeds.append(0.0)   # at rest on the goal from here on
    assert (goal.inv() * prev).magnitude() < 1e-6
    # float32 quaternions: an angle of about 1e-5 deg per call is noise
    noise = 2e-5 / dt
    assert max(speeds) <= rate + noise
    assert np.abs(np.diff(speeds)).max() <= acc * dt * (1.0 + 1e-3) + noise
