"""st/Kinematics4Axis.st (document 001's 4-axis arm) against the Robotics Toolbox.

Reference: a DHRobot of RevoluteMDH links built here from document 001's modified-DH table
(float64), with the horizontal last link and the tool drop as its tool transform. The IK is
checked by round trips FK(IK(p)) with the toolbox's FK, on 10,000 reachable points per
elbow, plus the constraint that defines the method: the last link stays horizontal.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from chain_models import FOUR_AXIS_GEO, empty_link, four_axis_rtb

rtb = pytest.importorskip("roboticstoolbox")
sm = pytest.importorskip("spatialmath")

GEO = FOUR_AXIS_GEO
N_ROUND_TRIP = 10_000
ROUND_TRIP_TOL_MM = 0.01
FK_TOL_MM = 1e-3
# ErrorIds (st/ArmAngles.st)
UNREACHABLE, SINGULAR, NOT_FINITE, BAD_GEOMETRY = 1, 2, 3, 4


def test_fk_and_jacobian_match_toolbox_mdh_model(st_module: Any) -> None:
    r = four_axis_rtb()
    rng = np.random.default_rng(1)
    worst = 0.0
    chain = {"Links": [empty_link() for _ in range(6)]}
    code, outs = st_module.call_full("Arm4AxisFillChain", Geometry=GEO, Chain=chain)
    assert code == 0 and outs["Chain"]["Count"] == 4 and outs["Chain"]["Modified"]
    for _ in range(500):
        q = rng.uniform(-180.0, 180.0, 4)
        js = [*q.tolist(), 0.0, 0.0]
        T = np.array(st_module.call("ForwardKinematic_4Axis", Geometry=GEO, Joints=js))
        ref = r.fkine(np.radians(q)).A
        d = float(np.abs(T[:3, 3] - ref[:3, 3]).max())
        worst = max(worst, d)
        assert d < FK_TOL_MM
        assert np.abs(T[:3, :3] - ref[:3, :3]).max() < 1e-5
        Tc = np.array(st_module.call("ForwardKinematic_Chain", Chain=outs["Chain"], Joints=js))
        assert np.abs(Tc - T).max() < 1e-4
        # jacob0 of the MDH model (mm per rad here: the model is in mm)
        J = np.array(st_module.call("ChainJacobian", Chain=outs["Chain"], Joints=js))[:, :4]
        Jr = r.jacob0(np.radians(q))
        assert np.abs(J[:3] / 1000.0 - Jr[:3] / 1000.0).max() < 1e-5   # m per rad
        assert np.abs(J[3:] - Jr[3:]).max() < 1e-5
    print(f"\n4-axis FK vs toolbox RevoluteMDH model: worst {worst:.2e} mm")


def reachable_points(rng: np.random.Generator, count: int) -> np.ndarray:
    """Tool points of random joint angles with the last link horizontal (so reachable),
    computed by the toolbox; a tenth of them within 0.01 mm of full stretch."""
    r = four_axis_rtb()
    q = np.zeros((count, 4))
    q[:, 0] = rng.uniform(-math.pi, math.pi, count)
    q[:, 1] = rng.uniform(-math.pi, math.pi, count)
    q[:, 2] = rng.uniform(-math.pi, math.pi, count)
    stretched = rng.random(count) < 0.1
    q[stretched, 2] = rng.uniform(-2e-3, 2e-3, int(stretched.sum()))
    q[:, 3] = -(q[:, 1] + q[:, 2])
    poses = r.fkine(q)
    return np.array([T.t for T in poses])


@pytest.mark.parametrize("elbow_up", [True, False], ids=["elbow-up", "elbow-down"])
def test_round_trip_10000_points(st_module: Any, elbow_up: bool) -> None:
    r = four_axis_rtb()
    rng = np.random.default_rng(2 if elbow_up else 3)
    pts = reachable_points(rng, N_ROUND_TRIP)
    answers = np.zeros((N_ROUND_TRIP, 4))
    skipped_axis = 0
    for i, (x, y, z) in enumerate(pts):
        code = st_module.call("InverseKinematik4AxisCheck", X=x, Y=y, Z=z, Geometry=GEO)
        if code == SINGULAR and math.hypot(x, y) < 0.01:
            skipped_axis += 1          # on the base axis: q1 undefined, documented
            answers[i] = np.nan
            continue
        assert code == 0, (x, y, z, code)
        answers[i] = st_module.call("InverseKinematik_4Axis", X=x, Y=y, Z=z, Geometry=GEO,
                                    ElbowUp=elbow_up)[:4]
    ok = ~np.isnan(answers[:, 0])
    assert skipped_axis < 5
    q = np.radians(answers[ok])
    poses = r.fkine(q)
    got = np.array([T.t for T in poses])
    err = np.linalg.norm(got - pts[ok], axis=1)
    # the last link horizontal: x4 (the link's direction) has no vertical component
    x_axis_z = np.array([T.A[2, 0] for T in poses])
    # elbow branch: q3 <= 0 for elbow up, >= 0 for elbow down (REAL slack at the stretch)
    q3 = answers[ok, 2]
    print(f"\n4-axis {'up' if elbow_up else 'down'}: {int(ok.sum())} points, FK(IK(p)) worst "
          f"{err.max():.2e} mm, mean {err.mean():.2e} mm; |x4_z| worst "
          f"{np.abs(x_axis_z).max():.1e}")
    assert err.max() < ROUND_TRIP_TOL_MM
    assert np.abs(x_axis_z).max() < 1e-5
    if elbow_up:
        assert (q3 <= 0.05).all()
    else:
        assert (q3 >= -0.05).all()


def test_both_elbows_differ_and_agree_at_the_tool(st_module: Any) -> None:
    up = st_module.call("InverseKinematik_4Axis", X=150.0, Y=60.0, Z=120.0, Geometry=GEO,
                        ElbowUp=True)
    down = st_module.call("InverseKinematik_4Axis", X=150.0, Y=60.0, Z=120.0, Geometry=GEO,
                          ElbowUp=False)
    assert up[2] < -1.0 and down[2] > 1.0
    assert up[0] == pytest.approx(math.degrees(math.atan2(60.0, 150.0)), abs=1e-4)
    # closed form of document 001's correction: the wrist point is the target moved in
    # by the horizontal link and up by the drop; the planar 2-link solve reaches it
    r_w = math.hypot(150.0, 60.0) - GEO["WristLinkMm"] - GEO["ShoulderOffsetMm"]
    z_w = 120.0 + GEO["ToolDropMm"] - GEO["BaseHeightMm"]
    a2, a3 = GEO["UpperArmMm"], GEO["ForearmMm"]
    c3 = (r_w**2 + z_w**2 - a2**2 - a3**2) / (2 * a2 * a3)
    q3 = math.degrees(math.acos(c3))
    assert down[2] == pytest.approx(q3, abs=1e-3)
    assert up[2] == pytest.approx(-q3, abs=1e-3)
    for q in (up, down):
        assert q[1] + q[2] + q[3] == pytest.approx(0.0, abs=1e-3)


def test_bad_input_keeps_last_valid(st_module: Any) -> None:
    fb = st_module.new_fb("Arm4AxisKinematics")
    fb(Enable=True, X=150.0, Y=60.0, Z=120.0, ElbowUp=True, Geometry=GEO)
    assert fb.Valid and not fb.Error
    good = fb.Joints
    cases = [
        ({"X": 1000.0}, UNREACHABLE),
        ({"X": 0.0, "Y": 0.0}, SINGULAR),
        ({"Z": math.nan}, NOT_FINITE),
        ({"Geometry": {**GEO, "UpperArmMm": 0.0}}, BAD_GEOMETRY),
        ({"Geometry": {**GEO, "WristLinkMm": math.inf}}, BAD_GEOMETRY),
    ]
    for patch, code in cases:
        fb(**{"Enable": True, "X": 150.0, "Y": 60.0, "Z": 120.0, "Geometry": GEO, **patch})
        assert fb.Error and not fb.Valid and fb.ErrorId == code, (patch, fb.ErrorId)
        assert fb.Joints == good
        x, y, z = (patch.get(k, d) for k, d in (("X", 150.0), ("Y", 60.0), ("Z", 120.0)))
        g = patch.get("Geometry", GEO)
        out = st_module.call("InverseKinematik_4Axis", X=x, Y=y, Z=z, Geometry=g, ElbowUp=True)
        assert out == [0.0] * 6
    fb(Enable=False)
    assert not fb.Error and fb.ErrorId == 0 and fb.Joints == good
    T = np.array(st_module.call("ForwardKinematic_4Axis", Geometry={**GEO, "ForearmMm": -1.0},
                                Joints=[10.0] * 6))
    assert np.array_equal(T, np.eye(4))
