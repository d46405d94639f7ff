"""Property tests of st/KinematicsFixed.st and its tables over their whole input range.

Every integer input is drawn from its full type (DINT, LINT, INT), with the extremes (min,
max, 0, +/-1) and the documented range limits drawn often. For every public POU the property
is: either the documented error code (or the documented out-of-range result of a helper
without one), or an answer within the documented tolerance of an independent reference:
exact integer arithmetic in Python (math.isqrt, Fraction-free floor/round), math.sin/atan2
in float64, and a float64 closed-form IK/FK of the arm (document 002) at the same integer
target.

Documented tolerances (KinematicsFixed.st headers): RsqrtFixed 2.0E-6 relative, SqrtNormFixed
+/-1 of the mantissa, SqrtProductFixed 1 + 2.5E-6 sqrt(A B), sine 1.1E-5 of full scale,
Atan2Fixed 3.3E-4 deg, IK angles 5.5E-3 deg (0.01 deg goal), FK 1.1E-5 x (|a2| + 2 (a3 + a4))
plus the rounding to 0.01 mm.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

NO_ERROR, UNREACHABLE, SINGULAR, BAD_GEOMETRY = 0, 1, 2, 4
DINT_MIN, DINT_MAX = -(2**31), 2**31 - 1
LINT_MIN, LINT_MAX = -(2**63), 2**63 - 1
INT_MIN, INT_MAX = -(2**15), 2**15 - 1
P62 = 2**62
MAX_LEN = 1_000_000  # 0.01 mm: 10 m
DEFAULT_GEO = {"A1Mm100": 10000, "A2Mm100": 2000, "A3Mm100": 12000, "A4Mm100": 13000}
IK_ANGLE_TOL_DEG = 5.5e-3
REPO = Path(__file__).resolve().parents[2]


def dint(*edges: int) -> st.SearchStrategy[int]:
    """Any DINT, with the type's extremes and the given range limits drawn often."""
    common = [DINT_MIN, DINT_MIN + 1, -1, 0, 1, DINT_MAX - 1, DINT_MAX]
    near = [e + d for e in edges for d in (-1, 0, 1)]
    return st.one_of(st.integers(DINT_MIN, DINT_MAX), st.sampled_from(common + near))


def lint(*edges: int) -> st.SearchStrategy[int]:
    common = [LINT_MIN, LINT_MIN + 1, -1, 0, 1, LINT_MAX - 1, LINT_MAX]
    near = [e + d for e in edges for d in (-1, 0, 1)]
    return st.one_of(st.integers(LINT_MIN, LINT_MAX), st.sampled_from(common + near),
                     st.integers(-(2**40), 2**40))


def round_half_away(num: int, den: int) -> int:
    q, r = divmod(abs(num), den)
    if 2 * r >= den:
        q += 1
    return q if num >= 0 else -q


def angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


# ----------------------------------------------------------------------------- helpers
@given(num=lint(), den=st.one_of(lint(), st.integers(1, 10**6), st.sampled_from([1, 2, 3])))
@example(num=LINT_MAX, den=2)
@example(num=LINT_MIN, den=2)
@example(num=LINT_MIN, den=1)
def test_div_round_lint_exact(st_module: Any, figures: Any, num: int, den: int) -> None:
    figures.case("DivRoundLint")
    got = st_module.call("DivRoundLint", Num=num, Den=den)
    assert got == (round_half_away(num, den) if den > 0 else 0), (num, den, got)


@given(x=lint(2**30, 2**31))
def test_rsqrt_fixed_any_lint(st_module: Any, figures: Any, x: int) -> None:
    figures.case("RsqrtFixed")
    fb = st_module.new_fb("RsqrtFixed")
    fb(X30=x)
    clamped = min(max(x, 2**30), 2**31 - 1)
    rel = abs(fb.Y30 / 2**30 * math.sqrt(clamped / 2**30) - 1.0)
    figures.error("RsqrtFixed", rel, "rel")
    assert rel <= 2.0e-6


