"""st/KinematicsFixed.st (integer-only IK/FK, LUT trig) and st/KinematicsDH.st.

References are independent of the ST: Python's math module (math.isqrt, sin, atan2) and the
float64 reference kinematics armbench.plant.arm (written from document 002's transform table).
The fixed-point IK is compared with float64 at the *same* integer target (its input is integer
0.01 mm), so the figures measure the algorithm, not the input quantisation. Worst-case and
mean figures are printed: run with -s.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from armbench import lutgen
from armbench.plant import arm

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
FIXED_FILES = [ST / "KinematicsFixed.st", ST / "KinematicsFixedTables.st"]
SOURCES = [ST / "ArmAngles.st", ST / "Kinematics.st", ST / "KinematicsDH.st", *FIXED_FILES]

GEOMETRY = arm.DEFAULT_GEOMETRY
GEO = GEOMETRY.as_st()
GEO_FIXED = {"A1Mm100": 10000, "A2Mm100": 2000, "A3Mm100": 12000, "A4Mm100": 13000}
NO_ERROR, UNREACHABLE, SINGULAR, BAD_GEOMETRY = 0, 1, 2, 4

IK_POINTS = 20_000
SEED_REQUIREMENT_DEG = 0.072  # document 000: one stepper step
GOAL_DEG = 0.01
TABLE_BYTES_GOAL = 2048
# MATIEC_CHECK names a check script: `$MATIEC_CHECK FILE.st` exits 0 iff OpenPLC builds FILE.st.
MATIEC_CHECK = Path(os.environ.get("MATIEC_CHECK", "/nonexistent/check-st.sh"))


@pytest.fixture(scope="module")
def mod() -> Any:
    compiler = pytest.importorskip("armbench.compiler")
    return compiler.compile_files(SOURCES)


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + 180.0) % 360.0 - 180.0)


# ------------------------------------------------------------------ integer only, tables
def _code_tokens(path: Path) -> list[str]:
    text = re.sub(r"\(\*.*?\*\)", " ", path.read_text(encoding="utf-8"), flags=re.S)
    return re.findall(r"[A-Za-z_][A-Za-z0-9_]*|\d+\.\d+|\d+[eE]", text)


# KinematicsChainFixed.st (document 003's integer resolved-rate step) is held to the same
# rule; it is not in FIXED_FILES, whose sources this module compiles
@pytest.mark.parametrize("path", [*FIXED_FILES, ST / "KinematicsChainFixed.st"],
                         ids=lambda p: p.name)
def test_no_floating_point_tokens(path: Path) -> None:
    tokens = _code_tokens(path)
    float_functions = {"SQRT", "LN", "LOG", "EXP", "EXPT", "SIN", "COS", "TAN", "ASIN", "ACOS",
                       "ATAN", "TRUNC"}
    floats = [t for t in tokens
              if re.fullmatch(r"L?REAL|\w+_TO_L?REAL|L?REAL_TO_\w+|\d+\.\d+|\d+[eE]", t.upper())
              or t.upper() in float_functions]
    assert not floats, f"{path.name} uses floating point: {sorted(set(floats))}"


def test_no_floating_point_types_in_checked_program() -> None:
    from armbench.compiler.driver import analyse
    from armbench.compiler.types import ArrayType, ElemType, LiteralType, PouType, StructType

    prog, diags = analyse([ST / "ArmAngles.st", *FIXED_FILES])
    assert prog is not None, diags
    mine = {str(p) for p in FIXED_FILES} | {p.name for p in FIXED_FILES}

    def in_my_files(node: Any) -> bool:
        file = str(node.pos.file)
        return file in mine or Path(file).name in mine

    def real_parts(t: Any, seen: set[int]) -> list[str]:
        if id(t) in seen:
            return []
        seen.add(id(t))
        if isinstance(t, ElemType):
            return [t.name] if t.is_real else []
        if isinstance(t, LiteralType):
            return [t.name] if t.is_real else []
        if isinstance(t, ArrayType):
            return real_parts(t.element, seen)
        if isinstance(t, StructType):
            return [x for _, ft in t.fields.values() for x in real_parts(ft, seen)]
        if isinstance(t, PouType) and t.symbol is not None:
            return [x for v in t.symbol.vars.values() for x in real_parts(v.type, seen)]
        return []

    pous = [p for p in prog.pous.values() if p.node is not None and in_my_files(p.node)]
    assert len(pous) >= 8, [p.name for p in pous]
    bad = []
    for pou in pous:
        if pou.return_type is not None and real_parts(pou.return_type, set()):
            bad.append(f"{pou.name} returns {pou.return_type}")
        for var in pou.vars.values():
            if real_parts(var.type, set()):
                bad.append(f"{pou.name}.{var.name} : {var.type}")
    bad += [f"expression at {e.pos}: {t}" for e, t in prog.expr_types.items()
            if in_my_files(e) and real_parts(t, set())]
    for name in ("ArmGeometryFixed", "ArmAnglesFixed"):
        t = prog.types.get(name.upper()) or prog.types.get(name)
        assert t is not None, name
        bad += [f"type {name}: {x}" for x in real_parts(t, set())]
    assert not bad, bad


def test_tables_regenerate_identically(tmp_path: Path) -> None:
    assert lutgen.main(["--out", str(tmp_path)]) == 0
    fresh = (tmp_path / lutgen.TABLES_FILE).read_bytes()
    assert fresh == (ST / lutgen.TABLES_FILE).read_bytes(), \
        "st/KinematicsFixedTables.st is stale: run python -m armbench.lutgen"
    assert lutgen.main(["--check"]) == 0


def test_table_bytes_within_goal() -> None:
    from armbench.compiler.driver import analyse
    from armbench.compiler.types import ArrayType

    prog, diags = analyse([ST / "KinematicsFixedTables.st"])
    assert prog is not None, diags
    arrays = [v.type for p in prog.pous.values() for v in p.vars.values()
              if isinstance(v.type, ArrayType)]
    sizes = {"UINT": 2, "INT": 2, "DINT": 4, "UDINT": 4, "SINT": 1, "USINT": 1}
    total = sum(a.size * sizes[str(a.element)] for a in arrays)
    print(f"\n  table bytes: {total} ({len(arrays)} tables; seed: 31,106)")
    assert total == lutgen.table_bytes() == 1542
    assert total <= TABLE_BYTES_GOAL


def test_tables_match_their_definition() -> None:
    sin_t, atan_t, rsqrt_t = lutgen.tables()
    for i, v in enumerate(sin_t.entries):
        assert v == round(math.sin(i * math.pi / 512) * 2**18 - i * 1024)
    for i, v in enumerate(atan_t.entries):
        assert v == round(math.degrees(math.atan(i / 256)) * 1e4 - i * 450000 / 256)
    assert 2**20 - round(2**20 / math.sqrt(2)) == 307121
    for i, v in enumerate(rsqrt_t.entries):
        assert v == round(2**20 - i * 307121 / 256 - 2**20 / math.sqrt(1 + i / 256))
    assert sin_t.entries[0] == sin_t.entries[-1] == atan_t.entries[0] == atan_t.entries[-1] == 0
    assert rsqrt_t.entries[0] == rsqrt_t.entries[-1] == 0


# ------------------------------------------------------------------ building blocks
def test_isqrt_is_exact_floor(mod: Any) -> None:
    isqrt = mod.new_fb("IsqrtFixed")
    rng = np.random.default_rng(61131)
    values = [0, 1, 2, 3, 4, 15, 16, 17, 2**62, 2**63 - 1, (2**31 - 1) ** 2, (2**31 - 1) ** 2 - 1]
    values += [int(v) for v in rng.integers(0, 2**63 - 1, 2000, dtype=np.int64)]
    values += [int(v) for v in rng.integers(0, 2**20, 1000, dtype=np.int64)]
    values += [int(r) ** 2 + d for r in rng.integers(1, 3 * 10**9, 500) for d in (-1, 0, 1)]
    values += [r * r + d for r in range(1, 200) for d in (-1, 0, 1)]
    for v in values:
        isqrt(Value=v)
        assert isqrt.Root == math.isqrt(v), v
    isqrt(Value=-5)
    assert isqrt.Root == 0


def test_rsqrt_seed_and_square_root_mantissa(mod: Any) -> None:
    seed = mod.new_fb("RsqrtFixed")
    worst = 0.0
    for x30 in range(2**30, 2**31 + 1, 2**30 // 4099):
        seed(X30=x30)
        worst = max(worst, abs(seed.Y30 / 2**30 * math.sqrt(x30 / 2**30) - 1.0))
    print(f"\n  RsqrtFixed max relative error {worst:.2e}")
    assert worst <= 2.0e-6
    norm = mod.new_fb("SqrtNormFixed")
    rng = np.random.default_rng(3)
    for v in [1, 2, 3, 2**60 - 1, 2**60, 2**62 - 1,
              *(int(x) for x in rng.integers(1, 2**62 - 1, 2000, dtype=np.int64))]:
        norm(Value=v)
        assert 2**30 <= norm.Root <= 2**31 and 0 <= norm.Shift <= 30, v
        assert abs(norm.Root - math.sqrt(v * 4**norm.Shift)) <= 1.0, v


def test_sqrt_product_without_the_product(mod: Any) -> None:
    prod = mod.new_fb("SqrtProductFixed")
    rng = np.random.default_rng(11)
    pairs = [(1, 1), (2, 8), (2**62 - 1, 2**62 - 1), (1, 2**62 - 1), (3, 5)]
    pairs += [(int(a), int(b)) for a, b in zip(rng.integers(1, 2**62 - 1, 1500, dtype=np.int64),
                                              rng.integers(1, 2**62 - 1, 1500, dtype=np.int64),
                                              strict=True)]
    pairs += [(int(a), int(b)) for a, b in zip(rng.integers(1, 10**6, 1500),
                                              rng.integers(1, 2**55, 1500, dtype=np.int64),
                                              strict=True)]
    for a, b in pairs:
        prod(A=a, B=b)
        want = math.sqrt(a) * math.sqrt(b)
        assert abs(prod.Root - want) <= 1.0 + 2.5e-6 * want, (a, b, prod.Root, want)
    prod(A=0, B=5)
    assert prod.Root == 0


def test_div_round(mod: Any) -> None:
    for num, den, want in [(5, 2, 3), (-5, 2, -3), (4, 3, 1), (-4, 3, -1), (149, 100, 1),
                           (150, 100, 2), (-150, 100, -2), (-149, 100, -1), (7, 0, 0)]:
        assert mod.call("DivRoundLint", Num=num, Den=den) == want


def test_sin_cos_every_hundredth_degree(mod: Any) -> None:
    trig = mod.new_fb("SinCosFixed")
    worst = 0.0
    for a in range(-36000, 72001):
        trig(AngleDeg100=a)
        rad = math.radians(a / 100.0)
        worst = max(worst, abs(trig.SinQ18 / 2**18 - math.sin(rad)),
                    abs(trig.CosQ18 / 2**18 - math.cos(rad)))
    trig(AngleDeg100=9000)
    assert (trig.SinQ18, trig.CosQ18) == (2**18, 0)
    trig(AngleDeg100=18000)
    assert (trig.SinQ18, trig.CosQ18) == (0, -(2**18))
    # As an angle error: |d sin| <= worst means at most asin-slope 1 -> worst rad.
    print(f"\n  sin/cos max error {worst:.2e} (= {math.degrees(worst):.5f} deg as an angle)")
    assert worst <= 1.2e-5
    assert math.degrees(worst) < SEED_REQUIREMENT_DEG


def test_atan2_all_octants_and_scales(mod: Any) -> None:
    atan = mod.new_fb("Atan2Fixed")
    rng = np.random.default_rng(5)
    cases = [(0, 0), (0, 5), (0, -5), (5, 0), (-5, 0), (7, 7), (-7, 7), (7, -7), (-7, -7),
             (1, 2**60), (2**60, 1), (-(2**61), 3), (2**61, -(2**61))]
    for scale in (10, 10**4, 10**9, 10**15, 2**61):
        ys = rng.integers(-scale, scale, 1500, dtype=np.int64)
        xs = rng.integers(-scale, scale, 1500, dtype=np.int64)
        cases += list(zip(ys.tolist(), xs.tolist(), strict=True))
    worst = 0.0
    for y, x in cases:
        atan(Y=y, X=x)
        got = atan.AngleDeg10k / 1e4
        assert -180.0 < got <= 180.0
        want = math.degrees(math.atan2(y, x)) if (x, y) != (0, 0) else 0.0
        worst = max(worst, float(angle_diff(np.array(got), np.array(want))))
    atan(Y=0, X=-3)
    assert atan.AngleDeg10k == 1800000
    print(f"\n  Atan2Fixed max error {worst * 1e4:.2f} x 1.0E-4 deg over {len(cases)} pairs")
    assert worst <= 2.3e-4


# ------------------------------------------------------------------ inverse kinematics
def _targets(rng: np.random.Generator, count: int) -> np.ndarray:
    """Integer targets (0.01 mm) spread over the reach shell, clear of the tolerance bands.

    Nine tenths uniform in the shell (including the region behind the base axis that only the
    back side reaches), one tenth within 0.01 mm inside the outer or inner shell (full stretch,
    fully folded) where acos-based methods lose accuracy.
    """
    low, high = arm.reach_limits(GEOMETRY)
    a1, a2 = GEOMETRY.a1, GEOMETRY.a2
    out: list[tuple[int, int, int]] = []

    def keep(xi: int, yi: int, zi: int) -> bool:
        if xi == 0 and yi == 0:
            return False
        radial = math.hypot(xi, yi) / 100.0
        zp = zi / 100.0 - a1
        front = math.hypot(radial - a2, zp)
        back = math.hypot(-radial - a2, zp)
        margin = 2e-3  # the ST accepts up to 1e-3 mm outside the shell

        def clear(cp: float) -> bool:
            return abs(cp - high) > margin and abs(cp - low) > margin

        if not (clear(front) and clear(back)):
            return False
        return (low < front < high) or (low < back < high)

    n_shell = count // 10
    while len(out) < count - n_shell:
        radial = rng.uniform(0.0, a2 + high)
        z = rng.uniform(a1 - high, a1 + high)
        base = rng.uniform(-math.pi, math.pi)
        p = (round(radial * math.cos(base) * 100), round(radial * math.sin(base) * 100),
             round(z * 100))
        if keep(*p):
            out.append(p)
    while len(out) < count:
        shell = high - rng.uniform(0.003, 0.01) if rng.random() < 0.5 \
            else low + rng.uniform(0.003, 0.01)
        direction = rng.uniform(-math.pi, math.pi)
        base = rng.uniform(-math.pi, math.pi)
        radial = a2 + shell * math.cos(direction)
        z = a1 + shell * math.sin(direction)
        if radial <= 0.0:
            continue
        p = (round(radial * math.cos(base) * 100), round(radial * math.sin(base) * 100),
             round(z * 100))
        if keep(*p):
            out.append(p)
    return np.array(out, dtype=np.int64)


def _solve_fixed(mod: Any, targets: np.ndarray, elbow_up: bool) -> np.ndarray:
    ik = mod.new_fb("InverseKinematikFixed")
    res = np.empty((len(targets), 3))
    for k, (x, y, z) in enumerate(targets.tolist()):
        ik(XMm100=x, YMm100=y, ZMm100=z, ElbowUp=elbow_up, Geometry=GEO_FIXED)
        assert ik.Valid and not ik.Error, (x, y, z, ik.ErrorId)
        a = ik.Angles
        res[k] = (a["BaseDeg100"], a["ShoulderDeg100"], a["ElbowDeg100"])
    return res / 100.0


def _reference(targets: np.ndarray, elbow_up: bool) -> np.ndarray:
    mm = targets / 100.0
    return np.array([arm.inverse(x, y, z, GEOMETRY, elbow_up) for x, y, z in mm.tolist()])


@pytest.fixture(scope="module")
def ik_targets() -> np.ndarray:
    return _targets(np.random.default_rng(2024), IK_POINTS)


@pytest.mark.parametrize("elbow_up", [True, False], ids=["elbow-up", "elbow-down"])
def test_ik_accuracy_against_float64(mod: Any, ik_targets: np.ndarray, elbow_up: bool) -> None:
    got = _solve_fixed(mod, ik_targets, elbow_up)
    ref = _reference(ik_targets, elbow_up)
    err = angle_diff(got, ref)
    names = ("Base", "Shoulder", "Elbow")
    print(f"\n  InverseKinematikFixed vs float64, {len(ik_targets)} targets, "
          f"elbow {'up' if elbow_up else 'down'}:")
    for j, name in enumerate(names):
        print(f"    {name:8s} max {err[:, j].max():.5f} deg  mean {err[:, j].mean():.5f} deg")
    worst = float(err.max())
    assert worst <= SEED_REQUIREMENT_DEG
    assert worst <= GOAL_DEG
    # Output rounding alone contributes up to 0.005 deg; the mean of a uniform rounding
    # error is 0.0025 deg.
    assert float(err.mean()) <= 0.003


def test_ik_float_methods_for_comparison(mod: Any, ik_targets: np.ndarray) -> None:
    """The geometric (V1, REAL) and DH (REAL) methods on the same targets, for the record."""
    subset = ik_targets[:3000]
    ref = _reference(subset, True)
    dh = mod.new_fb("InverseKinematik_DH")
    v1 = np.empty((len(subset), 3))
    dhr = np.empty((len(subset), 3))
    residual = 0.0
    for k, (x, y, z) in enumerate((subset / 100.0).tolist()):
        target = {"X": x, "Y": y, "Z": z, "GripperUpDown": 0.0, "Gripper": 0.0,
                  "ElbowRotate": 0.0, "GripperRotate": 0.0}
        a = mod.call("InverseKinematik_V1", Target=target, Geometry=GEO, ElbowUp=True)
        v1[k] = (a["Base"], a["Shoulder"], a["Elbow"])
        dh(Target=target, Geometry=GEO, ElbowUp=True)
        assert dh.Valid, (x, y, z, dh.ErrorId)
        b = dh.Angles
        dhr[k] = (b["Base"], b["Shoulder"], b["Elbow"])
        residual = max(residual, dh.ResidualMm)
    e_v1, e_dh = angle_diff(v1, ref), angle_diff(dhr, ref)
    print(f"\n  REAL (float32) methods, {len(subset)} targets: geometric V1 max "
          f"{e_v1.max():.5f} mean {e_v1.mean():.6f} deg; DH max {e_dh.max():.5f} mean "
          f"{e_dh.mean():.6f} deg; DH residual max {residual:.2e} mm")
    assert e_dh.max() <= 0.05
    assert residual <= 0.01


def test_ik_errors_and_hold(mod: Any) -> None:
    ik = mod.new_fb("InverseKinematikFixed")
    ik(XMm100=15000, YMm100=5000, ZMm100=12000, ElbowUp=True, Geometry=GEO_FIXED)
    assert ik.Valid and ik.ErrorId == NO_ERROR
    held = dict(ik.Angles)
    cases = [
        ((0, 0, 15000), GEO_FIXED, SINGULAR),                  # on the base axis
        ((100000, 0, 10000), GEO_FIXED, UNREACHABLE),          # far away
        ((300, 0, 10000), {**GEO_FIXED, "A2Mm100": 0}, UNREACHABLE),  # inside |a3-a4| = 10 mm
        ((2_000_000, 0, 0), GEO_FIXED, UNREACHABLE),           # beyond 10 m
        ((15000, 0, 0), {**GEO_FIXED, "A3Mm100": 0}, BAD_GEOMETRY),
        ((15000, 0, 0), {**GEO_FIXED, "A4Mm100": -5}, BAD_GEOMETRY),
        ((15000, 0, 0), {**GEO_FIXED, "A1Mm100": 2_000_000}, BAD_GEOMETRY),
        ((2000, 0, 10000), {**GEO_FIXED, "A4Mm100": 12000}, SINGULAR),  # a3 = a4, at shoulder
    ]
    for (x, y, z), geo, code in cases:
        ik(XMm100=x, YMm100=y, ZMm100=z, ElbowUp=True, Geometry=geo)
        assert (ik.Valid, ik.Error, ik.ErrorId) == (False, True, code), (x, y, z, geo)
        assert dict(ik.Angles) == held


def test_ik_full_stretch_and_back_side(mod: Any) -> None:
    ik = mod.new_fb("InverseKinematikFixed")
    # Straight arm along +X at shoulder height: Base 0, Shoulder 0, Elbow 180.
    ik(XMm100=2000 + 25000, YMm100=0, ZMm100=10000, ElbowUp=True, Geometry=GEO_FIXED)
    assert ik.Valid and dict(ik.Angles) == {"BaseDeg100": 0, "ShoulderDeg100": 0,
                                            "ElbowDeg100": 18000}
    # Straight up: Shoulder 90.
    ik(XMm100=2000, YMm100=0, ZMm100=10000 + 25000, ElbowUp=False, Geometry=GEO_FIXED)
    assert dict(ik.Angles) == {"BaseDeg100": 0, "ShoulderDeg100": 9000, "ElbowDeg100": 18000}
    # 5.8 mm from the shoulder (inside |a3-a4|): only the back side reaches.
    ik(XMm100=1500, YMm100=0, ZMm100=10300, ElbowUp=True, Geometry=GEO_FIXED)
    ref = arm.inverse(15.0, 0.0, 103.0, GEOMETRY, True)
    got = ik.Angles
    assert got["BaseDeg100"] == 18000 == round(ref[0] * 100)
    assert abs(got["ShoulderDeg100"] / 100 - ref[1]) <= GOAL_DEG
    assert abs(got["ElbowDeg100"] / 100 - ref[2]) <= GOAL_DEG


def test_fk_fixed_against_float64_and_round_trip(mod: Any) -> None:
    rng = np.random.default_rng(7)
    fk = mod.new_fb("ForwardKinematicFixed")
    ik = mod.new_fb("InverseKinematikFixed")
    angles = np.stack([rng.integers(-17999, 18001, 3000), rng.integers(-9000, 9001, 3000),
                       rng.integers(1000, 17001, 3000)], axis=1)
    worst_fk = 0.0
    worst_rt = 0.0
    for b, s, e in angles.tolist():
        fk(Angles={"BaseDeg100": b, "ShoulderDeg100": s, "ElbowDeg100": e}, Geometry=GEO_FIXED)
        assert not fk.Error
        got = np.array([fk.XMm100, fk.YMm100, fk.ZMm100]) / 100.0
        want = arm.forward(b / 100, s / 100, e / 100, GEOMETRY)
        worst_fk = max(worst_fk, float(np.abs(got - want).max()))
        if math.hypot(fk.XMm100, fk.YMm100) < 1000:
            continue  # near the axis the base angle is ill-conditioned by position rounding
        ik(XMm100=fk.XMm100, YMm100=fk.YMm100, ZMm100=fk.ZMm100, ElbowUp=True,
           Geometry=GEO_FIXED)
        if ik.Valid:
            a = ik.Angles
            back = arm.forward(a["BaseDeg100"] / 100, a["ShoulderDeg100"] / 100,
                               a["ElbowDeg100"] / 100, GEOMETRY)
            worst_rt = max(worst_rt, float(np.abs(back - got).max()))
    print(f"\n  ForwardKinematicFixed max error {worst_fk * 1000:.2f} um; "
          f"FK(IK(p)) max error {worst_rt * 1000:.1f} um")
    assert worst_fk <= 0.011
    assert worst_rt <= 0.05


# ------------------------------------------------------------------ real MatIEC
@pytest.mark.skipif(not MATIEC_CHECK.is_file(),
                    reason="MATIEC_CHECK not set or no file: set it to a script that builds "
                           "FILE.st the way OpenPLC v3 does (README)")
def test_real_matiec_accepts_fixed_library(tmp_path: Path) -> None:
    program = tmp_path / "fixed_main.st"
    program.write_text("""PROGRAM FixedMain
  VAR
    Ik : InverseKinematikFixed;
    Fk : ForwardKinematicFixed;
    Dh : InverseKinematik_DH;
    Target : Coordinates;
    Geometry : ArmGeometry;
    Elbow : DINT;
    Zo : DINT;
  END_VAR
  Ik(XMm100 := 15000, YMm100 := 5000, ZMm100 := 12000, ElbowUp := TRUE);
  Elbow := Ik.Angles.ElbowDeg100;
  Fk(Angles := Ik.Angles);
  Zo := Fk.ZMm100;
  Target.X := 150.0;
  Target.Z := 120.0;
  Dh(Target := Target, Geometry := Geometry, ElbowUp := TRUE);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : FixedMain;
  END_RESOURCE
END_CONFIGURATION
""")
    # check-st.sh takes one whole program, as the OpenPLC upload does
    sources = [ST / "ArmAngles.st", ST / "Kinematics.st", ST / "KinematicsDH.st",
               *FIXED_FILES]
    whole = tmp_path / "fixed_whole.st"
    whole.write_text("\n".join(f.read_text(encoding="utf-8") for f in sources)
                     + "\n" + program.read_text(), encoding="utf-8")
    bash = shutil.which("bash") or "/bin/bash"
    run = subprocess.run([bash, str(MATIEC_CHECK), str(whole)], capture_output=True,
                         text=True, timeout=600, check=False)
    assert run.returncode == 0, \
        run.stdout + run.stderr
