"""Property tests of the chain, 5-axis and orientation POUs at the edges of their documented
ranges: float32 extremes and just beyond (tiny and huge values, NaN, +/-Inf), near-singular
and boundary poses. POUs: ForwardKinematic_Chain, ChainJacobian, InverseKinematik_Chain
(st/KinematicsChain.st); InverseKinematik5Axis's tool direction (st/Kinematics5Axis.st);
QuatNormalise, QuatFromAxisAngle, QuatToMatrix, QuatAngleDeg, QuatSlerp (st/Quaternion.st);
VectorNorm3 (st/OrientationFilters.st); ToolOrientationFollower (st/ToolOrientation.st);
ToolOrientationFollow5Axis (st/ToolOrientation5Axis.st).

Properties (the headers' promises): never NaN out; the documented ErrorId on a refusal;
FK and Jacobian equal to the Robotics Toolbox's fkine / jacob0 (float64) for finite joints;
an IK answer whose Toolbox FK meets the target; unit quaternions equal to scipy's rotations;
the follower's speed changing by at most MaxAccDps2 * dt per call; the 5-axis follow never
leaving the IK branch it started on. The examples per test are bounded (the repo's profile,
derandomized) so that the file runs in well under a minute.
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

hypothesis = pytest.importorskip("hypothesis")
rtb = pytest.importorskip("roboticstoolbox")
from hypothesis import event, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

F32_MAX = float(np.finfo(np.float32).max)
EXTREMES = [0.0, -0.0, 1e-38, -1e-38, 1e-45, 1e-30, 1e-12, 1e-6, 1.0, 1e6, 1e30, 1.1e30,
            1e38, F32_MAX, -F32_MAX, math.inf, -math.inf, math.nan]
G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0
GEO5 = {"Arm": G.as_st(), "ToolMm": TOOL_MM}
IDENT = {"W": 1.0, "X": 0.0, "Y": 0.0, "Z": 0.0}
CHAIN_IK_CODES = {8, 9, 10, 30, 31, 32, 33, 34}
FOLLOW5_START_CODES = {1, 2, 3, 4, 8, 24, 35, 36, 37, 45}
FOLLOW5_UNREACHABLE = {1, 2, 10, 24, 35, 37}


def real(lo: float = -1e6, hi: float = 1e6) -> st.SearchStrategy[float]:
    """Any float32 in [lo, hi], or one of the extremes (beyond the range too)."""
    return st.one_of(st.floats(lo, hi, width=32), st.sampled_from(EXTREMES),
                     st.sampled_from(EXTREMES).map(lambda v: -v))


def finite(values: list[float]) -> bool:
    return all(math.isfinite(v) for v in values)


def quat(r: Rotation) -> dict[str, float]:
    w, x, y, z = r.as_quat(scalar_first=True)
    return {"W": float(w), "X": float(x), "Y": float(y), "Z": float(z)}


def rot(q: dict[str, float]) -> Rotation:
    return Rotation.from_quat([q["W"], q["X"], q["Y"], q["Z"]], scalar_first=True)


def qvals(q: dict[str, float]) -> list[float]:
    return [q["W"], q["X"], q["Y"], q["Z"]]


@pytest.fixture(scope="module")
def puma() -> Any:
    return rtb.models.DH.Puma560()


# --- KinematicsChain ----------------------------------------------------------------------

@examples(150)
@given(joints=st.one_of(st.lists(st.floats(-720.0, 720.0, width=32), min_size=6, max_size=6),
                       st.lists(real(-720.0, 720.0), min_size=6, max_size=6)),
       tool=st.tuples(*[st.floats(-200.0, 200.0, width=32)] * 3))
def test_chain_fk_and_jacobian(st_module: Any, puma: Any, joints: list[float],
                               tool: tuple[float, float, float]) -> None:
    chain = chain_of(puma, MM_PER_M, tool=tool)
    T = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain, Joints=joints))
    J = np.array(st_module.call("ChainJacobian", Chain=chain, Joints=joints))
    assert np.isfinite(T).all() and np.isfinite(J).all()
    if not all(math.isfinite(v) and abs(v) <= 1e30 for v in joints):
        assert np.array_equal(T, np.eye(4))
        return
    if not all(abs(v) <= 720.0 for v in joints):
        return  # beyond the range compared here: finite is the promise
    q = np.radians(np.array(joints, dtype=np.float32).astype(np.float64))
    import spatialmath as sm

    robot = rtb.DHRobot(puma.links, tool=sm.SE3(*(np.array(tool, np.float32) / MM_PER_M)))
    ref = robot.fkine(q).A
    assert np.abs(T[:3, :3] - ref[:3, :3]).max() < 2e-5
    assert np.abs(T[:3, 3] - ref[:3, 3] * MM_PER_M).max() < 2e-3
    ref_j = robot.jacob0(q)
    assert np.abs(J[:3] - ref_j[:3] * MM_PER_M).max() < 2e-3
    assert np.abs(J[3:] - ref_j[3:]).max() < 2e-5


NOT_CONVERGED, SINGULAR = 9, 32  # InverseKinematik_Chain's codes for a stalled solve
TOL_MM, TOL_DEG = 0.005, 5e-4


def check_round_trip(st_module: Any, puma: Any, qt: np.ndarray, q0: np.ndarray,
                     position_only: bool, misses_ok: bool) -> None:
    """Solve the Toolbox FK of `qt` from the seed `q0`: converged, the Toolbox FK of the
    answer meets the target; else 32 or 9, never NaN; a miss where the Toolbox's ikine_LM
    converges from the same seed fails unless `misses_ok`."""
    Tep = puma.fkine(qt).A
    ik = st_module.new_fb("InverseKinematik_Chain")
    ik(Execute=True, Chain=chain_of(puma, MM_PER_M), Target=chain_pose(Tep, MM_PER_M),
       Seed=joints_st(puma, q0, MM_PER_M), PositionOnly=position_only, TolMm=TOL_MM,
       TolDeg=TOL_DEG, ItersPerScan=400, MaxIters=400)
    assert not ik.Busy and ik.Done != ik.Error
    assert finite([*ik.Joints, ik.ResidualMm, ik.ResidualDeg, ik.SigmaMin, ik.Damping])
    if not ik.Done:
        assert ik.ErrorId in (NOT_CONVERGED, SINGULAR), (ik.ErrorId, ik.ResidualMm)
        ref = puma.ikine_LM(Tep, q0=q0, ilimit=400, slimit=1, tol=1e-20,
                            joint_limits=True, mask=[1, 1, 1, 0, 0, 0] if position_only else None)
        T = puma.fkine(ref.q).A
        ref_mm = float(np.linalg.norm(T[:3, 3] - Tep[:3, 3])) * MM_PER_M
        ref_deg = 0.0 if position_only else rotation_angle_deg(T[:3, :3], Tep[:3, :3])
        ref_reaches = ref_mm <= TOL_MM and ref_deg <= TOL_DEG
        # The header promises no more than this: it documents misses next to the singular
        # fold, a local minimum there that ikine_LM's path happened to avoid (32), or the
        # cap (9), and gives their measured rate (1 in 3598 for seeds within 0.5 rad).
        # The 10x soak found one where ikine_LM stalls too (0.013 mm, both singularities
        # 0.2 deg away) and, with seed 2, one where it converges (the xfail below).
        if misses_ok:  # inside the property test: tally them
            event(f"chain IK miss ({ik.ErrorId}), ikine_LM "
                  + ("converges" if ref_reaches else "misses too"))
            return
        assert not ref_reaches, (
            f"ikine_LM reaches {ref_mm:.2e} mm, {ref_deg:.2e} deg from this seed, the block "
            f"stops with {ik.ErrorId} at {ik.ResidualMm:.2e} mm, {ik.ResidualDeg:.2e} deg")
        return
    T = puma.fkine(joints_rtb(puma, ik.Joints, MM_PER_M)).A
    assert np.linalg.norm(T[:3, 3] - Tep[:3, 3]) * MM_PER_M <= 0.01
    if not position_only:
        assert rotation_angle_deg(T[:3, :3], Tep[:3, :3]) <= 1e-3


@examples(60)
@given(data=st.data())
def test_chain_ik_round_trip_near_singular(st_module: Any, puma: Any, data: Any) -> None:
    """Targets anywhere in the limits, often within 1e-6..1e-1 rad of the wrist (q5 = 0) or
    the stretched elbow (tan q3 = -d4 / a3) singularity; seeds within 0.4 rad."""
    lo, hi = puma.qlim
    qt = np.array([data.draw(st.floats(float(a), float(b))) for a, b in zip(lo, hi,
                                                                            strict=True)])
    kind = data.draw(st.sampled_from(["any", "wrist", "elbow", "both"]))
    eps = data.draw(st.floats(1e-6, 1e-1)) * data.draw(st.sampled_from([-1.0, 1.0]))
    a3, d4 = float(puma.links[2].a), float(puma.links[3].d)
    if kind in ("wrist", "both"):
        qt[4] = eps
    if kind in ("elbow", "both"):
        qt[2] = math.atan2(-d4, a3) + eps
    q0 = qt + np.array(data.draw(st.lists(st.floats(-0.4, 0.4), min_size=6, max_size=6)))
    check_round_trip(st_module, puma, qt, q0, data.draw(st.booleans()), misses_ok=True)


def test_chain_ik_stall_where_the_singularities_meet(st_module: Any, puma: Any) -> None:
    """The 10x soak's case: wrist and elbow both 1/256 rad from singular, the seed 0.25 rad
    off in joint 6 only. The block stops with 32 at 0.013 mm; so does ikine_LM."""
    a3, d4 = float(puma.links[2].a), float(puma.links[3].d)
    qt = np.zeros(6)
    qt[4] = 2.0**-8
    qt[2] = math.atan2(-d4, a3) + 2.0**-8
    check_round_trip(st_module, puma, qt, qt + np.array([0, 0, 0, 0, 0, 0.25]), False,
                     misses_ok=False)


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "a miss the IK header documents (32 next to the singular fold where ikine_LM's path "
    "avoids the local minimum); strict, so it shows when the IK learns to solve it"))
def test_chain_ik_documented_miss_that_ikine_lm_avoids(st_module: Any, puma: Any) -> None:
    """The soak's seed-2 case: wrist and elbow 0.0027 rad from singular, the seed 0.34 rad
    off in joint 4 only. ikine_LM converges from there; the block stops with 32 at 6.2e-3
    mm (tolerance 5e-3)."""
    a3, d4 = float(puma.links[2].a), float(puma.links[3].d)
    eps = -0.002681185663865647
    qt = np.zeros(6)
    qt[4] = eps
    qt[2] = math.atan2(-d4, a3) + eps
    check_round_trip(st_module, puma, qt, qt + np.array([0, 0, 0, 0.34375, 0, 0]), False,
                     misses_ok=False)


@examples(120)
@given(target=st.lists(real(-2000.0, 2000.0), min_size=3, max_size=3),
       seed=st.lists(real(-400.0, 400.0), min_size=6, max_size=6),
       lam=real(-0.5, 1.5), tol=real(-1.0, 1.0))
def test_chain_ik_bad_inputs_give_documented_codes(st_module: Any, puma: Any,
                                                   target: list[float], seed: list[float],
                                                   lam: float, tol: float) -> None:
    T = np.eye(4)
    T[:3, 3] = target
    ik = st_module.new_fb("InverseKinematik_Chain")
    ik(Execute=True, Chain=chain_of(puma, MM_PER_M), Target=chain_pose(T), Seed=seed,
       PositionOnly=True, Lambda=lam, TolMm=tol, ItersPerScan=50, MaxIters=50)
    assert finite([*ik.Joints, ik.ResidualMm, ik.ResidualDeg, ik.SigmaMin, ik.Damping])
    assert ik.Error or ik.Done or ik.Busy
    if ik.Error:
        assert ik.ErrorId in CHAIN_IK_CODES
    params_ok = 0.0 < lam <= 1.0 and 0.0 < tol <= 1e6 and all(abs(v) <= 1e6 for v in seed)
    if not params_ok:
        assert (ik.Error, ik.ErrorId) == (True, 8)
    elif not all(abs(v) <= 1e6 for v in target):
        assert (ik.Error, ik.ErrorId) == (True, 34)


# --- Kinematics5Axis: the tool direction's length -----------------------------------------

@examples(200)
@given(scale=st.one_of(st.floats(1e-30, 1e29), st.sampled_from(
           [1e-6 * (1 - 1e-4), 1e-6 * (1 + 1e-4), 1.27e-6, 1e-12, 1e-30, 1e29, 2e30])),
       pitch=st.floats(-170.0, 170.0))
def test_five_axis_direction_length(st_module: Any, scale: float, pitch: float) -> None:
    """Refused with 36 exactly when the direction is shorter than 1e-6 (float64 length, a
    1e-5 relative band around it left free), with 3 beyond 1e30; else the solved tool axis
    is the direction normalised (float64 FK)."""
    u = np.array([math.cos(math.radians(pitch)), 0.0, math.sin(math.radians(pitch))])
    d = (u * scale).astype(np.float32)
    ik = st_module.new_fb("InverseKinematik5Axis")
    ik(XMm=150.0, YMm=0.0, ZMm=160.0, TipFixed=False, UseToolVector=True, PitchDeg=0.0,
       RollDeg=0.0, DirX=float(d[0]), DirY=float(d[1]), DirZ=float(d[2]), ElbowUp=True,
       Geometry=GEO5)
    assert finite([ik.TipXMm, ik.TipYMm, ik.TipZMm, ik.ToolPitchDeg, *ik.Joints])
    length = float(np.linalg.norm(d.astype(np.float64)))
    if np.abs(d).max() > 1e30:
        assert ik.ErrorId == 3
    elif length < 1e-6 * (1 - 1e-5):
        assert (ik.Error, ik.ErrorId) == (True, 36)
    elif length > 1e-6 * (1 + 1e-5):
        assert ik.Valid, ik.ErrorId
        q = [ik.Angles[k] for k in ("Base", "Shoulder", "Elbow", "GripperUpDown",
                                    "GripperRotate")]
        axis = fk5(q, G, TOOL_MM)[1][:3, 0]
        assert np.abs(axis - d / length).max() < 2e-5


# --- Quaternion.st and VectorNorm3 --------------------------------------------------------

@examples(300)
@given(w=real(), x=real(), y=real(), z=real())
def test_quat_normalise_is_unit_or_fallback(st_module: Any, w: float, x: float, y: float,
                                            z: float) -> None:
    src = {"W": w, "X": x, "Y": y, "Z": z}
    fallback = quat(Rotation.from_euler("Z", 30.0, degrees=True))
    out = qvals(st_module.call("QuatNormalise", Quat=src, Fallback=fallback))
    assert finite(out)
    assert abs(math.fsum(v * v for v in out) - 1.0) < 1e-6
    vals = np.array([w, x, y, z], dtype=np.float64)
    if np.isfinite(vals).all() and np.linalg.norm(vals) >= 1e-12 * (1 + 1e-5) \
            and np.abs(vals).max() <= 1e30:
        assert np.abs(np.array(out) - vals / np.linalg.norm(vals)).max() < 1e-6


@examples(300)
@given(axis=st.tuples(real(), real(), real()), angle=real(-1e6, 1e6))
def test_quat_from_axis_angle_and_matrix(st_module: Any, axis: tuple[float, float, float],
                                         angle: float) -> None:
    q = st_module.call("QuatFromAxisAngle", AxisX=axis[0], AxisY=axis[1], AxisZ=axis[2],
                       AngleDeg=angle)
    vals = qvals(q)
    assert finite(vals) and abs(math.fsum(v * v for v in vals) - 1.0) < 1e-5
    M = np.array(st_module.call("QuatToMatrix", Quat=q))
    assert np.isfinite(M).all()
    assert np.abs(M @ M.T - np.eye(4 - 1)).max() < 1e-5
    a = np.array(axis, dtype=np.float64)
    if np.isfinite(a).all() and np.abs(a).max() <= 1e30 and 1e-11 < np.linalg.norm(a) \
            and abs(angle) <= 720.0:
        ref = Rotation.from_rotvec(math.radians(float(np.float32(angle)))
                                   * a / np.linalg.norm(a))
        assert np.abs(M - ref.as_matrix()).max() < 1e-5


@examples(200)
@given(a=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       b=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       t=real(-0.5, 1.5))
def test_quat_angle_and_slerp(st_module: Any, a: list[float], b: list[float],
                              t: float) -> None:
    ra, rb = Rotation.from_rotvec(np.array(a) * 3.0), Rotation.from_rotvec(np.array(b) * 3.0)
    qa, qb = quat(ra), quat(rb)
    angle = st_module.call("QuatAngleDeg", A=qa, B=qb)
    assert angle == pytest.approx(math.degrees((ra.inv() * rb).magnitude()), abs=2e-3)
    s = qvals(st_module.call("QuatSlerp", A=qa, B=qb, T=t))
    assert finite(s) and abs(math.fsum(v * v for v in s) - 1.0) < 1e-5
    frac = 0.0 if math.isnan(t) else min(1.0, max(0.0, t))   # header: clamped, NaN 0
    rel = (ra.inv() * rb).as_rotvec()
    want = ra * Rotation.from_rotvec(rel * frac)
    assert math.degrees((want.inv() * rot(dict(zip("WXYZ", s, strict=True)))).magnitude()) \
        < 5e-3


@examples(300)
@given(v=st.tuples(real(), real(), real()))
def test_vector_norm3_tiny_and_huge(st_module: Any, v: tuple[float, float, float]) -> None:
    n = st_module.call("VectorNorm3", V={"X": v[0], "Y": v[1], "Z": v[2]})
    ref = math.hypot(*(float(np.float32(c)) for c in v))
    if math.isnan(ref) or any(math.isnan(c) for c in v):
        return  # NaN in, NaN out (header)
    if math.isinf(ref) or ref > 1e30:
        return
    assert n >= 0.0 and n == pytest.approx(ref, rel=1e-6, abs=1e-44)


# --- ToolOrientation.st / ToolOrientation5Axis.st -----------------------------------------

@examples(60)
@given(rate=st.floats(5.0, 3600.0), dt=st.floats(0.002, 0.05), ramp=st.floats(0.5, 60.0),
       angle=st.floats(0.05, 179.9), axis=st.lists(st.floats(-1.0, 1.0), min_size=3,
                                                   max_size=3).filter(
           lambda a: np.linalg.norm(a) > 0.1))
def test_follower_acceleration_limit(st_module: Any, rate: float, dt: float, ramp: float,
                                     angle: float, axis: list[float]) -> None:
    """Static goal: |change of speed| <= MaxAccDps2 * dt in every call, speed <= MaxRateDps,
    lands on the goal; speeds from successive float32 outputs (noise ~2e-5 deg per call).
    MaxAccDps2 reaches the rate within ``ramp`` calls (at most 1e6 deg/s^2)."""
    acc = min(1e6, rate / (ramp * dt))   # the documented range ends at 1e6 deg/s^2
    calls = int(angle / (rate * dt) + 2.0 * ramp + 2.0 * math.sqrt(angle / (acc * dt * dt)))
    fb = st_module.new_fb("ToolOrientationFollower")
    fb(Enable=True, Reset=True, InitialQuat=IDENT, Target=IDENT, MountOffset=IDENT,
       DeadBandDeg=0.0, MaxRateDps=rate, MaxAccDps2=acc, CycleTimeS=dt)
    goal = Rotation.from_rotvec(math.radians(angle) * np.array(axis) / np.linalg.norm(axis))
    prev, speeds = rot(fb.Orientation), [0.0]
    for _ in range(calls + 10):
        fb(Reset=False, Target=quat(goal))
        o = fb.Orientation
        assert finite(qvals(o)) and not fb.Error
        cur = rot(o)
        speeds.append(math.degrees((prev.inv() * cur).magnitude()) / dt)
        prev = cur
        if not fb.Tracking:
            break
    else:
        pytest.fail(f"not on the goal after {calls + 10} calls")
    speeds.append(0.0)
    noise = 4e-5 / dt
    assert math.degrees((goal.inv() * prev).magnitude()) < 1e-4
    assert max(speeds) <= rate * (1 + 1e-5) + noise
    assert np.abs(np.diff(speeds)).max() <= acc * dt * (1.0 + 1e-3) + noise


@examples(60)
@given(q=st.tuples(st.floats(-170.0, 170.0), st.floats(0.0, 170.0), st.floats(20.0, 340.0),
                   st.floats(-179.0, 179.0), st.floats(-179.0, 179.0)),
       flange=st.booleans(),
       goal=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_follow5_never_leaves_its_branch(st_module: Any, q: tuple[float, ...], flange: bool,
                                         goal: list[float]) -> None:
    """Any start pose: refused with a documented code, or every solved sample keeps the base
    and the elbow's side of the Start and holds the point; unreachable ones hold the
    joints with a documented UnreachableId."""
    fb = st_module.new_fb("ToolOrientationFollow5Axis")
    joints = [float(np.float32(v)) for v in q]
    fb.set(Enable=True, Joints=[*joints, 0.0], Geometry=GEO5, FlangeFixed=flange,
           HeadingDeg=0.0, MountOffset=IDENT, DeadBandDeg=0.0, MaxRateDps=300.0,
           SamplePeriodS=0.01)
    fb(Start=True)
    if fb.Error:
        assert fb.ErrorId in FOLLOW5_START_CODES and not fb.Active
        return
    fb(Start=False)
    flange_T, tool_T = fk5(joints, G, TOOL_MM)
    anchor = (flange_T if flange else tool_T)[:3, 3]
    target = quat(Rotation.from_matrix(tool_T[:3, :3]) * Rotation.from_rotvec(
        np.array(goal) * 2.0))
    for _ in range(60):
        before = list(fb.SetJoints)
        fb(NewSample=True, Orientation=target)
        now = list(fb.SetJoints)
        assert finite(now)
        if fb.Unreachable and not fb.Solved:
            assert fb.UnreachableId in FOLLOW5_UNREACHABLE and now == before
            continue
        assert fb.Solved
        assert abs((now[0] - joints[0] + 180.0) % 360.0 - 180.0) < 1e-3
        assert (now[2] <= 180.0) == (joints[2] <= 180.0)
        f2, t2 = fk5(now[:5], G, TOOL_MM)
        assert np.linalg.norm((f2 if flange else t2)[:3, 3] - anchor) < 0.05


@examples(200)
@given(axis=st.tuples(real(), real(), real()), angle=real(-1e6, 1e6))
def test_quat_matrix_column_is_quat_to_matrix(st_module: Any,
                                              axis: tuple[float, float, float],
                                              angle: float) -> None:
    """QuatMatrixColumn (a column, for a block that keeps no 2-D array) is QuatToMatrix's
    column to the bit."""
    q = st_module.call("QuatFromAxisAngle", AxisX=axis[0], AxisY=axis[1], AxisZ=axis[2],
                       AngleDeg=angle)
    M = st_module.call("QuatToMatrix", Quat=q)
    for col in (1, 2, 3):
        got = st_module.call("QuatMatrixColumn", Quat=q, Column=col)
        assert got == [M[row][col - 1] for row in range(3)]