@given(v=lint(P62, 2**60, 2**30))
@example(v=P62 - 1)
@example(v=P62)
def test_sqrt_norm_fixed_any_lint(st_module: Any, figures: Any, v: int) -> None:
    figures.case("SqrtNormFixed")
    fb = st_module.new_fb("SqrtNormFixed")
    fb(Value=v)
    if not 1 <= v < P62:
        assert fb.Root == 0 and fb.Shift == 0
        return
    assert 0 <= fb.Shift <= 30 and 2**30 <= fb.Root <= 2**31
    exact = math.isqrt(v * 4**fb.Shift)  # floor of the mantissa
    assert exact - 1 <= fb.Root <= exact + 2, (v, fb.Root, exact)
    figures.error("SqrtNormFixed", float(abs(fb.Root - exact)), "mantissa units")


@given(v=lint(P62, 2**31))
def test_isqrt_fixed_exact(st_module: Any, figures: Any, v: int) -> None:
    figures.case("IsqrtFixed")
    fb = st_module.new_fb("IsqrtFixed")
    fb(Value=v)
    assert fb.Root == (math.isqrt(v) if v > 0 else 0)


@given(a=lint(P62, 2**30), b=lint(P62, 2**30))
def test_sqrt_product_fixed(st_module: Any, figures: Any, a: int, b: int) -> None:
    figures.case("SqrtProductFixed")
    fb = st_module.new_fb("SqrtProductFixed")
    fb(A=a, B=b)
    if not (1 <= a < P62 and 1 <= b < P62):
        assert fb.Root == 0
        return
    exact = math.sqrt(a) * math.sqrt(b)
    err = abs(fb.Root - exact)
    figures.error("SqrtProductFixed", err / (1.0 + exact), "rel (1 + sqrt(AB))")
    assert err <= 1.0 + 2.5e-6 * exact, (a, b, fb.Root, exact)


@given(angle=dint(10**9, -(10**9)))
@example(angle=DINT_MAX)
@example(angle=DINT_MIN)
def test_deg10k_to_deg100_exact(st_module: Any, figures: Any, angle: int) -> None:
    figures.case("Deg10kToDeg100")
    assert st_module.call("Deg10kToDeg100", Angle=angle) == round_half_away(angle, 100)


@given(angle=dint(0, 9000))
def test_quarter_sine_fixed(st_module: Any, figures: Any, angle: int) -> None:
    figures.case("QuarterSineFixed")
    fb = st_module.new_fb("QuarterSineFixed")
    fb(AngleDeg100=angle)
    want = math.sin(math.radians(min(max(angle, 0), 9000) / 100.0)) * 2**18
    err = abs(fb.SinQ18 - want) / 2**18
    figures.error("QuarterSineFixed", err, "of full scale")
    assert err <= 1.1e-5 and 0 <= fb.SinQ18 <= 2**18


@given(angle=dint(36000, -36000, 9000, 18000, 27000))
def test_sin_cos_fixed_any_dint(st_module: Any, figures: Any, angle: int) -> None:
    figures.case("SinCosFixed")
    fb = st_module.new_fb("SinCosFixed")
    fb(AngleDeg100=angle)
    t = math.radians((angle % 36000) / 100.0)  # Python's % is exact for any integer
    err = max(abs(fb.SinQ18 - math.sin(t) * 2**18), abs(fb.CosQ18 - math.cos(t) * 2**18)) / 2**18
    figures.error("SinCosFixed", err, "of full scale")
    assert err <= 1.1e-5, (angle, fb.SinQ18, fb.CosQ18)


@given(y=lint(P62, -P62), x=lint(P62, -P62))
@example(y=LINT_MIN, x=LINT_MIN)
@example(y=0, x=LINT_MIN)
@example(y=LINT_MAX, x=LINT_MIN)
@example(y=-1, x=LINT_MIN)
def test_atan2_fixed_any_lint(st_module: Any, figures: Any, y: int, x: int) -> None:
    figures.case("Atan2Fixed")
    fb = st_module.new_fb("Atan2Fixed")
    fb(Y=y, X=x)
    got = fb.AngleDeg10k
    assert -1_800_000 < got <= 1_800_000, (y, x, got)
    if x == 0 and y == 0:
        assert got == 0
        return
    want = math.degrees(math.atan2(float(y), float(x)))
    err = angle_diff(got / 1e4, want)
    figures.error("Atan2Fixed", err, "deg")
    assert err <= 3.3e-4, (y, x, got, want)


