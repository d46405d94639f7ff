"""st/KinematicsChain.st forward kinematics and Jacobians against the Robotics Toolbox.

References: roboticstoolbox-python's DHRobot (standard DH, RevoluteDH/PrismaticDH, its
Puma 560) and modified DH (RevoluteMDH/PrismaticMDH), float64: link.A, fkine, fkine_all,
jacob0; numpy for the Cholesky solver; spatialmath for rotation vectors; the document-002
arm's own FK (st/Kinematics.st, itself checked against numpy and the toolbox) for the
cross-check of the generic chain with the 3-DOF arm written as a DH table.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from chain_models import MM_PER_M, chain_of, empty_link, joints_st, puma560

rtb = pytest.importorskip("roboticstoolbox")
sm = pytest.importorskip("spatialmath")

FK_TOL_MM = 1e-3        # position, mm
ROT_TOL = 1e-5          # rotation matrix entries
JAC_TOL = 1e-5          # jacob0 in the toolbox's units (m/rad and rad/rad)
N_CONFIGS = 200


def to_toolbox_units(robot: Any, J: np.ndarray) -> np.ndarray:
    """Our Jacobian (mm per rad, mm per mm) in the toolbox's units (m per rad, m per m)."""
    out = np.array(J, dtype=float)[:, :robot.n]
    for i, link in enumerate(robot.links):
        if link.isrevolute:
            out[:3, i] /= MM_PER_M
    return out


def random_mixed_robot(rng: np.random.Generator, modified: bool) -> Any:
    """Six joints, revolute and prismatic mixed, random geometry (metres)."""
    links = []
    for i in range(6):
        a, d = rng.uniform(-0.4, 0.4, 2)
        alpha, offset = rng.uniform(-math.pi, math.pi, 2)
        if i in (2, 4):
            cls = rtb.PrismaticMDH if modified else rtb.PrismaticDH
            links.append(cls(a=a, alpha=alpha, theta=offset, offset=d))
        else:
            cls = rtb.RevoluteMDH if modified else rtb.RevoluteDH
            links.append(cls(a=a, d=d, alpha=alpha, offset=offset))
    return rtb.DHRobot(links)


def random_q(rng: np.random.Generator, robot: Any) -> np.ndarray:
    return np.array([rng.uniform(-math.pi, math.pi) if link.isrevolute
                     else rng.uniform(-0.3, 0.3) for link in robot.links])


def test_link_transform_matches_toolbox_link_A(st_module: Any) -> None:
    rng = np.random.default_rng(11)
    worst = 0.0
    for modified in (False, True):
        robot = random_mixed_robot(rng, modified)
        chain = chain_of(robot, MM_PER_M)
        for _ in range(50):
            q = random_q(rng, robot)
            js = joints_st(robot, q, MM_PER_M)
            for i, link in enumerate(robot.links):
                got = np.array(st_module.call("ChainLinkTransform", Link=chain["Links"][i],
                                              Modified=modified, JointValue=js[i]))
                ref = link.A(q[i]).A
                worst = max(worst, float(np.abs(got[:3, :3] - ref[:3, :3]).max()))
                assert np.abs(got[:3, :3] - ref[:3, :3]).max() < ROT_TOL
                assert np.abs(got[:3, 3] - ref[:3, 3] * MM_PER_M).max() < FK_TOL_MM
                assert got[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    print(f"\nChainLinkTransform vs link.A: worst rotation entry {worst:.2e}")


@pytest.mark.parametrize("name", ["puma560", "mixed-DH", "mixed-MDH"])
def test_fk_frames_and_jacobian_match_toolbox(st_module: Any, name: str) -> None:
    rng = np.random.default_rng(5)
    robot = {"puma560": puma560(), "mixed-DH": random_mixed_robot(rng, False),
             "mixed-MDH": random_mixed_robot(rng, True)}[name]
    tool = (0.0, 0.0, 0.0)
    if name != "puma560":
        tool_m = rng.uniform(-0.1, 0.1, 3)
        robot.tool = sm.SE3(*tool_m)
        tool = tuple(float(v) * MM_PER_M for v in tool_m)
    chain = chain_of(robot, MM_PER_M, tool=tool)
    worst_p = worst_j = 0.0
    for _ in range(N_CONFIGS):
        q = random_q(rng, robot)
        js = joints_st(robot, q, MM_PER_M)
        T = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain, Joints=js))
        ref = robot.fkine(q).A
        worst_p = max(worst_p, float(np.abs(T[:3, 3] - ref[:3, 3] * MM_PER_M).max()))
        assert np.abs(T[:3, 3] - ref[:3, 3] * MM_PER_M).max() < FK_TOL_MM
        assert np.abs(T[:3, :3] - ref[:3, :3]).max() < ROT_TOL
        J = np.array(st_module.call("ChainJacobian", Chain=chain, Joints=js))
        Jr = robot.jacob0(q)
        got = to_toolbox_units(robot, J)
        err = float(np.abs(got - Jr).max())
        worst_j = max(worst_j, err)
        assert err < JAC_TOL, (q, got, Jr)
        Jp = np.array(st_module.call("ChainJacobianPosition", Chain=chain, Joints=js))
        assert np.abs(to_toolbox_units(robot, np.vstack([Jp, J[3:]]))[:3] - Jr[:3]).max() \
            < JAC_TOL
    # every frame: fkine_all gives frames 0..n (without the tool)
    q = random_q(rng, robot)
    frames = np.array([f["Pose"] for f in st_module.call(
        "ChainFramePoses", Chain=chain, Joints=joints_st(robot, q, MM_PER_M))])
    ref_all = robot.fkine_all(q)
    for i in range(robot.n + 1):
        assert np.abs(frames[i][:3, 3] - ref_all[i].A[:3, 3] * MM_PER_M).max() < FK_TOL_MM
        assert np.abs(frames[i][:3, :3] - ref_all[i].A[:3, :3]).max() < ROT_TOL
    print(f"\n{name}: FK worst {worst_p:.2e} mm, jacob0 worst {worst_j:.2e} over {N_CONFIGS}")


