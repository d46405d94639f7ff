"""st/Kinematics.st against independent references.

References: Python's math module, numpy, the float64 reference kinematics in
armbench.plant.arm (written from document 002's transform table, not from the ST), and --
when it is installed -- roboticstoolbox-python's DHRobot. Expected values are never captured
output of the ST code. Worst-case figures are printed (run with -s to see them).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from armbench.plant import arm

GEOMETRY = arm.DEFAULT_GEOMETRY  # a1=100, a2=20, a3=120, a4=130 mm
GEO = GEOMETRY.as_st()

# Error codes as documented in st/ArmAngles.st (part of the library's interface).
NO_ERROR, UNREACHABLE, SINGULAR, NOT_FINITE, BAD_GEOMETRY = 0, 1, 2, 3, 4

ANGLE_FIELDS = (
    "Base",
    "Shoulder",
    "Elbow",
    "GripperUpDown",
    "Gripper",
    "ElbowRotate",
    "GripperRotate",
)
COORD_FIELDS = ("X", "Y", "Z", "GripperUpDown", "Gripper", "ElbowRotate", "GripperRotate")

ROUND_TRIP_POINTS = 10_000
ROUND_TRIP_TOL_MM = 0.05
FK_TOL_MM = 0.01


def f32(x: float) -> float:
    return float(np.float32(x))


def angles(base: float, shoulder: float, elbow: float, **tool: float) -> dict[str, float]:
    out = dict.fromkeys(ANGLE_FIELDS, 0.0)
    out.update(Base=base, Shoulder=shoulder, Elbow=elbow)
    out.update(tool)
    return out


def coords(x: float, y: float, z: float, **tool: float) -> dict[str, float]:
    out = dict.fromkeys(COORD_FIELDS, 0.0)
    out.update(X=x, Y=y, Z=z)
    out.update(tool)
    return out


def angle_diff(a: float, b: float) -> float:
    """Smallest absolute difference of two angles in degrees."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def all_finite(values: dict[str, Any]) -> bool:
    return all(math.isfinite(v) for v in values.values())