@given(index=st.one_of(st.integers(INT_MIN, INT_MAX),
                       st.sampled_from([INT_MIN, -1, 0, 1, 254, 255, 256, INT_MAX])))
def test_tables_any_int_index(st_module: Any, figures: Any, index: int) -> None:
    """Each table block returns entries Index and Index + 1 of its definition (the residual
    of the function over its chord, formulas of KinematicsFixed.st's header), Index clamped
    to 0..255."""
    row = min(max(index, 0), 255)
    definitions = {
        "SinTableFixed": lambda i: round(math.sin(i * math.pi / 512) * 2**18 - i * 1024),
        "AtanTableFixed": lambda i: round(math.degrees(math.atan(i / 256)) * 1e4
                                          - i * 450000 / 256),
        "RsqrtTableFixed": lambda i: round(2**20 - i * 307121 / 256
                                           - 2**20 / math.sqrt(1 + i / 256)),
    }
    for name, entry in definitions.items():
        figures.case(name)
        fb = st_module.new_fb(name)
        fb(Index=index)
        assert (fb.Lower, fb.Upper) == (entry(row), entry(row + 1)), (name, index)


# ----------------------------------------------------------------------------- FK
def geometry_ok(g: dict[str, int]) -> bool:
    return (1 <= g["A3Mm100"] <= MAX_LEN and 1 <= g["A4Mm100"] <= MAX_LEN
            and abs(g["A1Mm100"]) <= MAX_LEN and abs(g["A2Mm100"]) <= MAX_LEN)


@st.composite
def geometries(draw: st.DrawFn) -> dict[str, int]:
    kind = draw(st.integers(0, 9))
    if kind <= 4:
        return dict(DEFAULT_GEO)
    if kind <= 7:
        return {"A1Mm100": draw(st.integers(-MAX_LEN, MAX_LEN)),
                "A2Mm100": draw(st.integers(-MAX_LEN, MAX_LEN)),
                "A3Mm100": draw(st.integers(1, MAX_LEN)),
                "A4Mm100": draw(st.integers(1, MAX_LEN))}
    edges = (MAX_LEN, -MAX_LEN, 1, 0)
    return {name: draw(dint(*edges)) for name in DEFAULT_GEO}


def fk64(base: float, shoulder: float, elbow: float, g: dict[str, int]) -> tuple[float, ...]:
    """Document 002's closed form in float64, lengths in 0.01 mm, angles in deg."""
    t1, t2 = math.radians(base), math.radians(shoulder)
    t23 = t2 + math.radians(elbow - 180.0)
    r = g["A2Mm100"] + g["A3Mm100"] * math.cos(t2) + g["A4Mm100"] * math.cos(t23)
    return (r * math.cos(t1), r * math.sin(t1),
            g["A1Mm100"] + g["A3Mm100"] * math.sin(t2) + g["A4Mm100"] * math.sin(t23))


@given(base=dint(36000, 18000), shoulder=dint(36000, 18000), elbow=dint(36000, 18000),
       g=geometries())
@example(base=0, shoulder=2_147_483_000, elbow=2_147_483_000, g=DEFAULT_GEO)
@example(base=DINT_MIN, shoulder=DINT_MAX, elbow=DINT_MAX, g=DEFAULT_GEO)
@example(base=0, shoulder=0, elbow=18000, g={**DEFAULT_GEO, "A1Mm100": DINT_MIN})
def test_forward_kinematic_fixed(
    st_module: Any, figures: Any, base: int, shoulder: int, elbow: int, g: dict[str, int]
) -> None:
    figures.case("ForwardKinematicFixed")
    fb = st_module.new_fb("ForwardKinematicFixed")
    fb(Angles={"BaseDeg100": base, "ShoulderDeg100": shoulder, "ElbowDeg100": elbow},
       Geometry=g)
    if not geometry_ok(g):
        assert fb.Error and fb.ErrorId == BAD_GEOMETRY
        return
    assert not fb.Error and fb.ErrorId == NO_ERROR
    want = fk64((base % 36000) / 100.0, (shoulder % 36000) / 100.0, (elbow % 36000) / 100.0, g)
    tol = 1.1e-5 * (abs(g["A2Mm100"]) + 2 * (g["A3Mm100"] + g["A4Mm100"])) + 0.5 + 1e-6
    err = max(abs(fb.XMm100 - want[0]), abs(fb.YMm100 - want[1]), abs(fb.ZMm100 - want[2]))
    figures.error("ForwardKinematicFixed", err / 100.0, "mm")
    assert err <= tol, (base, shoulder, elbow, g, (fb.XMm100, fb.YMm100, fb.ZMm100), want)