def test_short_chain_columns_past_count_are_zero(st_module: Any) -> None:
    robot = rtb.DHRobot([rtb.RevoluteDH(a=0.3), rtb.RevoluteDH(a=0.2)])
    chain = chain_of(robot, MM_PER_M)
    q = np.array([0.4, -1.1])
    J = np.array(st_module.call("ChainJacobian", Chain=chain,
                                Joints=joints_st(robot, q, MM_PER_M)))
    assert np.abs(J[:3, :2] / MM_PER_M - robot.jacob0(q)[:3]).max() < JAC_TOL
    assert not J[:, 2:].any()
    frames = np.array([f["Pose"] for f in st_module.call(
        "ChainFramePoses", Chain=chain, Joints=joints_st(robot, q, MM_PER_M))])
    for i in range(3, 7):  # frames past Count repeat the last one
        assert np.array_equal(frames[i], frames[2])


def test_generic_chain_equals_the_002_arm(st_module: Any) -> None:
    """The 3-DOF arm of document 002 as a DH table: the generic FK must give
    ForwardKinematic_V1's position, and the position Jacobian the toolbox's."""
    g = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}
    links = [
        {**empty_link(), "D": g["A1"], "A": g["A2"], "AlphaDeg": 90.0},
        {**empty_link(), "A": g["A3"]},
        {**empty_link(), "A": g["A4"], "ThetaOffsetDeg": -180.0},
        empty_link(), empty_link(), empty_link(),
    ]
    chain = {"Links": links, "Count": 3, "Modified": False}
    rng = np.random.default_rng(2)
    worst = 0.0
    for _ in range(N_CONFIGS):
        base, shoulder, elbow = rng.uniform([-180, -90, 0], [180, 180, 360])
        T = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain,
                                    Joints=[base, shoulder, elbow, 0.0, 0.0, 0.0]))
        ref = st_module.call("ForwardKinematic_V1",
                             Angles={"Base": base, "Shoulder": shoulder, "Elbow": elbow},
                             Geometry=g)
        d = float(np.abs(T[:3, 3] - [ref["X"], ref["Y"], ref["Z"]]).max())
        worst = max(worst, d)
        assert d < FK_TOL_MM
    print(f"\n002 arm: generic chain vs ForwardKinematic_V1 worst {worst:.2e} mm")