def random_reachable_targets(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 3) targets uniformly spread over the reach shell, off the base axis.

    One tenth of them lie within 0.01 mm of the outer or inner shell (full stretch / fully
    folded), where a naive two-acos solution loses accuracy in float32.
    """
    low, high = arm.reach_limits(GEOMETRY)
    out: list[np.ndarray] = []
    n_shell = count // 10
    # Inside the shell: rejection sampling in (radial, z), random base angle.
    while sum(len(o) for o in out) < count - n_shell:
        radial = rng.uniform(1.0, GEOMETRY.a2 + high, 4096)
        z = rng.uniform(GEOMETRY.a1 - high, GEOMETRY.a1 + high, 4096)
        cp = np.hypot(radial - GEOMETRY.a2, z - GEOMETRY.a1)
        keep = (cp > low + 1e-3) & (cp < high - 1e-3)
        base = rng.uniform(-math.pi, math.pi, int(keep.sum()))
        r, zz = radial[keep], z[keep]
        out.append(np.stack([r * np.cos(base), r * np.sin(base), zz], axis=1))
    pts = np.concatenate(out)[: count - n_shell]
    # On the shells: distance from the shoulder axis within 0.01 mm of a limit.
    phi = rng.uniform(-math.pi, math.pi, 4 * n_shell)
    cp = np.where(
        rng.random(4 * n_shell) < 0.5,
        high - rng.uniform(0.0, 0.01, 4 * n_shell),
        low + rng.uniform(0.0, 0.01, 4 * n_shell),
    )
    radial = GEOMETRY.a2 + cp * np.cos(phi)
    z = GEOMETRY.a1 + cp * np.sin(phi)
    ok = radial > 1.0
    base = rng.uniform(-math.pi, math.pi, int(ok.sum()))
    shell = np.stack([radial[ok] * np.cos(base), radial[ok] * np.sin(base), z[ok]], axis=1)
    return np.concatenate([pts, shell[:n_shell]])


# --------------------------------------------------------------------------- helpers


def test_deg_rad_conversions(st_module: Any) -> None:
    for deg in (-720.0, -180.0, -90.0, -1.0, 0.0, 0.5, 45.0, 90.0, 180.0, 359.0):
        assert st_module.call("DegToRad", deg) == pytest.approx(math.radians(deg), rel=2e-7)
        rad = math.radians(deg)
        assert st_module.call("RadToDeg", rad) == pytest.approx(deg, rel=2e-7, abs=1e-6)


def test_is_finite_real(st_module: Any) -> None:
    for value in (0.0, -1.0, 3.0e38, -1.0e30, 1.0e30, 1.0e-38):
        expected = abs(value) <= 1.0e30
        assert bool(st_module.call("IsFiniteReal", value)) == expected
    for value in (math.nan, math.inf, -math.inf):
        assert not st_module.call("IsFiniteReal", value)


def test_wrap_deg180(st_module: Any) -> None:
    rng = np.random.default_rng(7)
    worst = 0.0
    for value in [*rng.uniform(-5000.0, 5000.0, 500), 180.0, -180.0, 540.0, -540.0, 0.0, 360.0]:
        got = st_module.call("WrapDeg180", float(value))
        assert -180.0 < got <= 180.0
        worst = max(worst, angle_diff(got, float(value)))
    assert worst < 1e-3
    assert st_module.call("WrapDeg180", -180.0) == pytest.approx(180.0)
    for bad in (math.nan, math.inf, -math.inf, 1.0e7):
        assert st_module.call("WrapDeg180", bad) == 0.0


def test_atan2_full_quadrant(st_module: Any) -> None:
    rng = np.random.default_rng(1)
    worst = 0.0
    cases = [(float(y), float(x)) for y, x in rng.uniform(-1000.0, 1000.0, (2000, 2))]
    cases += [(y, x) for y in (-1.0, 0.0, 1.0, 1e-30, -1e-30) for x in (-1.0, 0.0, 1.0, 1e-30)]
    cases += [(1e-3, -1e6), (-1e-3, -1e6), (1e6, 1e-3), (3.0, 3.0), (-3.0, -3.0)]
    for y, x in cases:
        got = st_module.call("ArcTan2", y, x)
        want = math.atan2(f32(y), f32(x))
        if y == 0.0 and x == 0.0:
            want = 0.0
        assert -math.pi - 1e-6 <= got <= math.pi + 1e-6
        err = abs(got - want)
        if err > math.pi:  # +pi and -pi are the same direction
            err = abs(err - 2.0 * math.pi)
        worst = max(worst, err)
    print(f"\nAtan2 worst error vs math.atan2: {worst:.3e} rad over {len(cases)} cases")
    assert worst < 1e-6
    assert st_module.call("ArcTan2", 0.0, 0.0) == 0.0
    assert st_module.call("ArcTan2", 0.0, -1.0) == pytest.approx(math.pi)
    assert st_module.call("ArcTan2", 1.0, 0.0) == pytest.approx(math.pi / 2.0)
    assert st_module.call("ArcTan2", -1.0, 0.0) == pytest.approx(-math.pi / 2.0)


def test_fill_transformation_matrix(st_module: Any) -> None:
    rng = np.random.default_rng(2)
    rot = rng.uniform(-1.0, 1.0, (3, 3))
    disp = rng.uniform(-500.0, 500.0, 3)
    got = np.array(st_module.call("FillTransformationMatrix", rot.tolist(), disp.tolist()))
    want = np.eye(4)
    want[:3, :3] = rot
    want[:3, 3] = disp
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)


def test_matmul4(st_module: Any) -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.uniform(-10.0, 10.0, (4, 4)).astype(np.float32)
        b = rng.uniform(-10.0, 10.0, (4, 4)).astype(np.float32)
        got = np.array(st_module.call("MatMul4", a.tolist(), b.tolist()))
        want = a.astype(np.float64) @ b.astype(np.float64)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-4)


# --------------------------------------------------------------------------- forward


def test_forward_kinematics_vs_numpy_oracle(st_module: Any) -> None:
    rng = np.random.default_rng(4)
    q = np.column_stack(
        [
            rng.uniform(-180.0, 180.0, 3000),
            rng.uniform(-180.0, 180.0, 3000),
            rng.uniform(0.0, 360.0, 3000),
        ]
    )
    want = arm.forward_batch(q, GEOMETRY)
    worst = 0.0
    for (b, s, e), w in zip(q, want, strict=True):
        got = st_module.call(
            "ForwardKinematic_V1", Angles=angles(float(b), float(s), float(e)), Geometry=GEO
        )
        worst = max(
            worst, float(np.linalg.norm([got["X"] - w[0], got["Y"] - w[1], got["Z"] - w[2]]))
        )
    print(f"\nFK vs numpy oracle: worst {worst:.4e} mm over {len(q)} random angle sets")
    assert worst <= FK_TOL_MM


def test_forward_kinematics_oracle_matches_closed_form() -> None:
    # The oracle's DH product against the closed form printed in Kinematics.st's header.
    rng = np.random.default_rng(5)
    for b, s, e in rng.uniform(-360.0, 360.0, (50, 3)):
        p = arm.forward(float(b), float(s), float(e))
        t1, t2, t3 = math.radians(b), math.radians(s), math.radians(e - 180.0)
        r = GEOMETRY.a2 + GEOMETRY.a3 * math.cos(t2) + GEOMETRY.a4 * math.cos(t2 + t3)
        z = GEOMETRY.a1 + GEOMETRY.a3 * math.sin(t2) + GEOMETRY.a4 * math.sin(t2 + t3)
        np.testing.assert_allclose(p, [r * math.cos(t1), r * math.sin(t1), z], atol=1e-9)


def test_forward_kinematics_vs_roboticstoolbox(st_module: Any) -> None:
    rtb = pytest.importorskip("roboticstoolbox")
    robot = rtb.DHRobot(
        [
            rtb.RevoluteDH(d=GEOMETRY.a1, a=GEOMETRY.a2, alpha=math.pi / 2.0),
            rtb.RevoluteDH(a=GEOMETRY.a3),
            rtb.RevoluteDH(a=GEOMETRY.a4, offset=-math.pi),
        ],
        name="doc002",
    )
    rng = np.random.default_rng(6)
    worst = 0.0
    for b, s, e in rng.uniform(-180.0, 180.0, (300, 3)):
        want = robot.fkine(np.radians([b, s, e])).t
        got = st_module.call(
            "ForwardKinematic_V1", Angles=angles(float(b), float(s), float(e)), Geometry=GEO
        )
        worst = max(worst, float(np.linalg.norm(np.array([got["X"], got["Y"], got["Z"]]) - want)))
    print(f"\nFK vs roboticstoolbox DHRobot: worst {worst:.4e} mm over 300 angle sets")
    assert worst <= FK_TOL_MM


def test_forward_kinematics_known_poses(st_module: Any) -> None:
    # Straight arm, horizontal, along +X: x = a2 + a3 + a4, z = a1.
    got = st_module.call("ForwardKinematic_V1", Angles=angles(0.0, 0.0, 180.0), Geometry=GEO)
    assert got["X"] == pytest.approx(270.0, abs=1e-3)
    assert got["Y"] == pytest.approx(0.0, abs=1e-3)
    assert got["Z"] == pytest.approx(100.0, abs=1e-3)
    # Upper arm vertical, forearm horizontal forward, base at 90 deg (along +Y).
    got = st_module.call("ForwardKinematic_V1", Angles=angles(90.0, 90.0, 90.0), Geometry=GEO)
    assert got["X"] == pytest.approx(0.0, abs=1e-3)
    assert got["Y"] == pytest.approx(20.0 + 130.0, abs=1e-3)
    assert got["Z"] == pytest.approx(100.0 + 120.0, abs=1e-3)


def test_forward_kinematics_tool_outputs(st_module: Any) -> None:
    a = angles(
        30.0, 40.0, 100.0, GripperUpDown=25.0, Gripper=12.5, ElbowRotate=70.0, GripperRotate=-10.0
    )
    got = st_module.call("ForwardKinematic_V1", Angles=a, Geometry=GEO)
    pitch, eroll, groll = arm.tool_commands(30.0, 40.0, 100.0, 25.0, 70.0, -10.0)
    assert got["GripperUpDown"] == pytest.approx(pitch, abs=1e-4)
    assert got["Gripper"] == pytest.approx(12.5)
    assert got["ElbowRotate"] == pytest.approx(eroll, abs=1e-4)
    assert got["GripperRotate"] == pytest.approx(groll, abs=1e-4)


def test_forward_kinematics_non_finite_gives_zeros(st_module: Any) -> None:
    for field in ANGLE_FIELDS:
        for bad in (math.nan, math.inf, -math.inf):
            a = angles(10.0, 20.0, 30.0)
            a[field] = bad
            got = st_module.call("ForwardKinematic_V1", Angles=a, Geometry=GEO)
            assert all(v == 0.0 for v in got.values()), (field, bad, got)


# --------------------------------------------------------------------------- inverse


@pytest.mark.parametrize("elbow_up", [True, False], ids=["elbow_up", "elbow_down"])
def test_round_trip_fk_of_ik(st_module: Any, elbow_up: bool) -> None:
    rng = np.random.default_rng(100 + int(elbow_up))
    targets = random_reachable_targets(rng, ROUND_TRIP_POINTS)
    tools = rng.uniform(-170.0, 170.0, (len(targets), 4))
    worst_mm = worst_tool = worst_vs_oracle = 0.0
    worst_at: tuple[float, ...] = ()
    for (x, y, z), (pitch, grip, eroll, groll) in zip(targets, tools, strict=True):
        target = coords(
            float(x),
            float(y),
            float(z),
            GripperUpDown=float(pitch),
            Gripper=float(grip),
            ElbowRotate=float(eroll),
            GripperRotate=float(groll),
        )
        assert st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=GEO) == NO_ERROR
        sol = st_module.call("InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=elbow_up)
        assert all_finite(sol)
        if elbow_up:
            assert -1e-3 <= sol["Elbow"] <= 180.0 + 1e-3
        else:
            assert 180.0 - 1e-3 <= sol["Elbow"] <= 360.0 + 1e-3
        back = st_module.call("ForwardKinematic_V1", Angles=sol, Geometry=GEO)
        err = math.dist((back["X"], back["Y"], back["Z"]), (f32(x), f32(y), f32(z)))
        if err > worst_mm:
            worst_mm, worst_at = err, (float(x), float(y), float(z))
        for name in ("GripperUpDown", "ElbowRotate", "GripperRotate"):
            worst_tool = max(worst_tool, angle_diff(back[name], target[name]))
        assert back["Gripper"] == pytest.approx(target["Gripper"], abs=1e-4)
        # The joint angles themselves against the float64 two-acos oracle (document 002),
        # away from the shells where that oracle is itself ill-conditioned.
        if arm.is_reachable(float(x), float(y), float(z), GEOMETRY, margin=1.0):
            ref = arm.inverse(float(x), float(y), float(z), GEOMETRY, elbow_up=elbow_up)
            got = (sol["Base"], sol["Shoulder"], sol["Elbow"])
            worst_vs_oracle = max(
                worst_vs_oracle, *(angle_diff(g, r) for g, r in zip(got, ref, strict=True))
            )
    label = "elbow up" if elbow_up else "elbow down"
    print(
        f"\nFK(IK(p)) {label}: worst {worst_mm:.4e} mm at {worst_at} over {len(targets)} points;"
        f" tool angles worst {worst_tool:.2e} deg; IK vs float64 oracle worst"
        f" {worst_vs_oracle:.2e} deg"
    )
    assert worst_mm <= ROUND_TRIP_TOL_MM
    assert worst_tool <= 1e-3
    assert worst_vs_oracle <= 0.01


def test_round_trip_from_random_angles_incl_reaching_over_the_axis(st_module: Any) -> None:
    """Every pose the arm can take (off the base axis) must be solvable, also those whose
    tool point lies behind the base axis (only the back solution, Base + 180, reaches)."""
    rng = np.random.default_rng(8)
    q = np.column_stack(
        [
            rng.uniform(-180.0, 180.0, 4000),
            rng.uniform(-180.0, 180.0, 4000),
            rng.uniform(0.0, 360.0, 4000),
        ]
    )
    # Poses with the tool within 40 mm of the base axis, where the front side often can't reach.
    near_axis = []
    for shoulder in np.arange(-90.0, 91.0, 2.5):
        for elbow in np.arange(2.5, 360.0, 2.5):
            p = arm.forward(0.0, float(shoulder), float(elbow))
            if 0.5 < math.hypot(p[0], p[1]) < 40.0:
                near_axis.append((float(rng.uniform(-180.0, 180.0)), float(shoulder), float(elbow)))
    q = np.concatenate([q, np.array(near_axis)])
    targets = arm.forward_batch(q, GEOMETRY)
    worst = 0.0
    back_used = 0
    for (b, _s, e), (x, y, z) in zip(q, targets, strict=True):
        target = coords(float(x), float(y), float(z))
        if math.hypot(x, y) < 0.05:
            continue
        code = st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=GEO)
        assert code == NO_ERROR, (b, _s, e, target)
        sol = st_module.call(
            "InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=bool(e < 180.0)
        )
        back_used += angle_diff(sol["Base"], math.degrees(math.atan2(y, x))) > 90.0
        got = st_module.call("ForwardKinematic_V1", Angles=sol, Geometry=GEO)
        worst = max(worst, math.dist((got["X"], got["Y"], got["Z"]), (x, y, z)))
    print(
        f"\nFK(IK(FK(q))) from {len(q)} random/near-axis poses: worst {worst:.4e} mm;"
        f" {back_used} solved over the back"
    )
    assert back_used > 0
    assert worst <= ROUND_TRIP_TOL_MM


def test_ik_tool_outputs_follow_document_002(st_module: Any) -> None:
    p = arm.forward(-40.0, 35.0, 110.0)
    target = coords(
        *map(float, p), GripperUpDown=10.0, Gripper=33.0, ElbowRotate=5.0, GripperRotate=-15.0
    )
    sol = st_module.call("InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=True)
    assert sol["Base"] == pytest.approx(-40.0, abs=1e-3)
    assert sol["Shoulder"] == pytest.approx(35.0, abs=1e-3)
    assert sol["Elbow"] == pytest.approx(110.0, abs=1e-3)
    # GripperUpDown = 180 - (Elbow + Shoulder) + cmd; rotations = 90 - Base + cmd.
    assert sol["GripperUpDown"] == pytest.approx(180.0 - 145.0 + 10.0, abs=1e-3)
    assert sol["Gripper"] == pytest.approx(33.0)
    assert sol["ElbowRotate"] == pytest.approx(90.0 + 40.0 + 5.0, abs=1e-3)
    assert sol["GripperRotate"] == pytest.approx(90.0 + 40.0 - 15.0, abs=1e-3)


BAD_TARGETS = [
    ("far", coords(400.0, 0.0, 100.0), UNREACHABLE),
    ("just beyond full stretch", coords(270.1, 0.0, 100.0), UNREACHABLE),
    ("huge", coords(1.0e20, -1.0e20, 1.0e20), UNREACHABLE),
    ("below the floor, far", coords(0.0, 300.0, -500.0), UNREACHABLE),
    ("on the base axis", coords(0.0, 0.0, 200.0), SINGULAR),
    ("on the base axis, tiny offset", coords(1.0e-3, -1.0e-3, 150.0), SINGULAR),
    ("NaN X", coords(math.nan, 100.0, 100.0), NOT_FINITE),
    ("+Inf Y", coords(100.0, math.inf, 100.0), NOT_FINITE),
    ("-Inf Z", coords(100.0, 100.0, -math.inf), NOT_FINITE),
    ("NaN tool", coords(150.0, 0.0, 150.0, GripperUpDown=math.nan), NOT_FINITE),
    ("Inf roll", coords(150.0, 0.0, 150.0, GripperRotate=-math.inf), NOT_FINITE),
    ("1e31 gripper", coords(150.0, 0.0, 150.0, Gripper=1.0e31), NOT_FINITE),
]


@pytest.mark.parametrize(("name", "target", "code"), BAD_TARGETS, ids=[b[0] for b in BAD_TARGETS])
def test_ik_bad_targets_function(
    st_module: Any, name: str, target: dict[str, float], code: int
) -> None:
    assert st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=GEO) == code
    for elbow_up in (True, False):
        sol = st_module.call("InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=elbow_up)
        assert all(v == 0.0 for v in sol.values()), sol


def _fb_inputs(target: dict[str, float]) -> dict[str, Any]:
    return {name: target[name] for name in COORD_FIELDS}


@pytest.mark.parametrize(("name", "target", "code"), BAD_TARGETS, ids=[b[0] for b in BAD_TARGETS])
def test_ik_block_keeps_last_valid_angles(
    st_module: Any, name: str, target: dict[str, float], code: int
) -> None:
    fb = st_module.new_fb("ArmKinematics")
    good = coords(*map(float, arm.forward(25.0, 30.0, 120.0)), GripperUpDown=5.0)
    fb(Enable=True, ElbowUp=True, Geometry=GEO, **_fb_inputs(good))
    assert fb.Valid and not fb.Error and fb.ErrorId == NO_ERROR and fb.Reachable
    held = fb.get("Angles")
    assert held["Base"] == pytest.approx(25.0, abs=1e-3)
    for _ in range(3):  # several scans on the bad target
        fb(Enable=True, **_fb_inputs(target))
        assert fb.Error and not fb.Valid
        assert fb.ErrorId == code
        assert fb.Reachable == (code == SINGULAR)
        now = fb.get("Angles")
        assert now == held
        assert all_finite(now)
    # Recovers on the next good target.
    fb(Enable=True, **_fb_inputs(good))
    assert fb.Valid and not fb.Error and fb.ErrorId == NO_ERROR


def test_ik_block_bad_geometry(st_module: Any) -> None:
    fb = st_module.new_fb("ArmKinematics")
    good = coords(*map(float, arm.forward(0.0, 45.0, 90.0)))
    fb(Enable=True, ElbowUp=True, Geometry=GEO, **_fb_inputs(good))
    held = fb.get("Angles")
    for geo in (
        dict(GEO, A3=0.0),
        dict(GEO, A4=-5.0),
        dict(GEO, A1=math.nan),
        dict(GEO, A2=math.inf),
    ):
        fb(Enable=True, Geometry=geo, **_fb_inputs(good))
        assert fb.Error and fb.ErrorId == BAD_GEOMETRY and not fb.Reachable
        assert fb.get("Angles") == held
        assert st_module.call("ArmGeometryCheck", geo) == BAD_GEOMETRY
    assert st_module.call("ArmGeometryCheck", GEO) == NO_ERROR


def test_ik_block_elbow_choice_and_enable(st_module: Any) -> None:
    fb = st_module.new_fb("ArmKinematics")
    p = arm.forward(10.0, 50.0, 80.0)
    target = coords(*map(float, p))
    fb(Enable=True, ElbowUp=True, Geometry=GEO, **_fb_inputs(target))
    up = fb.get("Angles")
    assert up["Elbow"] == pytest.approx(80.0, abs=1e-3)
    fb(Enable=True, ElbowUp=False, **_fb_inputs(target))
    down = fb.get("Angles")
    ref = arm.inverse(*map(float, p), elbow_up=False)
    assert down["Shoulder"] == pytest.approx(ref[1], abs=1e-3)
    assert down["Elbow"] == pytest.approx(ref[2], abs=1e-3)
    assert down["Elbow"] == pytest.approx(360.0 - 80.0, abs=1e-3)
    # Disabled: nothing solved, status cleared, angles held.
    fb(Enable=False, X=400.0)
    assert not fb.Valid and not fb.Error and fb.ErrorId == NO_ERROR and not fb.Reachable
    assert fb.get("Angles") == down


def test_ik_block_before_first_solution_outputs_zero(st_module: Any) -> None:
    fb = st_module.new_fb("ArmKinematics")
    fb(Enable=True, Geometry=GEO, X=math.nan, Y=0.0, Z=0.0)
    assert fb.Error and fb.ErrorId == NOT_FINITE
    assert all(v == 0.0 for v in fb.get("Angles").values())


def test_reachable_shell_edges(st_module: Any) -> None:
    low, high = arm.reach_limits(GEOMETRY)
    # Exactly at full stretch and within the 1e-3 mm tolerance: solvable.
    for cp in (high, high + 0.5e-3, low + 1e-4):
        target = coords(GEOMETRY.a2 + cp, 0.0, GEOMETRY.a1)
        assert st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=GEO) == NO_ERROR
        sol = st_module.call("InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=True)
        back = st_module.call("ForwardKinematic_V1", Angles=sol, Geometry=GEO)
        assert math.dist((back["X"], back["Y"], back["Z"]), (target["X"], 0.0, target["Z"])) < 0.01
    # Beyond the tolerance: unreachable. Outside the outer shell:
    target = coords(GEOMETRY.a2 + high + 0.01, 0.0, GEOMETRY.a1)
    assert st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=GEO) == UNREACHABLE
    # Inside the inner shell on both sides of the base axis: with the default a2 = 20 mm the
    # back solution reaches every point near the axis, so take an arm without the offset.
    geo0 = dict(GEO, A2=0.0)
    for cp, code in ((low - 0.01, UNREACHABLE), (low - 5.0, UNREACHABLE), (low + 1e-4, NO_ERROR)):
        target = coords(cp, 0.0, GEOMETRY.a1)
        assert st_module.call("InverseKinematikCheck_V1", Target=target, Geometry=geo0) == code
    fb = st_module.new_fb("ArmKinematics")
    fb(Enable=True, Geometry=geo0, X=100.0, Y=0.0, Z=150.0)
    held = fb.get("Angles")
    assert fb.Valid
    fb(Enable=True, X=low - 5.0, Y=0.0, Z=GEOMETRY.a1)
    assert fb.Error and fb.ErrorId == UNREACHABLE and not fb.Reachable
    assert fb.get("Angles") == held
