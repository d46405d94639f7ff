"""Property tests of st/Kinematics.st and st/KinematicsDH.st over their documented input range.

For every public POU: either the documented error code (or the documented all-zero / 0.0
result of a function without one), or an answer within the documented tolerance of an
independent float64 reference: numpy closed forms of document 002 (FK: r = a2 + a3 cos t2 +
a4 cos(t2 + t3'), X = r cos t1, Y = r sin t1, Z = a1 + a3 sin t2 + a4 sin(t2 + t3')), Python's
math.atan2 / fmod, numpy matmul, and roboticstoolbox's DHRobot for the DH block. Inputs are
float32 (what the PLC holds) and include NaN, +/-Inf, 1e30 and the float32 extremes.

Documented tolerances used (from the ST headers):
- IK answers (V1, ArmKinematics, DH): FK of the answer within IK_TOL of the target,
  IK_TOL = 2.0E-3 mm + 1.0E-5 * (|A1| + |A2| + A3 + A4) (reach clamp 1.0E-3 mm + REAL
  rounding), Base and Shoulder in (-180, 180].
- tool commands |value| <= 360 deg, coordinates |value| <= 1.0E6 mm, FK angles |value| <= 1.0E6.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from float32_support import any_real as _any_real  # noqa: E402
from float32_support import f32, finite  # noqa: E402
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

from armbench.plant.arm import wrap180  # noqa: E402


def any_real() -> Any:
    """float32 values, with the coordinate limit 1.0E6 mm and its neighbours often."""
    return _any_real(extra=(1.0e6, -1.0e6, 1.0000001e6))

NO_ERROR, UNREACHABLE, SINGULAR, NOT_FINITE, BAD_GEOMETRY = 0, 1, 2, 3, 4
MAX_COORD_MM = 1.0e6
MAX_TOOL_DEG = 360.0
MAX_FK_ANGLE_DEG = 1.0e6
REACH_TOL_MM = 1.0e-3
PI32 = float(np.float32(3.14159265))
ANGLE_FIELDS = ("Base", "Shoulder", "Elbow", "GripperUpDown", "Gripper", "ElbowRotate",
                "GripperRotate")
TOOL_FIELDS = ("GripperUpDown", "Gripper", "ElbowRotate", "GripperRotate")
DEFAULT_GEO = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}










def angle_diff(a: float, b: float) -> float:
    return abs(wrap180(a - b))


def fk64(base: float, shoulder: float, elbow: float, g: dict[str, float]) -> np.ndarray:
    t1, t2 = math.radians(wrap180(base)), math.radians(wrap180(shoulder))
    t23 = t2 + math.radians(wrap180(elbow - 180.0))
    r = g["A2"] + g["A3"] * math.cos(t2) + g["A4"] * math.cos(t23)
    return np.array([r * math.cos(t1), r * math.sin(t1),
                     g["A1"] + g["A3"] * math.sin(t2) + g["A4"] * math.sin(t23)])


def ik_tol(g: dict[str, float]) -> float:
    return 2.0e-3 + 1.0e-5 * (abs(g["A1"]) + abs(g["A2"]) + g["A3"] + g["A4"])


# ----------------------------------------------------------------------------- scalar helpers
@given(x=any_real())
def test_is_finite_real(st_module: Any, figures: Any, x: float) -> None:
    figures.case("IsFiniteReal")
    assert st_module.call("IsFiniteReal", x) == finite(x)


@given(x=any_real())
def test_deg_rad_conversions(st_module: Any, figures: Any, x: float) -> None:
    figures.case("DegToRad")
    figures.case("RadToDeg")
    for name, factor in (("DegToRad", math.pi / 180.0), ("RadToDeg", 180.0 / math.pi)):
        got = st_module.call(name, x)
        want = x * factor
        if math.isnan(x):
            assert math.isnan(got)
        elif abs(want) > 3.4e38 or math.isinf(want):
            assert math.isinf(got) or abs(got) >= 3.4e38
        elif abs(want) > 1e-30:
            rel = abs(got - want) / abs(want)
            figures.error(name, rel, "rel")
            assert rel <= 2e-7, (x, got, want)


@given(x=st.one_of(st.floats(-1.2e6, 1.2e6, width=32), any_real()))
@example(x=-180.0)
@example(x=180.0)
@example(x=540.0)
@example(x=-540.0)
def test_wrap_deg180_exact(st_module: Any, figures: Any, x: float) -> None:
    figures.case("WrapDeg180")
    got = st_module.call("WrapDeg180", x)
    if not (math.isfinite(x) and abs(x) <= MAX_FK_ANGLE_DEG):
        assert got == 0.0
        return
    assert got == wrap180(x), (x, got)  # exact: the reduction loses nothing in float32
    assert -180.0 < got <= 180.0


@given(y=any_real(), x=any_real())
@example(y=-1.0e-30, x=-1.0)   # rounds to -pi in float32: must come out as +pi
@example(y=-1.0e-8, x=-100.0)
@example(y=0.0, x=-1.0)
@example(y=0.0, x=0.0)
def test_atan2_range_and_accuracy(st_module: Any, figures: Any, y: float, x: float) -> None:
    figures.case("ArcTan2")
    got = st_module.call("ArcTan2", y, x)
    if math.isnan(x) or math.isnan(y):
        assert math.isnan(got)
        return
    if math.isinf(x) and math.isinf(y):  # outside "finite values": any angle, never beyond pi
        return
    assert -PI32 < got <= PI32, (y, x, got)
    want = math.atan2(y, x) if (x, y) != (0.0, 0.0) else 0.0
    err = abs(math.remainder(got - want, 2.0 * math.pi))
    figures.error("ArcTan2", err, "rad")
    assert err <= 4e-7, (y, x, got, want)


matrices = st.lists(st.floats(-2.0**50, 2.0**50, width=32), min_size=16, max_size=16)


@given(rot=st.lists(any_real(), min_size=9, max_size=9),
       disp=st.lists(any_real(), min_size=3, max_size=3))
def test_fill_transformation_matrix(
    st_module: Any, figures: Any, rot: list[float], disp: list[float]
) -> None:
    figures.case("FillTransformationMatrix")
    r = np.array(rot, dtype=np.float64).reshape(3, 3)
    got = np.array(st_module.call("FillTransformationMatrix", r.tolist(), disp))
    want = np.eye(4)
    want[:3, :3] = r
    want[:3, 3] = disp
    np.testing.assert_array_equal(got, want)  # a copy: bit for bit, NaN included


@given(a=matrices, b=matrices)
def test_matmul4_vs_numpy(st_module: Any, figures: Any, a: list[float], b: list[float]) -> None:
    figures.case("MatMul4")
    ma = np.array(a).reshape(4, 4)
    mb = np.array(b).reshape(4, 4)
    got = np.array(st_module.call("MatMul4", ma.tolist(), mb.tolist()))
    want = ma @ mb
    bound = 4.0 * 2.0**-23 * (np.abs(ma) @ np.abs(mb)) + 1e-37
    err = np.abs(got - want) / np.maximum(np.abs(ma) @ np.abs(mb), 1e-30)
    figures.error("MatMul4", float(err.max()), "rel to sum|a||b|")
    assert (np.abs(got - want) <= bound).all()


# ----------------------------------------------------------------------------- geometry
@st.composite
def geometries(draw: st.DrawFn) -> dict[str, float]:
    kind = draw(st.integers(0, 9))
    if kind <= 5:
        return dict(DEFAULT_GEO)
    if kind <= 7:
        return {"A1": draw(st.floats(-500.0, 500.0, width=32)),
                "A2": draw(st.floats(-200.0, 200.0, width=32)),
                "A3": draw(st.floats(1.0, 1000.0, width=32)),
                "A4": draw(st.floats(1.0, 1000.0, width=32))}
    if kind == 8:  # up to the documented 1.0E6 mm, and just beyond
        big = st.one_of(st.floats(2.0**-10, 1.0e6, width=32),
                        st.sampled_from([1.0e6, f32(1.0000001e6)]))
        return {"A1": draw(big) * draw(st.sampled_from([1.0, -1.0])),
                "A2": draw(big) * draw(st.sampled_from([1.0, -1.0])),
                "A3": draw(big), "A4": draw(big)}
    return {name: draw(any_real()) for name in ("A1", "A2", "A3", "A4")}


def geometry_ok(g: dict[str, float]) -> bool:
    return (all(abs(v) <= MAX_COORD_MM for v in g.values())  # NaN fails too
            and g["A3"] > 0.0 and g["A4"] > 0.0)


@given(g=geometries())
def test_arm_geometry_check(st_module: Any, figures: Any, g: dict[str, float]) -> None:
    figures.case("ArmGeometryCheck")
    want = NO_ERROR if geometry_ok(g) else BAD_GEOMETRY
    assert st_module.call("ArmGeometryCheck", g) == want


# ----------------------------------------------------------------------------- FK
@st.composite
def joint_angles(draw: st.DrawFn) -> dict[str, float]:
    def one() -> float:
        kind = draw(st.integers(0, 9))
        if kind <= 5:
            return draw(st.floats(-400.0, 400.0, width=32))
        if kind <= 7:
            return draw(st.floats(-1.0e6, 1.0e6, width=32))
        return draw(any_real())
    return {name: one() for name in ANGLE_FIELDS}


@given(a=joint_angles(), g=geometries())
@example(a={**dict.fromkeys(ANGLE_FIELDS, 0.0), "Base": 999_990.0, "Shoulder": 45.0,
            "Elbow": 100.0}, g=DEFAULT_GEO)
@example(a={**dict.fromkeys(ANGLE_FIELDS, 0.0), "Shoulder": 900_000.0, "Elbow": 900_000.0,
            "GripperUpDown": 900_000.0}, g=DEFAULT_GEO)
def test_forward_kinematic_v1(
    st_module: Any, figures: Any, a: dict[str, float], g: dict[str, float]
) -> None:
    figures.case("ForwardKinematic_V1")
    got = st_module.call("ForwardKinematic_V1", Angles=a, Geometry=g)
    in_range = (all(finite(v) for v in (*a.values(), *g.values()))
                and all(abs(a[n]) <= MAX_FK_ANGLE_DEG for n in ANGLE_FIELDS if n != "Gripper"))
    if not in_range:
        assert all(v == 0.0 for v in got.values()), got
        return
    want = fk64(a["Base"], a["Shoulder"], a["Elbow"], g)
    scale = sum(abs(v) for v in g.values())
    err = float(np.abs(np.array([got["X"], got["Y"], got["Z"]]) - want).max())
    figures.error("ForwardKinematic_V1", err / max(scale, 1e-30), "rel to sum|A| (position)")
    assert err <= 2e-6 * scale + 1e-30, (a, g, got, want)
    pitch = wrap180(wrap180(a["GripperUpDown"]) + wrap180(a["Shoulder"]) + wrap180(a["Elbow"])
                    - 180.0)
    for name, want_deg in (
        ("GripperUpDown", pitch),
        ("ElbowRotate", wrap180(a["ElbowRotate"] + a["Base"] - 90.0)),
        ("GripperRotate", wrap180(a["GripperRotate"] + a["Base"] - 90.0)),
    ):
        assert -180.0 < got[name] <= 180.0
        assert angle_diff(got[name], want_deg) <= 2e-4, (name, got[name], want_deg)
    assert got["Gripper"] == a["Gripper"]


# ----------------------------------------------------------------------------- IK
@st.composite
def ik_cases(draw: st.DrawFn) -> tuple[dict[str, float], dict[str, float], bool]:
    """Targets from joint angles through the float64 FK (inside the shell, on it, or up to a
    few um beyond it), near the base axis, and anywhere at all; tool commands mostly within
    +/-360 deg; the default and random geometries."""
    g = draw(geometries())
    kind = draw(st.integers(0, 9))
    if kind <= 5 and geometry_ok(g):
        base = draw(st.floats(-180.0, 180.0))
        shoulder = draw(st.floats(-180.0, 180.0))
        elbow = draw(st.one_of(st.floats(0.0, 360.0), st.sampled_from([0.0, 180.0, 360.0])))
        p = fk64(base, shoulder, elbow, g)
        if kind <= 1:  # onto the shell (full stretch or folded) plus or minus a few um
            xp = math.hypot(p[0], p[1]) - g["A2"]
            zp = p[2] - g["A1"]
            cp = math.hypot(xp, zp)
            shell = draw(st.sampled_from([g["A3"] + g["A4"], abs(g["A3"] - g["A4"])]))
            if cp > 1e-6:
                k = (shell + draw(st.floats(-3e-3, 3e-3))) / cp
                radial = g["A2"] + xp * k
                az = math.atan2(p[1], p[0])
                p = np.array([radial * math.cos(az), radial * math.sin(az), g["A1"] + zp * k])
        elif kind == 2:  # near the base axis
            p[0] = draw(st.floats(-0.05, 0.05))
            p[1] = draw(st.floats(-0.05, 0.05))
        x, y, z = (f32(v) for v in p)
    else:
        x, y, z = (draw(st.one_of(st.floats(-2.0**21, 2.0**21, width=32), any_real()))
                   for _ in range(3))
    tool = {}
    for name in TOOL_FIELDS:
        choice = draw(st.integers(0, 19))  # hypothesis favours small integers: plain draws
        if choice == 19:
            tool[name] = draw(any_real())
        elif choice == 18:
            tool[name] = draw(st.sampled_from([360.0, -360.0, f32(360.00003), 2.0e6]))
        else:
            tool[name] = draw(st.floats(-360.0, 360.0, width=32))
    target = {"X": x, "Y": y, "Z": z, **tool}
    return target, g, draw(st.booleans())


def expected_codes(t: dict[str, float], g: dict[str, float]) -> set[int]:
    """InverseKinematikCheck_V1's documented rules in float64; near a threshold (float32
    rounding) both neighbouring answers are allowed."""
    if not all(finite(t[n]) for n in ("X", "Y", "Z", *TOOL_FIELDS)):
        return {NOT_FINITE}
    if not geometry_ok(g):
        return {BAD_GEOMETRY}
    if (max(abs(t["X"]), abs(t["Y"]), abs(t["Z"])) > MAX_COORD_MM
            or max(abs(t[n]) for n in TOOL_FIELDS) > MAX_TOOL_DEG):
        return {UNREACHABLE}
    radial = math.hypot(t["X"], t["Y"])
    zp = t["Z"] - g["A1"]
    lo, hi = abs(g["A3"] - g["A4"]) - REACH_TOL_MM, g["A3"] + g["A4"] + REACH_TOL_MM
    fuzz = 1e-6 * (abs(radial) + abs(zp) + abs(g["A1"]) + abs(g["A2"]) + g["A3"] + g["A4"])

    def may_be(value: float, limit: float, below: bool) -> set[bool]:
        """Possible outcomes of `value < limit` (below) or `value > limit` under rounding."""
        if abs(value - limit) <= fuzz:
            return {True, False}
        return {value < limit} if below else {value > limit}

    cps = [math.hypot(sign * radial - g["A2"], zp) for sign in (1.0, -1.0)]
    oks = [{not (a or b) for a in may_be(cp, lo, True) for b in may_be(cp, hi, False)}
           for cp in cps]
    codes: set[int] = set()
    for front_ok in oks[0]:
        for back_ok in oks[1]:
            for on_axis in may_be(radial, 1e-2, True):
                for at_front in may_be(cps[0], 1e-3, True):
                    for at_back in may_be(cps[1], 1e-3, True):
                        if not (front_ok or back_ok):
                            codes.add(UNREACHABLE)
                        elif on_axis or (front_ok and at_front) or (not front_ok and at_back):
                            codes.add(SINGULAR)
                        else:
                            codes.add(NO_ERROR)
    return codes


def check_ik_answer(
    sol: dict[str, float], t: dict[str, float], g: dict[str, float], up: bool
) -> float:
    """Assert the documented properties of a solution; return its FK residual, mm."""
    assert all(math.isfinite(v) for v in sol.values()), sol
    assert -180.0 < sol["Base"] <= 180.0, sol
    assert -180.0 < sol["Shoulder"] <= 180.0, sol
    lo, hi = (0.0, 180.0) if up else (180.0, 360.0)
    # at full stretch or folded, the elbow's REAL rounding is the position tolerance seen
    # over the shorter link (0.5 deg for a 1 mm forearm)
    slack = max(1e-3, math.degrees(ik_tol(g) / min(g["A3"], g["A4"])))
    assert lo - slack <= sol["Elbow"] <= hi + slack, sol
    reached = fk64(sol["Base"], sol["Shoulder"], sol["Elbow"], g)
    residual = float(np.linalg.norm(reached - np.array([t["X"], t["Y"], t["Z"]])))
    assert residual <= ik_tol(g), (t, g, up, sol, residual)
    tools = (
        ("GripperUpDown", 180.0 - (sol["Elbow"] + sol["Shoulder"]) + t["GripperUpDown"]),
        ("ElbowRotate", 90.0 - sol["Base"] + t["ElbowRotate"]),
        ("GripperRotate", 90.0 - sol["Base"] + t["GripperRotate"]),
    )
    for name, want in tools:
        assert -180.0 < sol[name] <= 180.0
        assert angle_diff(sol[name], want) <= 1e-3, (name, sol[name], want)
    assert sol["Gripper"] == t["Gripper"]
    return residual


@examples(800)
@given(case=ik_cases())
@example(case=({"X": -150.0, "Y": -1.0e-30, "Z": 100.0, "GripperUpDown": 0.0, "Gripper": 0.0,
                "ElbowRotate": 0.0, "GripperRotate": 0.0}, DEFAULT_GEO, True))
@example(case=({"X": 150.0, "Y": 0.0, "Z": 100.0, "GripperUpDown": 0.0, "Gripper": 0.0,
                "ElbowRotate": 2.0e6, "GripperRotate": 0.0}, DEFAULT_GEO, True))
@example(case=({"X": 506.0013732910156, "Y": 0.0, "Z": -0.0523359552025795,  # inner shell,
                "GripperUpDown": 0.0, "Gripper": 0.0, "ElbowRotate": 0.0,  # a3 >> a4: the
                "GripperRotate": 0.0}, {"A1": 0.0, "A2": 0.0, "A3": 507.0, "A4": 1.0},  # acos
               False))  # lost 0.014 mm
def test_inverse_kinematik_v1_and_check(
    st_module: Any, figures: Any, case: tuple[dict[str, float], dict[str, float], bool]
) -> None:
    t, g, up = case
    figures.case("InverseKinematikCheck_V1")
    figures.case("InverseKinematik_V1")
    code = st_module.call("InverseKinematikCheck_V1", Target=t, Geometry=g)
    assert code in expected_codes(t, g), (t, g, code)
    sol = st_module.call("InverseKinematik_V1", Target=t, Geometry=g, ElbowUp=up)
    if code != NO_ERROR:
        assert all(v == 0.0 for v in sol.values()), sol
        return
    residual = check_ik_answer(sol, t, g, up)
    figures.error("InverseKinematik_V1", residual, "mm (FK64 of answer - target)")


@examples(500)
@given(case=ik_cases())
def test_arm_kinematics_block(
    st_module: Any, figures: Any, case: tuple[dict[str, float], dict[str, float], bool]
) -> None:
    t, g, up = case
    figures.case("ArmKinematics")
    fb = st_module.new_fb("ArmKinematics")
    fb(Enable=True, X=1.0, Y=1.0, Z=100.0, ElbowUp=up, Geometry=DEFAULT_GEO)  # a valid solve
    held = dict(fb.Angles)
    fb(Enable=True, ElbowUp=up, Geometry=g, **t)
    code = st_module.call("InverseKinematikCheck_V1", Target=t, Geometry=g)
    assert fb.ErrorId == code and fb.Valid == (code == NO_ERROR) and fb.Error == (code != 0)
    if not fb.Valid:
        assert fb.Angles == held  # the last valid angles are kept
        assert fb.Reachable == (code == SINGULAR)
        return
    residual = check_ik_answer(dict(fb.Angles), t, g, up)
    figures.error("ArmKinematics", residual, "mm (FK64 of answer - target)")


@pytest.fixture(scope="module")
def dh_robot() -> Any:
    rtb = pytest.importorskip("roboticstoolbox")

    def build(g: dict[str, float]) -> Any:
        return rtb.DHRobot([
            rtb.RevoluteDH(d=g["A1"], a=g["A2"], alpha=math.pi / 2.0),
            rtb.RevoluteDH(a=g["A3"]),
            rtb.RevoluteDH(a=g["A4"], offset=-math.pi),
        ])
    return build


@examples(800)
@given(case=ik_cases())
def test_inverse_kinematik_dh_valid_means_on_target(
    st_module: Any, figures: Any, dh_robot: Any,
    case: tuple[dict[str, float], dict[str, float], bool],
) -> None:
    """Valid only when the FK of the answer (roboticstoolbox's DH model, float64) is within
    the documented tolerance of the target; the codes are the check's, or 1 Unreachable
    when the block's own residual check fails."""
    t, g, up = case
    figures.case("InverseKinematik_DH")
    fb = st_module.new_fb("InverseKinematik_DH")
    fb(Target=t, Geometry=g, ElbowUp=up)
    code = st_module.call("InverseKinematikCheck_V1", Target=t, Geometry=g)
    if code != NO_ERROR:
        assert not fb.Valid and fb.Error and fb.ErrorId == code
        return
    if not fb.Valid:
        assert fb.ErrorId == UNREACHABLE and fb.ResidualMm > ik_tol(g) * 0.999
        return
    sol = dict(fb.Angles)
    check_ik_answer(sol, t, g, up)
    pose = dh_robot(g).fkine(np.radians([sol["Base"], sol["Shoulder"], sol["Elbow"]])).t
    residual = float(np.linalg.norm(pose - np.array([t["X"], t["Y"], t["Z"]])))
    figures.error("InverseKinematik_DH", residual, "mm (rtb FK of answer - target)")
    assert residual <= ik_tol(g)
    assert fb.ResidualMm <= ik_tol(g)


# ----------------------------------------------------------------------------- defects
def test_defect_dh_valid_with_large_residual_near_the_shell(st_module: Any) -> None:
    """Regression: InverseKinematik_DH said Valid with a 35-40 mm residual for targets within
    1e-3 mm of the reach boundary. Sweep 3,000 such targets with both elbows."""
    rng = np.random.default_rng(8)
    fb = st_module.new_fb("InverseKinematik_DH")
    g = DEFAULT_GEO
    worst = 0.0
    valid = 0
    for i in range(3000):
        az, el = rng.uniform(-math.pi, math.pi, 2)
        shell = 250.0 if i % 2 == 0 else 10.0
        cp = shell + rng.uniform(-1.2e-3, 1.2e-3)
        radial = g["A2"] + cp * math.cos(el)
        t = {"X": f32(radial * math.cos(az)), "Y": f32(radial * math.sin(az)),
             "Z": f32(g["A1"] + cp * math.sin(el)), **dict.fromkeys(TOOL_FIELDS, 0.0)}
        for up in (True, False):
            fb(Target=t, Geometry=g, ElbowUp=up)
            if fb.Valid:
                valid += 1
                a = fb.Angles
                reached = fk64(a["Base"], a["Shoulder"], a["Elbow"], g)
                worst = max(worst, float(np.linalg.norm(reached - [t["X"], t["Y"], t["Z"]])))
    print(f"\nDH near the shell: {valid} valid answers of 6000, worst FK residual {worst:.3e} mm")
    assert valid > 3000 and worst <= ik_tol(g)


def test_defect_ik_base_never_minus_180(st_module: Any) -> None:
    """Regression: Base came out as -180.0 (header: (-180, 180]) for targets just below the
    -X axis, where atan2 rounds to -pi in float32."""
    fb = st_module.new_fb("InverseKinematik_DH")
    for y in (-1.0e-30, -1.0e-20, -1.0e-9, -1.0e-7):
        t = {"X": -150.0, "Y": y, "Z": 100.0, **dict.fromkeys(TOOL_FIELDS, 0.0)}
        assert -math.pi < st_module.call("ArcTan2", y, -150.0)
        sol = st_module.call("InverseKinematik_V1", Target=t, Geometry=DEFAULT_GEO, ElbowUp=True)
        assert -180.0 < sol["Base"] <= 180.0, (y, sol["Base"])
        fb(Target=t, Geometry=DEFAULT_GEO, ElbowUp=True)
        assert fb.Valid and -180.0 < fb.Angles["Base"] <= 180.0, (y, fb.Angles["Base"])


@pytest.mark.parametrize("name", ["GripperUpDown", "ElbowRotate", "GripperRotate", "Gripper"])
def test_defect_huge_tool_commands_rejected(st_module: Any, name: str) -> None:
    """Regression: tool commands of 2e6 deg were Valid and gave nonsense. The range is
    +/-360 deg; beyond it the target is rejected as 1 Unreachable."""
    for value, want in ((2.0e6, UNREACHABLE), (-361.0, UNREACHABLE), (360.0, NO_ERROR),
                        (-360.0, NO_ERROR)):
        t = {"X": 150.0, "Y": 10.0, "Z": 100.0, **dict.fromkeys(TOOL_FIELDS, 0.0), name: value}
        assert st_module.call("InverseKinematikCheck_V1", Target=t, Geometry=DEFAULT_GEO) == want
        fb = st_module.new_fb("ArmKinematics")
        fb(Enable=True, Geometry=DEFAULT_GEO, **t)
        assert fb.Valid == (want == NO_ERROR) and fb.ErrorId == want


def test_defect_fk_large_angles_give_the_reduced_pose(st_module: Any) -> None:
    """Angles up to 1e6 deg are documented for ForwardKinematic_V1: the pose must be the
    one of the angle reduced modulo 360 (DegToRad of 999,990 deg alone is 0.1 deg off)."""
    big = {**dict.fromkeys(ANGLE_FIELDS, 0.0), "Base": 999_990.0 + 0.5, "Shoulder": 45.0 + 3600.0,
           "Elbow": 100.0 - 7200.0, "GripperUpDown": 900_000.0}
    got = st_module.call("ForwardKinematic_V1", Angles=big, Geometry=DEFAULT_GEO)
    want = fk64(big["Base"], big["Shoulder"], big["Elbow"], DEFAULT_GEO)
    assert np.abs(np.array([got["X"], got["Y"], got["Z"]]) - want).max() < 1e-3
    assert angle_diff(got["GripperUpDown"], 900_000.0 + 45.0 + 100.0 - 180.0) < 1e-3