def test_cholesky_solver_matches_numpy(st_module: Any) -> None:
    rng = np.random.default_rng(3)
    for size in range(1, 7):
        for _ in range(20):
            M = rng.normal(size=(size, size))
            A = M @ M.T + 0.1 * np.eye(size)
            b = rng.normal(size=size)
            mat = np.zeros((6, 6))
            mat[:size, :size] = A
            pivot, outs = st_module.call_full("ChainCholesky", Size=size, Matrix=mat.tolist())
            L = np.tril(np.array(outs["Matrix"])[:size, :size])
            assert np.abs(L - np.linalg.cholesky(A)).max() < 1e-4 * max(1.0, np.abs(A).max())
            ref_piv = min(np.diag(np.linalg.cholesky(A)) ** 2)
            assert pivot == pytest.approx(ref_piv, rel=1e-4)
            rhs = np.zeros(6)
            rhs[:size] = b
            ok, outs2 = st_module.call_full("ChainCholeskySolve", Size=size,
                                            Factor=outs["Matrix"], Rhs=rhs.tolist())
            assert ok
            x = np.array(outs2["Rhs"][:size])
            ref_x = np.linalg.solve(A, b)
            assert np.abs(x - ref_x).max() < 1e-3 * max(1.0, np.abs(ref_x).max())
    # not positive definite, NaN, bad size: -1, never a fault
    bad = np.zeros((6, 6))
    bad[0, 0] = -1.0
    assert st_module.call("ChainCholesky", Size=1, Matrix=bad.tolist()) == -1.0
    bad[0, 0] = math.nan
    assert st_module.call("ChainCholesky", Size=1, Matrix=bad.tolist()) == -1.0
    assert st_module.call("ChainCholesky", Size=7, Matrix=np.eye(6).tolist()) == -1.0
    assert not st_module.call("ChainCholeskySolve", Size=3, Factor=np.zeros((6, 6)).tolist(),
                              Rhs=[1.0] * 6)


@pytest.mark.parametrize("angle_deg", [0.0, 1e-3, 30.0, 90.0, 150.0, 179.0, 179.99, 180.0])
def test_pose_error_rotation_vector(st_module: Any, angle_deg: float) -> None:
    rng = np.random.default_rng(int(angle_deg * 100))
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        R0 = sm.SO3.Rand().A
        Rt = sm.SO3.AngVec(math.radians(angle_deg), axis).A @ R0
        cur = np.eye(4)
        cur[:3, :3] = R0
        cur[:3, 3] = [1.0, 2.0, 3.0]
        tgt = np.eye(4)
        tgt[:3, :3] = Rt
        tgt[:3, 3] = [4.0, 6.0, 8.0]
        err = np.array(st_module.call("ChainPoseError", Current=cur.tolist(),
                                      Target=tgt.tolist()))
        assert np.allclose(err[:3], [3.0, 4.0, 5.0], atol=1e-5)
        vec = axis * math.radians(angle_deg)
        if angle_deg >= 179.99:  # +axis*pi and -axis*pi are the same rotation
            assert min(np.abs(err[3:] - vec).max(), np.abs(err[3:] + vec).max()) < 2e-3
        else:
            assert np.abs(err[3:] - vec).max() < 2e-4


def test_bad_tables_give_identity_never_nan(st_module: Any) -> None:
    robot = puma560()
    chain = chain_of(robot, MM_PER_M)
    js = joints_st(robot, np.zeros(6), MM_PER_M)
    for patch in ({"Count": 0}, {"Count": 7}, {"ToolX": math.nan}):
        T = np.array(st_module.call("ForwardKinematic_Chain", Chain={**chain, **patch},
                                    Joints=js))
        assert np.array_equal(T, np.eye(4))
        J = np.array(st_module.call("ChainJacobian", Chain={**chain, **patch}, Joints=js))
        assert not J.any()
    nan_link = [dict(link) for link in chain["Links"]]
    nan_link[1]["A"] = math.nan
    assert st_module.call("ChainCheck", Chain={**chain, "Links": nan_link}) == 30
    T = np.array(st_module.call("ForwardKinematic_Chain", Chain={**chain, "Links": nan_link},
                                Joints=js))
    assert np.array_equal(T, np.eye(4))
    T = np.array(st_module.call("ForwardKinematic_Chain", Chain=chain,
                                Joints=[math.nan] + js[1:]))
    assert np.array_equal(T, np.eye(4))
    # the link transform alone: identity for NaN
    L = np.array(st_module.call("ChainLinkTransform", Link=nan_link[1], Modified=False,
                                JointValue=10.0))
    assert np.array_equal(L, np.eye(4))
    # ChainCheck's codes
    assert st_module.call("ChainCheck", Chain=chain) == 0
    assert st_module.call("ChainCheck", Chain={**chain, "Count": 0}) == 31
    assert st_module.call("ChainCheck", Chain={**chain, "Count": 7}) == 30
    flat = {"Links": [empty_link() for _ in range(6)], "Count": 3, "Modified": False}
    assert st_module.call("ChainCheck", Chain=flat) == 31
    swapped = [dict(link) for link in chain["Links"]]
    swapped[0]["LowerLimit"], swapped[0]["UpperLimit"] = 10.0, -10.0
    assert st_module.call("ChainCheck", Chain={**chain, "Links": swapped}) == 30
