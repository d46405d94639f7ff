"""Property tests of the chain, fixed-point chain, 4-axis and 5-axis POUs that had none:
ChainCheck, ChainReach, ChainScale, ChainLinkTransform, ChainFramePoses, ChainToolPose,
ChainJacobianFromFrames, ChainJacobianPosition, ChainCholesky, ChainCholeskySolve,
ChainDampedStep, ChainPoseError, ChainResolvedRate, ChainEvaluate (st/KinematicsChain.st);
ChainShiftLint, ChainBitLength, SinCosTurnFixed, ChainGeometryFixedCheck, ChainForwardFixed
(st/KinematicsChainFixed.st); Arm4AxisEquivalent, Arm4AxisFillChain, ForwardKinematic_4Axis,
InverseKinematik4AxisCheck, InverseKinematik_4Axis, Arm4AxisKinematics
(st/Kinematics4Axis.st); FiveAxisGeometryCheck (st/Kinematics5Axis.st).

Inputs over the documented ranges, the float32 / integer extremes and just beyond, NaN/Inf,
near-singular poses. References: the Robotics Toolbox (the Puma 560 and document 001's
modified-DH 4-axis arm: link transforms, fkine, jacob0), numpy (Cholesky, solve, the damped
least-squares normal equations), scipy rotations (rotation vectors), Python's exact integers
(shifts, bit lengths) and the closed forms the file headers state.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from chain_models import FOUR_AXIS_GEO, MM_PER_M, chain_of, four_axis_rtb
from scipy.spatial.transform import Rotation

hypothesis = pytest.importorskip("hypothesis")
rtb = pytest.importorskip("roboticstoolbox")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

F32_MAX = float(np.finfo(np.float32).max)
REAL_1E30 = float(np.float32(1.0e30))
NEXT_1E6 = float(np.nextafter(np.float32(1.0e6), np.float32(2.0e6)))
EXTREMES = [0.0, -0.0, 1e-45, 1e-30, 1e-6, 1.0, 1e6, NEXT_1E6, 1e30, 1.1e30, F32_MAX,
            math.inf, -math.inf, math.nan]
BAD_TABLE, EMPTY, BAD_GEOMETRY = 30, 31, 4
Q18, Q24 = 2**18, 2**24


def f32(x: float) -> float:
    return float(np.float32(x))


def real(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.one_of(st.floats(lo, hi, width=32), st.sampled_from(EXTREMES),
                     st.sampled_from(EXTREMES).map(lambda v: -v))


@pytest.fixture(scope="module")
def puma() -> Any:
    return rtb.models.DH.Puma560()


@pytest.fixture(scope="module")
def arm4() -> Any:
    return four_axis_rtb()


# --- Tables ---------------------------------------------------------------------------------

@st.composite
def tables(draw: Any) -> dict[str, Any]:
    links = []
    for _ in range(6):
        prism = draw(st.booleans()) and draw(st.booleans())
        lo = draw(st.floats(-500.0, 0.0, width=32))
        links.append({"A": draw(real(-1e3, 1e3)), "AlphaDeg": draw(st.sampled_from(
            [0.0, 90.0, -90.0, 30.0])), "D": draw(real(-1e3, 1e3)), "ThetaOffsetDeg": 0.0,
            "Prismatic": prism, "LowerLimit": lo,
            "UpperLimit": draw(st.sampled_from([0.0, 100.0, lo - 1.0, 500.0]))})
    return {"Links": links, "Count": draw(st.sampled_from([1, 3, 6, 0, 7])),
            "Modified": draw(st.booleans()), "ToolX": draw(real(-100.0, 100.0)), "ToolY": 0.0,
            "ToolZ": draw(st.sampled_from([0.0, 10.0, math.nan]))}


def table_code(c: dict[str, Any]) -> int:
    n = c["Count"]
    if n < 1:
        return EMPTY
    if n > 6:
        return BAD_TABLE
    vals = [f32(c[k]) for k in ("ToolX", "ToolY", "ToolZ")]
    for link in c["Links"][:n]:
        vals += [f32(link[k]) for k in ("A", "AlphaDeg", "D", "ThetaOffsetDeg", "LowerLimit",
                                        "UpperLimit")]
        if link["LowerLimit"] > link["UpperLimit"]:
            return BAD_TABLE
    if not all(math.isfinite(v) and abs(v) <= 1e6 for v in vals):
        return BAD_TABLE
    moves = any(link["A"] or link["D"] or link["Prismatic"] for link in c["Links"][:n])
    if not moves and not any(c[k] for k in ("ToolX", "ToolY", "ToolZ")):
        return EMPTY
    return 0


ZERO_LINK = {"A": 0.0, "AlphaDeg": 0.0, "D": 0.0, "ThetaOffsetDeg": 0.0, "Prismatic": False,
             "LowerLimit": 0.0, "UpperLimit": 0.0}


@examples(120)
@given(c=tables())
# found by the 10x soak: one unlimited prismatic joint and nothing else, reach -1
@example(c={"Links": [{**ZERO_LINK, "Prismatic": True}] + [ZERO_LINK] * 5, "Count": 1,
            "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0})
@example(c={"Links": [{**ZERO_LINK, "Prismatic": True, "UpperLimit": 100.0}, ZERO_LINK,
                      {**ZERO_LINK, "Prismatic": True}] + [ZERO_LINK] * 3, "Count": 3,
            "Modified": False, "ToolX": 0.0, "ToolY": 0.0, "ToolZ": 0.0})
def test_chain_check_reach_scale(st_module: Any, c: dict[str, Any]) -> None:
    code = st_module.call("ChainCheck", Chain=c)
    want = table_code(c)
    # the order of BadTable's causes is the ST's; which code, and 0 or not, is the promise
    assert (code == 0) == (want == 0) and code in (0, BAD_TABLE, EMPTY)
    if want in (0, EMPTY) and code:
        assert code == want
    if code:
        return
    n = c["Count"]
    links = c["Links"][:n]
    travel = sum(max(abs(f32(lk["LowerLimit"])), abs(f32(lk["UpperLimit"]))) for lk in links
                 if lk["Prismatic"])
    tool = math.sqrt(sum(f32(c[k]) ** 2 for k in ("ToolX", "ToolY", "ToolZ")))
    base = sum(math.hypot(f32(lk["A"]), f32(lk["D"])) for lk in links)
    reach = st_module.call("ChainReach", Chain=c)
    # equal limits (only 0 and 0 in these tables) leave a prismatic joint unlimited
    unlimited = any(lk["Prismatic"] and lk["LowerLimit"] == lk["UpperLimit"] == 0.0
                    for lk in links)
    if unlimited:
        assert reach == -1.0  # the header's "no bound"
    else:
        assert abs(reach - (base + travel + tool)) <= 1e-5 * (base + travel + tool) + 1e-6
    scale = st_module.call("ChainScale", Chain=c)
    # the scale leaves out the travel of an unlimited joint only, a limited one's stays (the
    # soak's seed 2 found 0..100 next to 0..0: 100, not 1); an unlimited joint's 0..0 adds 0
    ref = max(1.0, base + travel + tool)
    assert abs(scale - ref) <= 1e-5 * ref


# --- Frames, tool pose, Jacobians ------------------------------------------------------------

@examples(120)
@given(q=st.lists(st.floats(-720.0, 720.0, width=32), min_size=6, max_size=6),
       tool=st.tuples(*[st.floats(-200.0, 200.0, width=32)] * 3), modified=st.booleans(),
       bad=st.sampled_from([None, math.nan, math.inf, 1.1e30]))
def test_frames_tool_pose_and_jacobians(st_module: Any, puma: Any, arm4: Any, q: list[float],
                                        tool: tuple[float, float, float], modified: bool,
                                        bad: float | None) -> None:
    import spatialmath as sm

    robot = arm4 if modified else puma
    scale = 1.0 if modified else MM_PER_M
    chain = chain_of(robot, scale, tool=tool)
    joints = list(q[: robot.n]) + [0.0] * (6 - robot.n)
    if bad is not None:
        joints[1] = bad
    frames = st_module.call("ChainFramePoses", Chain=chain, Joints=joints)
    stack = np.array([f["Pose"] for f in frames])
    assert np.isfinite(stack).all()
    tool_pose = np.array(st_module.call("ChainToolPose", Chain=chain, Frames=frames))
    jac = np.array(st_module.call("ChainJacobianFromFrames", Chain=chain, Frames=frames))
    jpos = np.array(st_module.call("ChainJacobianPosition", Chain=chain, Joints=joints))
    assert np.isfinite(tool_pose).all() and np.isfinite(jac).all() and np.isfinite(jpos).all()
    if bad is not None:
        assert np.array_equal(stack, np.broadcast_to(np.eye(4), stack.shape))
        return
    qr = np.radians(np.array(joints[: robot.n], dtype=np.float32).astype(float))
    acc = np.eye(4)
    for i, link in enumerate(robot.links):
        a_i = link.A(qr[i]).A
        got = np.array(st_module.call("ChainLinkTransform", Link=chain["Links"][i],
                                      Modified=modified, JointValue=joints[i]))
        assert np.abs(got[:3, :3] - a_i[:3, :3]).max() < 2e-6
        assert np.abs(got[:3, 3] - a_i[:3, 3] * scale).max() < 2e-6 * max(scale, 200.0)
        acc = acc @ a_i
        assert np.abs(stack[i + 1][:3, :3] - acc[:3, :3]).max() < 1e-5
    tooled = rtb.DHRobot(robot.links, tool=sm.SE3(*(np.array(tool, np.float32) / scale)))
    ref = tooled.fkine(qr).A
    assert np.abs(tool_pose[:3, :3] - ref[:3, :3]).max() < 2e-5
    assert np.abs(tool_pose[:3, 3] - ref[:3, 3] * scale).max() < 2e-3
    ref_j = tooled.jacob0(qr)
    n = robot.n
    assert np.abs(jac[:3, :n] - ref_j[:3] * scale).max() < 2e-3
    assert np.abs(jac[3:, :n] - ref_j[3:]).max() < 2e-5
    assert not jac[:, n:].any()
    assert np.abs(jpos[:, :n] - ref_j[:3] * scale).max() < 2e-3


@examples(200)
@given(link=st.fixed_dictionaries({
    "A": st.floats(-1e3, 1e3, width=32), "AlphaDeg": st.floats(-180.0, 180.0, width=32),
    "D": st.floats(-1e3, 1e3, width=32), "ThetaOffsetDeg": st.floats(-180.0, 180.0, width=32),
    "Prismatic": st.booleans(), "LowerLimit": st.just(0.0), "UpperLimit": st.just(0.0)}),
       modified=st.booleans(), value=real(-1e6, 1e6))
def test_link_transform_any_value(st_module: Any, link: dict[str, Any], modified: bool,
                                  value: float) -> None:
    """Any joint value: never NaN; NaN, Inf or beyond 1e6: the identity; else a rigid motion
    equal to the DH product written out here (standard or modified)."""
    value = f32(value)
    got = np.array(st_module.call("ChainLinkTransform", Link=link, Modified=modified,
                                  JointValue=value))
    assert np.isfinite(got).all()
    if not (math.isfinite(value) and abs(value) <= 1e6):
        assert np.array_equal(got, np.eye(4))
        return
    theta = math.radians(link["ThetaOffsetDeg"] + (0.0 if link["Prismatic"] else value))
    d = link["D"] + (value if link["Prismatic"] else 0.0)
    alpha = math.radians(link["AlphaDeg"])
    rz = Rotation.from_euler("z", theta).as_matrix()
    rx = Rotation.from_euler("x", alpha).as_matrix()

    def h(r: np.ndarray, p: tuple[float, float, float]) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = r, p
        return m

    if modified:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
        ref = h(rx, (0, 0, 0)) @ h(np.eye(3), (link["A"], 0, 0)) @ h(rz, (0, 0, 0)) @ h(
            np.eye(3), (0, 0, d))
    else:  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        ref = h(rz, (0, 0, 0)) @ h(np.eye(3), (0, 0, d)) @ h(np.eye(3), (link["A"], 0, 0)) @ h(
            rx, (0, 0, 0))
    # the reduction of a large angle into (-180, 180] is exact; float32 of sin/cos remains
    assert np.abs(got[:3, :3] - ref[:3, :3]).max() < 2e-6
    assert np.abs(got[:3, 3] - ref[:3, 3]).max() < 2e-6 * (1.0 + abs(d) + abs(link["A"]))


# --- Linear algebra ----------------------------------------------------------------------------

@examples(300)
@given(size=st.sampled_from([1, 2, 3, 4, 5, 6, 0, 7]), seed=st.integers(0, 2**32 - 1),
       cond=st.sampled_from([1.0, 1e2, 1e4, 1e6]), kind=st.sampled_from(
           ["spd", "spd", "indefinite", "nan"]))
def test_cholesky_and_solve(st_module: Any, size: int, seed: int, cond: float,
                            kind: str) -> None:
    rng = np.random.default_rng(seed)
    n = max(1, min(size, 6))
    u, _ = np.linalg.qr(rng.normal(size=(n, n)))
    eig = np.geomspace(1.0, 1.0 / cond, n) * rng.uniform(0.1, 10.0)
    if kind == "indefinite":
        eig[-1] = -eig[0]
    a = (u * eig) @ u.T
    a = ((a + a.T) / 2).astype(np.float32).astype(float)
    if kind == "nan":
        a[n - 1, n - 1] = math.nan
    mat = np.zeros((6, 6))
    mat[:n, :n] = a
    pivot, outs = st_module.call_full("ChainCholesky", Size=size, Matrix=mat.tolist())
    factor = np.array(outs["Matrix"])
    if size != n or kind != "spd":
        assert pivot == -1.0
        return
    if pivot == -1.0:  # float32 may refuse a matrix near singular: only at cond ~ 1e6+
        assert cond >= 1e6
        return
    ref = np.linalg.cholesky(a)
    low = np.tril(factor[:n, :n])
    assert np.abs(low - ref).max() <= 1e-5 * cond * np.abs(ref).max()
    assert abs(pivot - float(np.min(np.diag(ref) ** 2))) <= 1e-4 * cond * float(np.max(eig))
    assert np.array_equal(np.triu(factor[:n, :n], 1), np.triu(a, 1))  # upper left as it was
    b = rng.normal(size=n)
    rhs = np.zeros(6)
    rhs[:n] = b
    ok, outs2 = st_module.call_full("ChainCholeskySolve", Size=size, Factor=factor.tolist(),
                                    Rhs=rhs.tolist())
    assert ok
    x = np.array(outs2["Rhs"])[:n]
    want = np.linalg.solve(a, b)
    assert np.abs(x - want).max() <= 1e-4 * cond * max(1.0, np.abs(want).max())


@examples(200)
@given(rows=st.integers(1, 6), cols=st.integers(1, 6), seed=st.integers(0, 2**32 - 1),
       lam=st.floats(1e-3, 1.0), band=st.floats(1e-3, 0.5), lmax=st.floats(0.0, 1.0),
       extra=st.floats(0.0, 1.0), mu=st.floats(1.0, 100.0), cap=st.floats(0.01, 10.0),
       base=st.one_of(st.just(-1.0), st.floats(0.0, 1.0)),
       sing=st.sampled_from([1.0, 1e-3, 1e-6, 0.0]))
# found by the 10x soak: a wide J with only the floor damping (J J^T's diagonal, not J^T J's)
@example(rows=1, cols=2, seed=0, lam=1.0, band=0.5, lmax=0.0, extra=0.0, mu=1.0, cap=1.0,
         base=0.0, sing=1.0)
# found by the soak with seed 2: rank 4 of 5 and Lambda 1e-3, J J^T + Lambda^2 I not positive
# definite in REAL, and the step failed on finite input
@example(rows=5, cols=5, seed=437, lam=0.001, band=0.5, lmax=0.0, extra=0.0, mu=1.0, cap=1.0,
         base=-1.0, sing=0.0)
def test_damped_step_is_the_dls_solution(st_module: Any, rows: int, cols: int, seed: int,
                                         lam: float, band: float, lmax: float, extra: float,
                                         mu: float, cap: float, base: float,
                                         sing: float) -> None:
    """dq solves (J^T J + lambda^2 I) dq = J^T e for the lambda^2 it reports, and lambda^2
    lies within the header's formula's bounds; near-singular and rank-deficient J too."""
    rng = np.random.default_rng(seed)
    jac = rng.normal(size=(rows, cols))
    if min(rows, cols) > 1:  # shrink the smallest singular value
        u, s, vt = np.linalg.svd(jac, full_matrices=False)
        s[-1] *= sing
        jac = (u * s) @ vt
    jac = jac.astype(np.float32).astype(float)
    err = rng.normal(size=rows).astype(np.float32).astype(float)
    jm, ev = np.zeros((6, 6)), np.zeros(6)
    jm[:rows, :cols], ev[:rows] = jac, err
    result = {"Dq": [0.0] * 6, "SigmaMin": 0.0, "DampingSq": 0.0, "Ok": False}
    ok, outs = st_module.call_full(
        "ChainDampedStep", TaskRows=rows, JointCount=cols, Lambda=f32(lam), Band=f32(band),
        LambdaMax=f32(lmax), ExtraSq=f32(extra), Mu=f32(mu), StepCap=f32(cap),
        BaseDampSq=f32(base), Jac=jm.tolist(), Err=ev.tolist(), Probe=[0.0] * 6, Result=result)
    res = outs["Result"]
    assert ok and res["Ok"]
    dq, l2 = np.array(res["Dq"]), res["DampingSq"]
    assert np.isfinite(dq).all() and math.isfinite(l2) and l2 > 0.0
    assert not dq[cols:].any()
    base_sq = f32(lam) ** 2 if base < 0 else f32(base)
    # the header's Gram matrix is the smaller one: J J^T for a wide or square J
    gram = jac @ jac.T if cols >= rows else jac.T @ jac
    floor = 1e-12 * float(np.max(np.diag(gram))) if jac.any() else 0.0
    low = f32(mu) * max(base_sq, floor)
    high = f32(mu) * (max(base_sq, floor) + f32(lmax) ** 2 + f32(extra))
    assert low * (1 - 1e-5) <= l2 <= high * (1 + 1e-5) + 1e-30
    want = np.linalg.solve(jac.T @ jac + l2 * np.eye(cols), jac.T @ err)
    # QR in REAL: the residual of the damped normal equations at REAL rounding of |J| |e|
    resid = (jac.T @ jac + l2 * np.eye(cols)) @ dq[:cols] - jac.T @ err
    scale = (np.linalg.norm(jac) ** 2 + l2) * max(np.linalg.norm(want), 1e-30)
    assert np.linalg.norm(resid) <= 1e-5 * scale + 1e-5 * np.linalg.norm(jac) * np.linalg.norm(
        err)


poses = st.tuples(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda c: np.linalg.norm(c) > 0.1), st.lists(st.floats(-1e3, 1e3), min_size=3,
                                                 max_size=3))


def to_mat4(pose: tuple[list[float], list[float]]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(pose[0]).as_matrix()
    m[:3, 3] = pose[1]
    return m.astype(np.float32).astype(float)


@examples(300)
@given(current=poses, target=poses, near_flip=st.booleans())
def test_pose_error(st_module: Any, current: Any, target: Any, near_flip: bool) -> None:
    cur = to_mat4(current)
    tgt = to_mat4(target)
    if near_flip:  # a rotation error within a hair of 180 deg
        axis = np.array(current[0][:3]) / max(np.linalg.norm(current[0][:3]), 1e-9)
        tgt[:3, :3] = (Rotation.from_rotvec(axis * (math.pi - 1e-4)).as_matrix() @ cur[:3, :3]
                       ).astype(np.float32)
    e = np.array(st_module.call("ChainPoseError", Current=cur.tolist(), Target=tgt.tolist()))
    assert np.abs(e[:3] - (tgt[:3, 3] - cur[:3, 3])).max() < 1e-3
    rel = Rotation.from_matrix(tgt[:3, :3] @ cur[:3, :3].T)
    got = Rotation.from_rotvec(e[3:])
    assert (got.inv() * rel).magnitude() < 1e-3  # same rotation, sign-free at 180 deg
    assert np.linalg.norm(e[3:]) <= math.pi + 1e-5


@examples(100)
@given(q=st.lists(st.floats(-170.0, 170.0), min_size=6, max_size=6),
       dx=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
       position_only=st.booleans(), lam=st.one_of(st.floats(1e-3, 0.05), st.sampled_from(
           [0.0, -0.1, 1.5, math.nan])),
       bad_joint=st.sampled_from([None, math.nan, math.inf]))
@example(q=[0.0, 0.0, 0.0, 0.0, 17.0, 0.0], dx=[0.0] * 5 + [1.0], position_only=False,
         lam=0.03125, bad_joint=None)
def test_resolved_rate_meets_the_displacement(st_module: Any, puma: Any, q: list[float],
                                              dx: list[float], position_only: bool,
                                              lam: float, bad_joint: float | None) -> None:
    chain = chain_of(puma, MM_PER_M)
    joints = [f32(v) for v in q]
    if bad_joint is not None:
        joints[2] = bad_joint
    disp = [f32(v) for v in dx]
    step = np.array(st_module.call("ChainResolvedRate", Chain=chain, PositionOnly=position_only,
                                   Lambda=f32(lam), Joints=joints, Displacement=disp))
    assert np.isfinite(step).all()
    if bad_joint is not None or not 0.0 < f32(lam) <= 1.0:
        assert not step.any()
        return
    qr = np.radians(joints)
    jac = puma.jacob0(qr)
    jac[:3] *= MM_PER_M
    rows = 3 if position_only else 6
    task = np.array(disp[:3] + [math.radians(v) for v in disp[3:]])[:rows]
    jj = jac[:rows]
    # the header's units: lengths over the chain's scale (sum of sqrt(a^2 + d^2), no tool),
    # so Lambda is dimensionless. Measured in mm against rad instead, a 0.1 mm miss of a
    # 1 deg turn looked like a broken promise (the soak's case below), while in these units
    # it is the DLS answer to 1e-5.
    scale = MM_PER_M * sum(math.hypot(float(lk.a), float(lk.d)) for lk in puma.links)
    w = np.r_[[scale] * 3, [1.0] * 3][:rows]
    js, ts = jj / w[:, None], task / w
    sig = np.linalg.svd(js, compute_uv=False)
    if sig.min() > 0.06:  # outside the singular band (0.05): plain DLS, lambda = Lambda
        lam2 = f32(lam) ** 2
        dls = js.T @ np.linalg.solve(js @ js.T + lam2 * np.eye(rows), ts)
        assert np.abs(np.radians(step) - dls).max() <= 1e-3 * np.abs(dls).max() + 1e-7
        # so it meets the displacement but for the damping's share, at most
        # lambda^2 / (sigma_min^2 + lambda^2) of it
        miss = np.linalg.norm(js @ np.radians(step) - ts)
        assert miss <= lam2 / (sig.min() ** 2 + lam2) * np.linalg.norm(ts) * 1.001 + 1e-6


@examples(100)
@given(q=st.lists(st.floats(-170.0, 170.0), min_size=6, max_size=6),
       qt=st.lists(st.floats(-170.0, 170.0), min_size=6, max_size=6),
       rows=st.sampled_from([3, 6]))
def test_chain_evaluate(st_module: Any, puma: Any, q: list[float], qt: list[float],
                        rows: int) -> None:
    chain = chain_of(puma, MM_PER_M)
    target = puma.fkine(np.radians(qt)).A
    target[:3, 3] *= MM_PER_M
    scale = f32(st_module.call("ChainScale", Chain=chain))
    joints = [f32(v) for v in q]
    res = {"Jac": np.zeros((6, 6)).tolist(), "Err": [0.0] * 6, "Energy": 0.0,
           "ResidualMm": 0.0, "ResidualDeg": 0.0}
    energy, outs = st_module.call_full("ChainEvaluate", Chain=chain, TaskRows=rows,
                                       Scale=scale, Joints=joints, Target=target.tolist(),
                                       Result=res)
    r = outs["Result"]
    cur = puma.fkine(np.radians(joints)).A
    dp = (target[:3, 3] - cur[:3, 3] * MM_PER_M)
    assert abs(r["ResidualMm"] - np.linalg.norm(dp)) < 2e-3
    err = dp / scale
    ang = Rotation.from_matrix(target[:3, :3] @ cur[:3, :3].T).magnitude()
    if rows == 6:
        assert abs(r["ResidualDeg"] - math.degrees(ang)) < 2e-3
        want = 0.5 * (np.dot(err, err) + ang**2)
    else:
        want = 0.5 * np.dot(err, err)
    assert energy == r["Energy"] and abs(energy - want) <= 1e-5 * want + 1e-9
    jac = puma.jacob0(np.radians(joints))
    assert np.abs(np.array(r["Jac"])[:3] - jac[:3] * MM_PER_M / scale).max() < 2e-5


# --- Fixed point -------------------------------------------------------------------------------

@examples(400)
@given(value=st.one_of(st.integers(-(2**62) + 1, 2**62 - 1), st.sampled_from(
           [0, 1, -1, 2**62 - 1, -(2**62) + 1, 3, -3, 5, -5])),
       bits=st.one_of(st.integers(-70, 70), st.sampled_from([0, 1, 62, 63, -62, -63])))
def test_shift_lint_and_bit_length(st_module: Any, value: int, bits: int) -> None:
    got = st_module.call("ChainShiftLint", value, bits)
    if bits > 0:
        if bits >= 63:
            want = 0
        else:  # round to nearest, halves away from zero, in exact integers
            half = 1 << (bits - 1)
            want = (abs(value) + half) >> bits
            want = want if value >= 0 else -want
        assert got == want
    elif -bits <= 62:
        if abs(value << -bits) < 2**63:  # the caller keeps the result below 2^63
            assert got == value << -bits
    else:
        assert got == 0
    n = st_module.call("ChainBitLength", value)
    assert n == (value.bit_length() if value >= 0 else 0)


@examples(400)
@given(angle=st.one_of(st.integers(-(2**31), 2**31 - 1), st.sampled_from(
           [0, 2**22, 2**23, 3 * 2**22, 2**24, -(2**31), 2**31 - 1, -1, 1])))
def test_sin_cos_turn_fixed(st_module: Any, angle: int) -> None:
    fb = st_module.new_fb("SinCosTurnFixed")
    fb(AngleT24=angle)
    turn = (angle & 0xFFFFFF) / Q24 * 2 * math.pi
    assert abs(fb.SinQ18 / Q18 - math.sin(turn)) <= 1.1e-5
    assert abs(fb.CosQ18 / Q18 - math.cos(turn)) <= 1.1e-5
    if angle & 0x3FFFFF == 0:  # exact at 0, 90, 180, 270 deg
        assert (fb.SinQ18, fb.CosQ18) == (round(math.sin(turn)) * Q18, round(math.cos(turn))
                                          * Q18)


def fixed_geo_ok(g: dict[str, int]) -> bool:
    return (abs(g["A1Um"]) <= 2_000_000 and abs(g["A2Um"]) <= 2_000_000
            and 1 <= g["A3Um"] <= 2_000_000 and 0 <= g["A4Um"] <= 2_000_000
            and 0 <= g["A5Um"] <= 2_000_000
            and abs(g["A2Um"]) + g["A3Um"] + g["A4Um"] + g["A5Um"] <= 4_000_000)


dint = st.one_of(st.integers(-2_500_000, 2_500_000), st.sampled_from(
    [-(2**31), 2**31 - 1, 0, 1, -1, 2_000_000, 2_000_001, -2_000_001]))


@examples(300)
@given(g=st.fixed_dictionaries({k: dint for k in ("A1Um", "A2Um", "A3Um", "A4Um", "A5Um")}),
       q=st.lists(st.one_of(st.integers(-(2**31), 2**31 - 1), st.integers(-(2**23), 2**23)),
                  min_size=4, max_size=4))
def test_fixed_geometry_and_forward(st_module: Any, g: dict[str, int], q: list[int]) -> None:
    code = st_module.call("ChainGeometryFixedCheck", g)
    assert code == (0 if fixed_geo_ok(g) else BAD_GEOMETRY)
    fb = st_module.new_fb("ChainForwardFixed")
    fb(Joints=q, Geometry=g)
    assert fb.ErrorId == code and fb.Error == (code != 0)
    if code:
        return
    # the file header's closed form, float64, on the angles reduced to one turn
    t = [(v & 0xFFFFFF) / Q24 * 2 * math.pi for v in q]
    a = [g[k] * 1e-6 for k in ("A1Um", "A2Um", "A3Um", "A4Um", "A5Um")]
    p2, p3, p4 = t[1], t[1] + t[2], t[1] + t[2] + t[3]
    r = a[1] + a[2] * math.cos(p2) + a[3] * math.cos(p3) + a[4] * math.cos(p4)
    want = np.array([r * math.cos(t[0]), r * math.sin(t[0]),
                     a[0] + a[2] * math.sin(p2) + a[3] * math.sin(p3) + a[4] * math.sin(p4)])
    got = np.array([fb.XUm, fb.YUm, fb.ZUm]) * 1e-6
    links = a[2] + a[3] + a[4] + abs(a[1])
    # the sine table's 1.1e-5 times the link lengths, and the um rounding
    assert np.abs(got - want).max() <= 1.1e-5 * links * 2 + 2e-6
    num = np.zeros((3, 4))
    for k in range(4):
        def fk(tt: list[float]) -> np.ndarray:
            q2, q3, q4 = tt[1], tt[1] + tt[2], tt[1] + tt[2] + tt[3]
            rr = a[1] + a[2] * math.cos(q2) + a[3] * math.cos(q3) + a[4] * math.cos(q4)
            return np.array([rr * math.cos(tt[0]), rr * math.sin(tt[0]),
                             a[0] + a[2] * math.sin(q2) + a[3] * math.sin(q3)
                             + a[4] * math.sin(q4)])
        tp, tm = list(t), list(t)
        tp[k] += 1e-6
        tm[k] -= 1e-6
        num[:, k] = (fk(tp) - fk(tm)) / 2e-6
    jac = np.array([fb.JacobianX, fb.JacobianY, fb.JacobianZ])  # rows X, Y, Z
    assert np.abs(jac / Q24 - num).max() <= 1.1e-5 * links * 4 + 1e-6


# --- The 4-axis and 5-axis arms ---------------------------------------------------------------

geo4 = st.fixed_dictionaries({
    "BaseHeightMm": real(-200.0, 200.0), "ShoulderOffsetMm": st.floats(-50.0, 50.0, width=32),
    "UpperArmMm": st.one_of(st.floats(50.0, 300.0, width=32), st.sampled_from(
        [0.0, -1.0, NEXT_1E6, math.nan])),
    "ForearmMm": st.floats(50.0, 300.0, width=32), "WristLinkMm": st.floats(0.0, 80.0,
                                                                            width=32),
    "ToolDropMm": st.floats(-30.0, 30.0, width=32)})


@examples(200)
@given(g=geo4, q=st.lists(st.floats(-180.0, 180.0, width=32), min_size=4, max_size=4))
@example(g={"BaseHeightMm": 1e6, "ShoulderOffsetMm": 0.0, "UpperArmMm": 50.0, "ForearmMm": 50.0,
            "WristLinkMm": 0.0, "ToolDropMm": 1.46875}, q=[0.0, 0.0, 0.0, 0.0])
def test_four_axis_geometry_chain_and_forward(st_module: Any, g: dict[str, float],
                                              q: list[float]) -> None:
    eq = st_module.call("Arm4AxisEquivalent", g)
    want = {"A1": g["BaseHeightMm"] - g["ToolDropMm"],
            "A2": g["ShoulderOffsetMm"] + g["WristLinkMm"], "A3": g["UpperArmMm"],
            "A4": g["ForearmMm"]}
    for k, v in want.items():
        assert (math.isnan(eq[k]) and math.isnan(v)) or eq[k] == v or (
            abs(eq[k] - v) <= 1e-6 * (1 + abs(v)))
    chain = chain_of(four_axis_rtb(FOUR_AXIS_GEO))
    code, outs = st_module.call_full("Arm4AxisFillChain", Geometry=g, Chain=chain)
    ok = (all(math.isfinite(v) and abs(v) <= 1e6 for v in g.values())
          and g["UpperArmMm"] > 0 and g["ForearmMm"] > 0)
    assert code == (0 if ok else BAD_GEOMETRY)
    assert outs["Chain"]["Count"] == 4 and outs["Chain"]["Modified"]
    if not ok:
        return
    js = list(q) + [0.0, 0.0]
    t = np.array(st_module.call("ForwardKinematic_4Axis", Geometry=g, Joints=js))
    ref = four_axis_rtb({k: f32(v) for k, v in g.items()}).fkine(np.radians(q)).A
    assert np.abs(t[:3, :3] - ref[:3, :3]).max() < 2e-5
    # REAL resolves a coordinate to half an ulp of the lengths summed into it: 0.03 mm at
    # a 1.0E6 mm base height (the soak's case below), not the 5e-3 mm of an arm's size
    ulp = float(np.spacing(np.float32(sum(abs(f32(v)) for v in g.values()))))
    assert np.abs(t[:3, 3] - ref[:3, 3]).max() < 5e-3 + 2 * ulp


@examples(300)
@given(p=st.one_of(st.tuples(st.floats(-350.0, 350.0), st.floats(-350.0, 350.0),
                             st.floats(-250.0, 450.0)),
                   st.lists(real(-1e6, 1e6), min_size=3, max_size=3).map(tuple)),
       elbow_up=st.booleans())
def test_four_axis_ik_check_and_solve(st_module: Any, arm4: Any, p: tuple[float, ...],
                                      elbow_up: bool) -> None:
    x, y, z = (f32(v) for v in p)
    g = FOUR_AXIS_GEO
    code = st_module.call("InverseKinematik4AxisCheck", X=x, Y=y, Z=z, Geometry=g)
    q = st_module.call("InverseKinematik_4Axis", X=x, Y=y, Z=z, Geometry=g, ElbowUp=elbow_up)
    assert all(math.isfinite(v) for v in q)
    if not all(math.isfinite(v) and abs(v) <= REAL_1E30 for v in (x, y, z)):
        assert code == 3
    # the reduced arm's reach shell around the shoulder (closed form, float64)
    a2 = g["ShoulderOffsetMm"] + g["WristLinkMm"]
    a1 = g["BaseHeightMm"] - g["ToolDropMm"]
    if all(abs(v) < 1e4 for v in (x, y, z)):
        cp = math.hypot(math.hypot(x, y) - a2, z - a1)
        lo, hi = abs(g["UpperArmMm"] - g["ForearmMm"]), g["UpperArmMm"] + g["ForearmMm"]
        if lo + 0.5 < cp < hi - 0.5 and math.hypot(x, y) > 1.0:
            assert code == 0
        elif cp > hi + 0.5 or cp < lo - 0.5:
            assert code != 0
    if code == 0:
        t = arm4.fkine(np.radians(q[:4])).A
        assert np.abs(t[:3, 3] - [x, y, z]).max() < 5e-3
        assert abs(t[2, 0]) < 1e-5  # the last link horizontal


@examples(40)
@given(targets=st.lists(st.one_of(
    st.tuples(st.floats(120.0, 250.0), st.floats(-100.0, 100.0), st.floats(0.0, 200.0)),
    st.tuples(*[st.sampled_from([math.nan, 1e6, 0.0])] * 3)), min_size=1, max_size=12),
       enables=st.lists(st.booleans(), min_size=12, max_size=12))
def test_four_axis_kinematics_block(st_module: Any, arm4: Any,
                                    targets: list[tuple[float, float, float]],
                                    enables: list[bool]) -> None:
    """One solve per scan while Enable; a refused target keeps the last valid joints."""
    fb = st_module.new_fb("Arm4AxisKinematics")
    last: list[float] | None = None
    for (x, y, z), enable in zip(targets, enables, strict=False):
        fb(Enable=enable, X=f32(x), Y=f32(y), Z=f32(z), ElbowUp=True, Geometry=FOUR_AXIS_GEO)
        joints = [float(v) for v in fb.Joints]
        assert all(math.isfinite(v) for v in joints)
        if not enable:
            continue
        code = st_module.call("InverseKinematik4AxisCheck", X=f32(x), Y=f32(y), Z=f32(z),
                              Geometry=FOUR_AXIS_GEO)
        assert fb.ErrorId == code and fb.Error == (code != 0)
        if code == 0:
            t = arm4.fkine(np.radians(joints[:4])).A
            assert np.abs(t[:3, 3] - [f32(x), f32(y), f32(z)]).max() < 5e-3
            last = joints
        elif last is not None:
            assert joints == last


@examples(300)
@given(a=st.lists(real(-1e3, 1e3), min_size=4, max_size=4), tool=real(0.0, 1e6))
def test_five_axis_geometry_check(st_module: Any, a: list[float], tool: float) -> None:
    arm_geo = dict(zip(("A1", "A2", "A3", "A4"), (f32(v) for v in a), strict=True))
    tool = f32(tool)
    code = st_module.call("FiveAxisGeometryCheck", {"Arm": arm_geo, "ToolMm": tool})
    ok = (all(math.isfinite(v) and abs(v) <= 1e6 for v in arm_geo.values())
          and arm_geo["A3"] > 0 and arm_geo["A4"] > 0 and math.isfinite(tool)
          and 0.0 <= tool <= 1e6)
    assert code == (0 if ok else BAD_GEOMETRY)


# --- The forms a block keeps (no 2-D array in its state: OpenPLC v4's debugger table) --------

finite_f32 = st.floats(-1e6, 1e6, allow_nan=False, width=32)


@examples(100)
@given(m=st.lists(finite_f32, min_size=16, max_size=16), canonical=st.booleans())
def test_chain_pose_round_trip(st_module: Any, m: list[float], canonical: bool) -> None:
    """ChainPoseOf keeps a Mat4's columns, reports whether the bottom row is 0 0 0 1;
    ChainPoseMatrix gives the matrix back with that row; ChainPoseEntry reads every entry."""
    mat = np.array(m, dtype=float).reshape(4, 4)
    if canonical:
        mat[3] = [0.0, 0.0, 0.0, 1.0]
    pose = {"AxisX": [0.0] * 3, "AxisY": [0.0] * 3, "AxisZ": [0.0] * 3, "Origin": [0.0] * 3}
    ok, outs = st_module.call_full("ChainPoseOf", Matrix=mat.tolist(), Pose=pose)
    assert ok == bool((mat[3] == [0.0, 0.0, 0.0, 1.0]).all())
    got = outs["Pose"]
    for col, name in enumerate(("AxisX", "AxisY", "AxisZ", "Origin")):
        assert got[name] == mat[:3, col].tolist()
    back = np.array(st_module.call("ChainPoseMatrix", Pose=got))
    want = mat.copy()
    want[3] = [0.0, 0.0, 0.0, 1.0]
    assert (back == want).all()
    for r in range(1, 5):
        for c in range(1, 5):
            assert st_module.call("ChainPoseEntry", Pose=got, Row=r, Col=c) == want[r - 1, c - 1]


@examples(60)
@given(jac=st.lists(finite_f32, min_size=36, max_size=36),
       err=st.lists(finite_f32, min_size=6, max_size=6), extra=st.lists(finite_f32, min_size=3,
                                                                       max_size=3))
def test_chain_evaluation_keep_and_restore(st_module: Any, jac: list[float], err: list[float],
                                           extra: list[float]) -> None:
    """ChainEvaluationKeep then ChainEvaluationRestore give the evaluation back to the bit."""
    ev = {"Jac": np.array(jac).reshape(6, 6).tolist(), "Err": err, "Energy": extra[0],
          "ResidualMm": extra[1], "ResidualDeg": extra[2]}
    kept = {"JacRows": [{"Cols": [0.0] * 6} for _ in range(6)], "Err": [0.0] * 6,
            "Energy": 0.0, "ResidualMm": 0.0, "ResidualDeg": 0.0}
    energy, outs = st_module.call_full("ChainEvaluationKeep", Eval=ev, Kept=kept)
    assert [row["Cols"] for row in outs["Kept"]["JacRows"]] == ev["Jac"]
    assert energy == extra[0]
    blank = {"Jac": [[0.0] * 6 for _ in range(6)], "Err": [0.0] * 6, "Energy": 0.0,
             "ResidualMm": 0.0, "ResidualDeg": 0.0}
    energy, back = st_module.call_full("ChainEvaluationRestore", Kept=outs["Kept"], Eval=blank)
    assert energy == extra[0] and back["Eval"] == ev


@examples(40)
@given(q=st.lists(st.floats(-170.0, 170.0), min_size=6, max_size=6),
       qt=st.lists(st.floats(-170.0, 170.0), min_size=6, max_size=6),
       rows=st.sampled_from([3, 6]))
def test_chain_evaluate_kept_is_chain_evaluate(st_module: Any, puma: Any, q: list[float],
                                               qt: list[float], rows: int) -> None:
    """ChainEvaluateKept (target as a ChainPose, result by rows) computes ChainEvaluate's
    values to the bit."""
    chain = chain_of(puma, MM_PER_M)
    target = puma.fkine(np.radians(qt)).A
    target[:3, 3] *= MM_PER_M
    target = target.astype(np.float32).astype(float)
    scale = f32(st_module.call("ChainScale", Chain=chain))
    joints = [f32(v) for v in q]
    res = {"Jac": np.zeros((6, 6)).tolist(), "Err": [0.0] * 6, "Energy": 0.0,
           "ResidualMm": 0.0, "ResidualDeg": 0.0}
    energy, outs = st_module.call_full("ChainEvaluate", Chain=chain, TaskRows=rows,
                                       Scale=scale, Joints=joints, Target=target.tolist(),
                                       Result=res)
    pose = {"AxisX": target[:3, 0].tolist(), "AxisY": target[:3, 1].tolist(),
            "AxisZ": target[:3, 2].tolist(), "Origin": target[:3, 3].tolist()}
    kept = {"JacRows": [{"Cols": [0.0] * 6} for _ in range(6)], "Err": [0.0] * 6,
            "Energy": 0.0, "ResidualMm": 0.0, "ResidualDeg": 0.0}
    energy_k, outs_k = st_module.call_full("ChainEvaluateKept", Chain=chain, TaskRows=rows,
                                           Scale=scale, Joints=joints, Target=pose,
                                           Result=kept)
    r, k = outs["Result"], outs_k["Result"]
    assert energy_k == energy
    assert [row["Cols"] for row in k["JacRows"]] == r["Jac"] and k["Err"] == r["Err"]
    assert (k["Energy"], k["ResidualMm"], k["ResidualDeg"]) == (
        r["Energy"], r["ResidualMm"], r["ResidualDeg"])


@examples(60)
@given(rows=st.integers(1, 6), cols=st.integers(1, 6), seed=st.integers(0, 2**31 - 1),
       lam=st.floats(1e-3, 10.0), cap=st.floats(0.1, 10.0))
def test_chain_damped_step_rows_is_chain_damped_step(st_module: Any, rows: int, cols: int,
                                                     seed: int, lam: float,
                                                     cap: float) -> None:
    """ChainDampedStepRows (the Jacobian by rows) gives ChainDampedStep's step to the bit."""
    rng = np.random.default_rng(seed)
    jm, ev = np.zeros((6, 6)), np.zeros(6)
    jm[:rows, :cols] = rng.normal(size=(rows, cols)).astype(np.float32)
    ev[:rows] = rng.normal(size=rows).astype(np.float32)
    args = {"TaskRows": rows, "JointCount": cols, "Lambda": f32(lam), "Band": 0.5,
            "LambdaMax": 0.1, "ExtraSq": 0.0, "Mu": 1.0, "StepCap": f32(cap),
            "BaseDampSq": -1.0}
    result = {"Dq": [0.0] * 6, "SigmaMin": 0.0, "DampingSq": 0.0, "Ok": False}
    ok, outs = st_module.call_full("ChainDampedStep", **args, Jac=jm.tolist(),
                                   Err=ev.tolist(), Probe=[0.0] * 6, Result=dict(result))
    rows_in = [{"Cols": row} for row in jm.tolist()]
    ok_r, outs_r = st_module.call_full("ChainDampedStepRows", **args, JacRows=rows_in,
                                       Err=ev.tolist(), Probe=[0.0] * 6, Result=dict(result))
    assert ok_r == ok and outs_r["Result"] == outs["Result"]
    assert outs_r["Probe"] == outs["Probe"]