# ----------------------------------------------------------------------------- IK
def ik64(x: int, y: int, z: int, g: dict[str, int], up: bool) -> tuple[float, float, float]:
    """Document 002's geometric IK in float64 (deg), reaching over the axis when only the
    back side reaches, as the header documents."""
    a1, a2, a3, a4 = (float(g[k]) for k in ("A1Mm100", "A2Mm100", "A3Mm100", "A4Mm100"))
    radial = math.hypot(x, y)
    zp = z - a1
    base = math.degrees(math.atan2(y, x))
    xp = radial - a2
    cp = math.hypot(xp, zp)
    if not abs(a3 - a4) - 0.1 <= cp <= a3 + a4 + 0.1:
        base = base + 180.0 if base <= 0.0 else base - 180.0
        xp = -radial - a2
        cp = math.hypot(xp, zp)
    cos_alpha = max(-1.0, min(1.0, (a3 * a3 + cp * cp - a4 * a4) / (2.0 * a3 * cp)))
    cos_beta = max(-1.0, min(1.0, (a3 * a3 + a4 * a4 - cp * cp) / (2.0 * a3 * a4)))
    alpha = math.degrees(math.acos(cos_alpha))
    beta = math.degrees(math.acos(cos_beta))
    direction = math.degrees(math.atan2(zp, xp))
    shoulder = direction + alpha if up else direction - alpha
    return base, (shoulder + 180.0) % 360.0 - 180.0, beta if up else 360.0 - beta


def cp_error(cp: float, a2: int) -> float:
    """Documented error of the distance Cp (0.01 mm): D = Cp^2 is exact but for the term
    2 a2 Radial, off by up to 2 |a2| / 1024 (0.01 mm)^2 (Radial's last bit)."""
    d_err = 2.0 * abs(a2) / 1024.0 + 0.01
    return min(d_err / (2.0 * cp), math.sqrt(d_err)) if cp > 0.0 else math.sqrt(d_err)


def reach_state(x: int, y: int, z: int, g: dict[str, int]) -> tuple[set[int], float]:
    """Possible codes by the documented rules (1 um reach tolerance = 0.1 unit), both where
    the target lies within 0.02 unit plus the documented error of Cp of a threshold; and the
    margin to the nearest shell."""
    a1, a2, a3, a4 = (g[k] for k in ("A1Mm100", "A2Mm100", "A3Mm100", "A4Mm100"))
    radial = math.hypot(x, y)
    lo, hi = abs(a3 - a4) - 0.1, a3 + a4 + 0.1
    cps = [math.hypot(s * radial - a2, z - a1) for s in (1.0, -1.0)]

    def ok(cp: float) -> set[bool]:
        fuzz = 0.02 + cp_error(cp, a2)
        inside, outside = lo + fuzz < cp < hi - fuzz, cp < lo - fuzz or cp > hi + fuzz
        return {True} if inside else {False} if outside else {True, False}

    codes: set[int] = set()
    for front in ok(cps[0]):
        for back in ok(cps[1]):
            cp = cps[0] if front else cps[1]
            if not (front or back):
                codes.add(UNREACHABLE)
            elif x == 0 and y == 0:
                codes.add(SINGULAR)
            elif cp * cp * 1024 < 10 - 0.5 or (a3 == a4 and cp < 0.2 + cp_error(cp, a2)):
                codes |= {SINGULAR} | ({NO_ERROR} if cp * cp * 1024 > 9 else set())
            else:
                codes.add(NO_ERROR)
    margin = min(min(abs(cp - lo), abs(cp - hi)) for cp in cps)
    return codes, margin


@st.composite
def ik_targets(draw: st.DrawFn) -> tuple[int, int, int, dict[str, int], bool]:
    g = draw(geometries())
    kind = draw(st.integers(0, 9))
    if kind <= 6 and geometry_ok(g):
        base = draw(st.floats(-180.0, 180.0))
        shoulder = draw(st.floats(-180.0, 180.0))
        elbow = draw(st.one_of(st.floats(0.0, 360.0), st.sampled_from([0.0, 180.0, 360.0])))
        p = fk64(base, shoulder, elbow, g)
        x, y, z = (max(DINT_MIN, min(DINT_MAX, round(v))) for v in p)
        if kind == 0:  # near the base axis
            x, y = draw(st.integers(-3, 3)), draw(st.integers(-3, 3))
    else:
        edges = (MAX_LEN, -MAX_LEN, 0)
        x, y, z = draw(dint(*edges)), draw(dint(*edges)), draw(dint(*edges))
    return x, y, z, g, draw(st.booleans())


@examples(1000)
@given(case=ik_targets())
@example(case=(-2016, 2775, 0, {"A1Mm100": 0, "A2Mm100": 3430, "A3Mm100": 1, "A4Mm100": 1},
               False))  # at the shoulder, a3 = a4: Singular (DistF rounds below 0)
@example(case=(383660, 147273, 9, {"A1Mm100": 0, "A2Mm100": 410939, "A3Mm100": 339,
                                    "A4Mm100": 320}, False))  # |a2| >> the arm: D's error
@example(case=(-8705, -456, -11, {"A1Mm100": 0, "A2Mm100": -8757, "A3Mm100": 140,
                                  "A4Mm100": 101}, False))  # near the inner shell, big a2
@example(case=(DINT_MIN, 100, 10000, DEFAULT_GEO, True))
@example(case=(100, DINT_MIN, 10000, DEFAULT_GEO, True))
@example(case=(15000, 0, DINT_MIN, DEFAULT_GEO, False))
@example(case=(15000, 0, 10000, {**DEFAULT_GEO, "A1Mm100": DINT_MIN}, True))
@example(case=(15000, 0, 10000, {**DEFAULT_GEO, "A2Mm100": DINT_MIN}, True))
@example(case=(MAX_LEN, MAX_LEN, MAX_LEN, {"A1Mm100": -MAX_LEN, "A2Mm100": -MAX_LEN,
                                           "A3Mm100": MAX_LEN, "A4Mm100": MAX_LEN}, True))
def test_inverse_kinematik_fixed(
    st_module: Any, figures: Any, case: tuple[int, int, int, dict[str, int], bool]
) -> None:
    x, y, z, g, up = case
    figures.case("InverseKinematikFixed")
    fb = st_module.new_fb("InverseKinematikFixed")
    fb(XMm100=x, YMm100=y, ZMm100=z, ElbowUp=up, Geometry=g)
    if not geometry_ok(g):
        assert not fb.Valid and fb.ErrorId == BAD_GEOMETRY
        return
    if max(abs(x), abs(y), abs(z)) > MAX_LEN:
        assert not fb.Valid and fb.ErrorId == UNREACHABLE
        return
    codes, margin = reach_state(x, y, z, g)
    assert fb.ErrorId in codes, (case, fb.ErrorId, codes)
    assert fb.Valid == (fb.ErrorId == NO_ERROR) and fb.Error == (fb.ErrorId != NO_ERROR)
    if not fb.Valid:
        return
    got = fb.Angles
    base, shoulder, elbow = (got[k] / 100.0 for k in ("BaseDeg100", "ShoulderDeg100",
                                                       "ElbowDeg100"))
    assert -180.0 < base <= 180.0 and -180.0 < shoulder <= 180.0
    assert (0.0 <= elbow <= 180.0) if up else (180.0 <= elbow <= 360.0)
    # Position: the FK of the answer hits the target within the angle tolerance seen over
    # the arm's levers, plus the 1 um reach clamp and the documented error of Cp.
    a2, a3, a4 = g["A2Mm100"], g["A3Mm100"], g["A4Mm100"]
    reached = fk64(base, shoulder, elbow, g)
    radial = math.hypot(x, y)
    side = 1.0 if -90.0 < angle_diff(base, math.degrees(math.atan2(y, x))) < 90.0 else -1.0
    cp = math.hypot(side * radial - a2, z - g["A1Mm100"])
    lever = radial + 2.0 * (a3 + a4)
    pos_err = math.dist(reached, (x, y, z))
    pos_tol = (math.radians(IK_ANGLE_TOL_DEG) * lever + 0.1 + 1e-6 * lever
               + 2.0 * cp_error(cp, a2))
    figures.error("InverseKinematikFixed", pos_err / 100.0, "mm (FK64 of answer - target)")
    assert pos_err <= pos_tol, (case, got, pos_err, pos_tol)
    # Angles against the float64 IK, where the target is clear of the shells (there the
    # angles are ill-conditioned: d(angle) / d(distance) is unbounded at full stretch) by
    # more than the documented error of Cp; that error's effect on the reference angles
    # (moving the target by it towards and away from the shoulder) is added to the bound.
    if margin > 1.0 + cp_error(cp, a2) and radial > 1.0 and min(a3, a4) > 100:
        want = ik64(x, y, z, g, up)
        spread = 0.0
        for k in (-1.0, 1.0):
            scale = 1.0 + k * cp_error(cp, a2) / cp
            r2 = a2 + (side * radial - a2) * scale
            z2 = g["A1Mm100"] + (z - g["A1Mm100"]) * scale
            az = math.atan2(y, x)
            moved = ik64(side * r2 * math.cos(az), side * r2 * math.sin(az), z2, g, up)
            spread = max(spread, *(angle_diff(a, b) for a, b in zip(moved, want, strict=True)))
        err = max(angle_diff(a, b) for a, b in zip((base, shoulder, elbow), want, strict=True))
        figures.error("InverseKinematikFixed angles", err, "deg")
        assert err <= IK_ANGLE_TOL_DEG + spread, (case, got, want, spread)


def test_defect_fixed_ik_min_dint_is_rejected(st_module: Any) -> None:
    """Regression: XMm100 = -2,147,483,648 came back Valid (ABS of the most negative DINT
    wraps to itself and passed the range check). Same for every coordinate and length."""
    fb = st_module.new_fb("InverseKinematikFixed")
    for name in ("XMm100", "YMm100", "ZMm100"):
        target = {"XMm100": 15000, "YMm100": 100, "ZMm100": 10000, name: DINT_MIN}
        fb(ElbowUp=True, Geometry=DEFAULT_GEO, **target)
        assert not fb.Valid and fb.ErrorId == UNREACHABLE, name
    for name in DEFAULT_GEO:
        fb(XMm100=15000, YMm100=100, ZMm100=10000, ElbowUp=True,
           Geometry={**DEFAULT_GEO, name: DINT_MIN})
        assert not fb.Valid and fb.ErrorId == BAD_GEOMETRY, name
    fk = st_module.new_fb("ForwardKinematicFixed")
    for name in ("A1Mm100", "A2Mm100"):
        fk(Angles={"BaseDeg100": 0, "ShoulderDeg100": 0, "ElbowDeg100": 18000},
           Geometry={**DEFAULT_GEO, name: DINT_MIN})
        assert fk.Error and fk.ErrorId == BAD_GEOMETRY, name


def test_defect_fixed_fk_large_angles(st_module: Any) -> None:
    """Regression: the fixed FK gave wrong poses for large angles its header allows (Shoulder
    + Elbow wrapped in DINT). Now any DINT angle gives the pose of its value mod 360 deg."""
    fk = st_module.new_fb("ForwardKinematicFixed")
    for s, e in ((2_147_483_000, 2_147_483_000), (DINT_MAX, DINT_MAX), (DINT_MIN, DINT_MIN),
                 (DINT_MAX, DINT_MIN)):
        fk(Angles={"BaseDeg100": 0, "ShoulderDeg100": s, "ElbowDeg100": e}, Geometry=DEFAULT_GEO)
        want = fk64(0.0, (s % 36000) / 100.0, (e % 36000) / 100.0, DEFAULT_GEO)
        got = (fk.XMm100, fk.YMm100, fk.ZMm100)
        assert max(abs(a - b) for a, b in zip(got, want, strict=True)) <= 2.0, (s, e, got, want)
