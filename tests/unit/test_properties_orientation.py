"""Property tests of the quaternion and IMU-filter POUs that had none: QuatProduct,
QuatConjugate, QuatNorm, QuatIsUsable, QuatFromMatrix, QuatToRollPitchYaw,
QuatFromRollPitchYaw, QuatToolDirection (st/Quaternion.st); ImuRawToSample, VectorCross3,
VectorIsUsable, ImuSampleCode, QuatIntegrateGyro, TriadUsable, QuatFromAccelMag,
QuatFromAccelTilt, GyroIntegrator, ComplementaryFilter, MadgwickImu, MadgwickMarg
(st/OrientationFilters.st); ToolFollowerSettingsOk (st/ToolOrientation.st).

Inputs are drawn over the documented ranges, the float32 extremes and just beyond (tiny and
huge vectors, 1.0E6 and its next float, NaN, +/-Inf). The promises are the headers':
closed forms in float64 (Hamilton product, norms, cross products, the calibration formula,
the sample codes), rotations equal to scipy's (from_matrix, Z-Y-X Euler, rotation vectors),
the TRIAD orientation equal to ahrs's TRIAD, one filter step equal to ahrs 0.4.0's Madgwick
updateIMU / updateMARG and to document 004's complementary blend, and for the filter blocks,
sample by sample: a unit quaternion, never NaN, a rejected sample leaving the output exactly
as it was with the documented ErrorId and Rejected counting it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

hypothesis = pytest.importorskip("hypothesis")
ahrs_filters = pytest.importorskip("ahrs.filters")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

F32_MAX = float(np.finfo(np.float32).max)
NEXT_1E6 = float(np.nextafter(np.float32(1.0e6), np.float32(2.0e6)))
EXTREMES = [0.0, -0.0, 1e-45, 1e-38, 1e-30, 1e-12, 1e-7, 1e-6, 1.0, 1e3, 1e6, NEXT_1E6,
            1e12, 1e30, 1.1e30, F32_MAX, math.inf, -math.inf, math.nan]
BAD_PARAMETER, NOT_FINITE, ACCEL_ZERO, MAG_ZERO, SATURATED, PARALLEL, BAD_QUAT = (
    8, 40, 41, 42, 43, 44, 45)
SIN_1DEG = math.sin(math.radians(1.0))
REAL_1E30 = float(np.float32(1.0e30))  # IsFiniteReal compares with the REAL 1.0E30
REAL_1EM6 = float(np.float32(1.0e-6))  # VectorIsUsable's REAL 1.0E-6


def f32(x: float) -> float:
    return float(np.float32(x))


def real(lo: float, hi: float) -> st.SearchStrategy[float]:
    """A float32 in [lo, hi], or an extreme (either sign, beyond the range too)."""
    return st.one_of(st.floats(lo, hi, width=32), st.sampled_from(EXTREMES),
                     st.sampled_from(EXTREMES).map(lambda v: -v))


def vec(v: Any) -> dict[str, float]:
    return {"X": float(v[0]), "Y": float(v[1]), "Z": float(v[2])}


def vrow(d: dict[str, float]) -> np.ndarray:
    return np.array([d["X"], d["Y"], d["Z"]], dtype=float)


def quat(q: Any) -> dict[str, float]:
    return {"W": float(q[0]), "X": float(q[1]), "Y": float(q[2]), "Z": float(q[3])}


def qrow(d: dict[str, float]) -> np.ndarray:
    return np.array([d["W"], d["X"], d["Y"], d["Z"]], dtype=float)


def rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(q, scalar_first=True)


def hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Rotation angle between two unit quaternions (either sign), deg, float64."""
    return float(np.degrees((rot(a).inv() * rot(b)).magnitude()))


def is_unit(q: np.ndarray, tol: float = 2e-6) -> bool:
    return bool(np.isfinite(q).all() and abs(np.linalg.norm(q) - 1.0) < tol)


def usable_vec(v: np.ndarray, nonzero: bool) -> bool:
    """VectorIsUsable's promise in float64: all |c| <= 1e6, and |v| >= 1e-6 when NonZero."""
    if not all(abs(c) <= 1.0e6 for c in v):  # NaN compares False
        return False
    return not nonzero or float(np.linalg.norm(v)) >= REAL_1EM6


unit_quats = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda c: np.linalg.norm(c) > 0.1).map(lambda c: np.array(c) / np.linalg.norm(c))
rotations = unit_quats.map(rot)


# --- Quaternion algebra ---------------------------------------------------------------------

@examples(300)
@given(a=st.lists(real(-1e6, 1e6), min_size=4, max_size=4),
       b=st.lists(real(-1e6, 1e6), min_size=4, max_size=4))
def test_quat_product_conjugate_norm_usable(st_module: Any, a: list[float],
                                           b: list[float]) -> None:
    qa, qb = np.array([f32(v) for v in a]), np.array([f32(v) for v in b])
    conj = qrow(st_module.call("QuatConjugate", quat(qa)))
    want_conj = qa * np.array([1.0, -1.0, -1.0, -1.0])
    assert np.array_equal(conj, want_conj, equal_nan=True)

    norm = st_module.call("QuatNorm", quat(qa))
    finite = bool(np.isfinite(qa).all() and np.abs(qa).max() <= REAL_1E30)
    if np.isnan(qa).any():
        assert math.isnan(norm)  # "NaN in gives NaN out"
    elif finite:
        ref = float(np.linalg.norm(qa))
        # relative to the norm, or one subnormal step (1.4e-45) where float32 has no closer
        assert norm >= 0.0 and abs(norm - ref) <= 4e-7 * ref + 1.5e-45

    usable = st_module.call("QuatIsUsable", quat(qa))
    ref_norm = float(np.linalg.norm(qa)) if finite else 0.0
    if not finite:
        assert usable is False
    elif abs(ref_norm - 1e-12) > 1e-18:  # off the float32 rounding band of the threshold
        assert usable is (ref_norm >= 1e-12)

    if finite and np.isfinite(qb).all() and np.abs(qb).max() <= 1e6 and np.abs(qa).max() <= 1e6:
        got = qrow(st_module.call("QuatProduct", quat(qa), quat(qb)))
        want = hamilton(qa, qb)
        scale = float(np.abs(qa).max() * np.abs(qb).max())
        assert np.abs(got - want).max() <= 1e-6 * scale + 1e-37


@examples(200)
@given(ra=rotations, rb=rotations)
def test_quat_product_composes_rotations(st_module: Any, ra: Rotation, rb: Rotation) -> None:
    """A (x) B applies B first, then A: scipy's ra * rb."""
    got = qrow(st_module.call("QuatProduct", quat(ra.as_quat(scalar_first=True)),
                              quat(rb.as_quat(scalar_first=True))))
    assert angle_deg(got / np.linalg.norm(got), (ra * rb).as_quat(scalar_first=True)) < 3e-4


# --- Matrices, Euler angles, tool direction -----------------------------------------------

near_flip = st.tuples(st.sampled_from([0, 1, 2]), st.floats(-1e-3, 1e-3)).map(
    lambda t: Rotation.from_rotvec(np.eye(3)[t[0]] * (math.pi - abs(t[1]))))


@examples(300)
@given(r=st.one_of(rotations, near_flip, st.just(Rotation.identity())))
def test_quat_from_matrix_and_tool_direction(st_module: Any, r: Rotation) -> None:
    m = r.as_matrix().astype(np.float32).astype(float)
    got = qrow(st_module.call("QuatFromMatrix", Rm=m.tolist()))
    assert is_unit(got) and got[0] >= 0.0
    assert angle_deg(got, Rotation.from_matrix(m).as_quat(scalar_first=True)) < 3e-4
    q = r.as_quat(scalar_first=True)
    tool = vrow(st_module.call("QuatToolDirection", quat(q)))
    assert np.abs(tool - r.as_matrix()[:, 0]).max() < 2e-6
    assert abs(np.linalg.norm(tool) - 1.0) < 2e-6


@examples(200)
@given(m=st.lists(st.lists(real(-2.0, 2.0), min_size=3, max_size=3), min_size=3, max_size=3))
def test_quat_from_matrix_never_nan(st_module: Any, m: list[list[float]]) -> None:
    """Any matrix, a rotation or not, NaN/Inf included: a unit quaternion with W >= 0."""
    got = qrow(st_module.call("QuatFromMatrix", Rm=m))
    assert is_unit(got) and got[0] >= 0.0


pitch_near_lock = st.tuples(st.sampled_from([-90.0, 90.0]), st.floats(-0.2, 0.2)).map(
    lambda t: t[0] - math.copysign(abs(t[1]), t[0]))


@examples(300)
@given(yaw=st.floats(-180.0, 180.0), pitch=st.one_of(st.floats(-90.0, 90.0), pitch_near_lock),
       roll=st.floats(-180.0, 180.0))
@example(yaw=92.40625, pitch=-89.875, roll=92.421875)
@example(yaw=29.60075113105546, pitch=-89.93818293664503, roll=29.60075113105546)
# found by the 10x soak: RadToDeg(-3.1415925) rounds to -180.0, outside (-180, 180]
@example(yaw=180.0, pitch=76.25, roll=129.5)
def test_roll_pitch_yaw_round_trip(st_module: Any, yaw: float, pitch: float,
                                   roll: float) -> None:
    yaw, pitch, roll = f32(yaw), f32(pitch), f32(roll)
    ref = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)
    q = qrow(st_module.call("QuatFromRollPitchYaw", roll, pitch, yaw))
    assert is_unit(q)
    assert angle_deg(q, ref.as_quat(scalar_first=True)) < 3e-4
    rpy = st_module.call("QuatToRollPitchYaw", quat(ref.as_quat(scalar_first=True)))
    r_out, p_out, y_out = rpy["RollDeg"], rpy["PitchDeg"], rpy["YawDeg"]
    assert -180.0 < r_out <= 180.0 and -180.0 < y_out <= 180.0 and -90.0 <= p_out <= 90.0
    back = Rotation.from_euler("ZYX", [y_out, p_out, r_out], degrees=True)
    # Near the lock the pitch comes from asin(2 (w y - z x)): the REAL quaternion (2^-24
    # relative per component), the two products and the difference put that argument
    # off by up to 2 * 0.5 * (3 + 1) * 2^-24 = 2.4e-7, which the asin turns into
    # 2.4e-7 / cos(pitch) rad (1.5e-7 was one rounding short: the soak's first case below,
    # 1.6e-7 at 0.125 deg from the lock). Inside the 0.0573 deg lock band (|sin| >=
    # 0.9999995) dropping the roll costs up to twice the distance from the lock; the same
    # 2.4e-7 moves the band's edge in REAL out to 1 - cos(d) = 5e-7 + 2.4e-7, d = 0.0697
    # deg (the soak's second case: 0.0618 deg from the lock, taken as locked).
    d = math.radians(abs(90.0 - abs(float(ref.as_euler("ZYX", degrees=True)[1]))))
    tol = 0.16 if d < math.radians(0.0698) else 3e-4 + math.degrees(2.4e-7 / math.sin(d))
    assert angle_deg(back.as_quat(scalar_first=True), ref.as_quat(scalar_first=True)) < tol
    if abs(abs(pitch) - 90.0) < 0.05:
        assert r_out == 0.0  # inside the lock band roll is 0, yaw carries the turn


@examples(200)
@given(angles=st.lists(real(-1e6, 1e6), min_size=3, max_size=3))
def test_quat_from_roll_pitch_yaw_any_angle(st_module: Any, angles: list[float]) -> None:
    """Any input, NaN/Inf and beyond the range included: never NaN, a unit quaternion; for
    finite angles within +/-1e6 deg, scipy's Z-Y-X rotation of the same float32 angles."""
    roll, pitch, yaw = (f32(v) for v in angles)
    q = qrow(st_module.call("QuatFromRollPitchYaw", roll, pitch, yaw))
    assert is_unit(q)
    if all(math.isfinite(v) and abs(v) <= 1e6 for v in (roll, pitch, yaw)):
        ref = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)
        # float32 half-angles of a large angle: a few ulps of |angle| (0.06 deg at 1e6)
        tol = 3e-4 + 4.0 * float(np.spacing(np.float32(max(abs(roll), abs(pitch), abs(yaw)))))
        assert angle_deg(q, ref.as_quat(scalar_first=True)) < tol


# --- Vectors ---------------------------------------------------------------------------------

@examples(300)
@given(a=st.lists(real(-1e6, 1e6), min_size=3, max_size=3),
       b=st.lists(real(-1e6, 1e6), min_size=3, max_size=3), nonzero=st.booleans())
def test_vector_helpers(st_module: Any, a: list[float], b: list[float], nonzero: bool) -> None:
    va, vb = np.array([f32(v) for v in a]), np.array([f32(v) for v in b])
    usable = st_module.call("VectorIsUsable", vec(va), nonzero)
    norm = float(np.linalg.norm(va)) if np.isfinite(va).all() else math.inf
    if not nonzero or abs(norm - REAL_1EM6) > 1e-12:
        assert usable is usable_vec(va, nonzero)
    if np.isfinite(va).all() and np.isfinite(vb).all() and max(
            np.abs(va).max(), np.abs(vb).max()) <= 1e6:
        got = vrow(st_module.call("VectorCross3", vec(va), vec(vb)))
        scale = float(np.abs(va).max() * np.abs(vb).max())
        assert np.abs(got - np.cross(va, vb)).max() <= 3e-7 * scale + 1e-37
    triad = st_module.call("TriadUsable", vec(va), vec(vb))
    if not (usable_vec(va, True) and usable_vec(vb, True)):
        assert triad is False
    else:
        ratio = np.linalg.norm(np.cross(va, vb)) / (np.linalg.norm(va) * np.linalg.norm(vb))
        if abs(ratio - SIN_1DEG) > 1e-5:  # off the float32 rounding band of the threshold
            assert triad is bool(ratio >= SIN_1DEG)


@examples(200)
@given(a=unit_quats.map(lambda q: q[1:]).filter(lambda v: np.linalg.norm(v) > 0.0),
       angle=st.one_of(st.floats(0.0, 3.0), st.floats(177.0, 180.0), st.floats(0.9, 1.1),
                       st.floats(178.9, 179.1)),
       scale_a=st.sampled_from([1e-5, 1.0, 1e5]), scale_b=st.sampled_from([1e-5, 1.0, 1e5]))
@example(a=np.array([0.0, 0.0, 2.22044605e-07]), angle=1.0, scale_a=1e-5, scale_b=1e-5)
def test_triad_usable_at_its_angle_band(st_module: Any, a: np.ndarray, angle: float,
                                       scale_a: float, scale_b: float) -> None:
    """Vector pairs at an exact angle near 0, 1, 179 and 180 deg, tiny and huge."""
    # a unit vector, so that scale_a is |va|: the strategy's max(|v|, 1e-9) let a quaternion's
    # 2e-16 vector part through as a 2e-7 one, and va (2e-12) was then too short for a triad
    # whatever the angle (the soak's case below)
    a = a / np.linalg.norm(a)
    perp = np.cross(a, [0.3, -0.5, 0.8])
    perp /= np.linalg.norm(perp)
    b = math.cos(math.radians(angle)) * a + math.sin(math.radians(angle)) * perp
    va = np.float32(scale_a) * a.astype(np.float32)
    vb = np.float32(scale_b) * b.astype(np.float32)
    true_angle = math.degrees(math.acos(np.clip(
        np.dot(va, vb) / (np.linalg.norm(va) * np.linalg.norm(vb)), -1.0, 1.0)))
    triad = st_module.call("TriadUsable", vec(va), vec(vb))
    if min(abs(true_angle - 1.0), abs(true_angle - 179.0)) > 1e-3:
        assert triad is (1.0 < true_angle < 179.0)


# --- IMU samples -------------------------------------------------------------------------------

raw_axis = st.one_of(st.integers(-32768, 32767), st.sampled_from([-32768, 32767, 0]))
mag_axis = st.one_of(st.integers(-2048, 2047), st.sampled_from([-4096, -2048, 2047, 0]))
lsb = st.one_of(st.floats(f32(1e-3), 1e6, width=32), st.sampled_from(
    [0.0, -1.0, NEXT_1E6, 131.0, 16384.0, 1090.0, math.nan, math.inf]))
scale = st.one_of(st.floats(0.5, 2.0, width=32), st.sampled_from(
    [0.5, 2.0, f32(0.4999999), f32(2.0000002), math.nan, -1.0]))
offset = st.one_of(st.floats(-1e3, 1e3, width=32), st.sampled_from(
    [1e3, -1e3, f32(1000.0001), math.nan, math.inf]))


@examples(300)
@given(raw=st.lists(raw_axis, min_size=6, max_size=6),
       mag=st.lists(mag_axis, min_size=3, max_size=3),
       lsbs=st.lists(lsb, min_size=3, max_size=3), scales=st.lists(scale, min_size=3,
                                                                   max_size=3),
       offsets=st.lists(offset, min_size=9, max_size=9))
def test_imu_raw_to_sample(st_module: Any, raw: list[int], mag: list[int], lsbs: list[float],
                           scales: list[float], offsets: list[float]) -> None:
    lsbs, scales, offsets = [f32(v) for v in lsbs], [f32(v) for v in scales], [
        f32(v) for v in offsets]
    raw_d = dict(zip(["GyroX", "GyroY", "GyroZ", "AccelX", "AccelY", "AccelZ", "MagX",
                      "MagY", "MagZ"], raw + mag, strict=True))
    cal = {"GyroLsbPerDps": lsbs[0], "AccelLsbPerG": lsbs[1], "MagLsbPerGauss": lsbs[2],
           "GyroBiasDps": vec(offsets[0:3]), "AccelOffsetG": vec(offsets[3:6]),
           "AccelScaleX": scales[0], "AccelScaleY": scales[1], "AccelScaleZ": scales[2],
           "MagOffsetGauss": vec(offsets[6:9])}
    out = st_module.call("ImuRawToSample", raw_d, cal)
    cal_ok = (all(0.0 < v <= 1e6 for v in lsbs) and all(0.5 <= v <= 2.0 for v in scales)
              and all(abs(v) <= 1e3 for v in offsets))
    got = np.concatenate([vrow(out["Gyro"]), vrow(out["Accel"]), vrow(out["Mag"])])
    if not cal_ok:
        assert out["Code"] == BAD_PARAMETER and not got.any()
        return
    saturated = any(v in (-32768, 32767) for v in raw) or -4096 in mag
    assert out["Code"] == (SATURATED if saturated else 0)
    want = np.concatenate([
        np.array(raw[0:3]) / lsbs[0] - np.array(offsets[0:3]),
        (np.array(raw[3:6]) / lsbs[1] - np.array(offsets[3:6])) * np.array(scales),
        np.array(mag) / lsbs[2] - np.array(offsets[6:9])])
    bound = np.abs(np.array(raw + mag, dtype=float)) / np.array([lsbs[0]] * 3 + [lsbs[1]] * 3
                                                                  + [lsbs[2]] * 3)
    tol = 4e-7 * (bound + np.abs(np.array(offsets))) * np.array([1.0] * 3 + [2.0] * 3 + [1.0] * 3)
    assert np.all(np.abs(got - want) <= tol + 1e-30)


def sample_code(s: dict[str, Any], use_mag: bool) -> int:
    """ImuSampleCode's rule, restated from its header, in float64."""
    if s["Code"] != 0:
        return int(s["Code"])
    g, a, m = vrow(s["Gyro"]), vrow(s["Accel"]), vrow(s["Mag"])
    if not (usable_vec(g, False) and usable_vec(a, False) and (usable_vec(m, False)
                                                               or not use_mag)):
        return NOT_FINITE
    if not usable_vec(a, True):
        return ACCEL_ZERO
    if use_mag and not usable_vec(m, True):
        return MAG_ZERO
    return 0


def triad_ok(a: np.ndarray, b: np.ndarray) -> bool:
    if not (usable_vec(a, True) and usable_vec(b, True)):
        return False
    return bool(np.linalg.norm(np.cross(a, b)) >= SIN_1DEG * np.linalg.norm(a)
                * np.linalg.norm(b))


def bad_component(draw: Any) -> float:
    return f32(draw(st.sampled_from([math.nan, math.inf, -math.inf, NEXT_1E6, -1e12, F32_MAX])))


@st.composite
def imu_samples(draw: Any, truth: Rotation | None = None) -> dict[str, Any]:
    """A sample of a sensor at a random pose (gravity and a tilted field, scaled), or one with
    a fault: a bad component, a zero accelerometer or magnetometer, a saturated or
    bad-calibration code, gravity parallel to the field, a zero gyro."""
    r = truth if truth is not None else draw(rotations)
    field = np.array([0.4, 0.0, -0.3])
    acc = r.inv().apply([0.0, 0.0, 1.0]) * draw(st.sampled_from([1.0, 0.05, 3.0, 1e-4, 1e5]))
    mag = r.inv().apply(field) * draw(st.sampled_from([1.0, 1e-4, 1e3]))
    gyro = np.array(draw(st.lists(st.floats(-500.0, 500.0), min_size=3, max_size=3)))
    code = 0
    kind = draw(st.sampled_from(["ok"] * 6 + ["gyro", "acc", "mag", "acc0", "mag0", "code",
                                              "parallel", "gyro0"]))
    if kind == "gyro":
        gyro[draw(st.integers(0, 2))] = bad_component(draw)
    elif kind == "acc":
        acc[draw(st.integers(0, 2))] = bad_component(draw)
    elif kind == "mag":
        mag[draw(st.integers(0, 2))] = bad_component(draw)
    elif kind == "acc0":
        acc = acc / np.linalg.norm(acc) * draw(st.sampled_from([0.0, 1e-9, 5e-7]))
    elif kind == "mag0":
        mag = mag / np.linalg.norm(mag) * draw(st.sampled_from([0.0, 1e-9, 5e-7]))
    elif kind == "code":
        code = draw(st.sampled_from([SATURATED, BAD_PARAMETER]))
    elif kind == "parallel":
        mag = acc * draw(st.sampled_from([0.5, -2.0])) + draw(st.floats(-1e-4, 1e-4)) * np.cross(
            acc, [1.0, 0.0, 0.0])
    elif kind == "gyro0":
        gyro = np.zeros(3)
    return {"Gyro": vec(gyro.astype(np.float32)), "Accel": vec(acc.astype(np.float32)),
            "Mag": vec(mag.astype(np.float32)), "Code": code}


@examples(300)
@given(sample=imu_samples(), use_mag=st.booleans())
def test_imu_sample_code(st_module: Any, sample: dict[str, Any], use_mag: bool) -> None:
    assert st_module.call("ImuSampleCode", sample, use_mag) == sample_code(sample, use_mag)


# --- Gyro step, TRIAD, tilt ------------------------------------------------------------------

@examples(300)
@given(q=unit_quats, gyro=st.lists(real(-1e6, 1e6), min_size=3, max_size=3),
       dt=st.one_of(st.floats(f32(1e-4), 1.0, width=32), st.sampled_from(
           [1.0, f32(1.0000001), 0.0, -0.01, math.nan, math.inf, 1e-45])))
def test_quat_integrate_gyro(st_module: Any, q: np.ndarray, gyro: list[float],
                             dt: float) -> None:
    g = np.array([f32(v) for v in gyro])
    q32 = q.astype(np.float32).astype(float)
    got = qrow(st_module.call("QuatIntegrateGyro", quat(q32), vec(g), f32(dt)))
    assert is_unit(got)
    q_unit = q32 / np.linalg.norm(q32)
    if not (usable_vec(g, False) and 0.0 < f32(dt) <= 1.0) or not np.any(g):
        assert angle_deg(got, q_unit) < 1e-4  # Quat itself, normalised
        return
    want = rot(q_unit) * Rotation.from_rotvec(np.radians(g) * f32(dt))
    turn = float(np.linalg.norm(g)) * f32(dt)
    # float32: the turn angle rounds to an ulp of itself; sin/cos of it in REAL
    tol = 3e-4 + 4.0 * float(np.spacing(np.float32(turn)))
    assert angle_deg(got, want.as_quat(scalar_first=True)) < tol


@examples(300)
@given(r=rotations, s_acc=st.sampled_from([1.0, 1e-5, 1e5, 0.3]),
       s_mag=st.sampled_from([1.0, 1e-5, 1e5, 0.5]),
       ref_mag=st.sampled_from([(1.0, 0.0, 0.0), (0.4, 0.0, -0.3), (0.2, 0.1, 0.9)]),
       parallel=st.booleans())
def test_quat_from_accel_mag_is_triad(st_module: Any, r: Rotation, s_acc: float,
                                      s_mag: float, ref_mag: tuple[float, float, float],
                                      parallel: bool) -> None:
    ref_acc = np.array([0.0, 0.0, 1.0])
    rm = np.array(ref_mag)
    acc = (r.inv().apply(ref_acc) * s_acc).astype(np.float32)
    mag = (r.inv().apply(rm) * s_mag).astype(np.float32)
    if parallel:
        mag = (acc * np.float32(2.0)).astype(np.float32)
    got = qrow(st_module.call("QuatFromAccelMag", vec(acc), vec(mag), vec(ref_acc), vec(rm)))
    assert is_unit(got)
    if not triad_ok(acc.astype(float), mag.astype(float)):
        assert np.array_equal(got, [1.0, 0.0, 0.0, 0.0])
        return
    a_mat = ahrs_filters.TRIAD(v1=ref_acc, v2=rm).estimate(acc.astype(float), mag.astype(float))
    want = Rotation.from_matrix(a_mat.T).as_quat(scalar_first=True)  # ahrs: earth to body
    assert angle_deg(got, want) < 3e-4


@examples(300)
@given(a=st.one_of(st.lists(real(-1e6, 1e6), min_size=3, max_size=3),
                   unit_quats.map(lambda q: list(q[1:])),
                   st.tuples(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3)).map(
                       lambda t: [t[0], t[1], -1.0])))
def test_quat_from_accel_tilt(st_module: Any, a: list[float]) -> None:
    acc = np.array([f32(v) for v in a])
    got = qrow(st_module.call("QuatFromAccelTilt", vec(acc)))
    assert is_unit(got)
    if not usable_vec(acc, True):
        assert np.array_equal(got, [1.0, 0.0, 0.0, 0.0])
        return
    assert got[3] == 0.0  # horizontal axis: no turn about the vertical
    u = acc / np.linalg.norm(acc)
    arc = math.degrees(math.acos(np.clip(u[2], -1.0, 1.0)))
    if 1.0 + u[2] < 1e-6:  # the documented flip: a 180 deg roll about X
        assert np.abs(np.abs(got) - [0.0, 1.0, 0.0, 0.0]).max() < 1e-6
        return
    # the rotation takes the measured direction to earth +Z by the shortest arc; W = 1 + a.z
    # cancels near the flip, so the direction resolves to ~1.2e-7 / (1 + a.z)
    tol = 3e-6 + 2.4e-7 / (1.0 + u[2])
    assert np.abs(rot(got).apply(u) - [0.0, 0.0, 1.0]).max() < tol
    assert abs(float(np.degrees(rot(got).magnitude())) - arc) < math.degrees(tol) + 1e-4


# --- The filter blocks, sample by sample ----------------------------------------------------

periods = st.one_of(st.floats(f32(1e-3), f32(0.05), width=32), st.sampled_from(
    [0.01, 1.0, f32(1.0000001), 0.0, -0.01, math.nan]))


def period_ok(dt: float) -> bool:
    return 0.0 < dt <= 1.0


@examples(60)
@given(q0=unit_quats, samples=st.lists(st.tuples(imu_samples(), periods), min_size=1,
                                       max_size=25),
       bad_init=st.booleans())
def test_gyro_integrator_sample_by_sample(st_module: Any, q0: np.ndarray,
                                          samples: list[tuple[dict[str, Any], float]],
                                          bad_init: bool) -> None:
    fb = st_module.new_fb("GyroIntegrator")
    init = quat([math.nan, 0.0, 0.0, 0.0]) if bad_init else quat(q0)
    fb(Reset=True, InitialQuat=init)
    assert fb.ErrorId == (BAD_QUAT if bad_init else 0)
    prev = qrow(fb.Orientation)
    assert is_unit(prev)
    rejected = 0
    for sample, dt in samples:
        dt = f32(dt)
        fb(Reset=False, InitialQuat=init, Sample=sample, SamplePeriodS=dt)
        out = qrow(fb.Orientation)
        assert is_unit(out)
        code = BAD_PARAMETER if not period_ok(dt) else sample["Code"] or (
            0 if usable_vec(vrow(sample["Gyro"]), False) else NOT_FINITE)
        assert fb.ErrorId == code and fb.Error == (code != 0)
        if code:
            rejected += 1
            assert np.array_equal(out, prev)
        else:
            g = vrow(sample["Gyro"])
            want = rot(prev) * Rotation.from_rotvec(np.radians(g) * dt)
            assert angle_deg(out, want.as_quat(scalar_first=True)) < 3e-4
        assert fb.Rejected == rejected
        prev = out


@examples(60)
@given(samples=st.lists(st.tuples(imu_samples(), periods), min_size=1, max_size=25),
       blend=st.one_of(st.floats(0.0, 1.0, width=32), st.sampled_from(
           [0.98, 0.0, 1.0, f32(1.0000001), -0.01, math.nan])))
def test_complementary_filter_sample_by_sample(st_module: Any,
                                               samples: list[tuple[dict[str, Any], float]],
                                               blend: float) -> None:
    fb = st_module.new_fb("ComplementaryFilter")
    ref_acc, ref_mag = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    triad = ahrs_filters.TRIAD(v1=ref_acc, v2=ref_mag)
    fb(Reset=True)
    blend = f32(blend)
    prev, valid, rejected = qrow(fb.Orientation), False, 0
    for sample, dt in samples:
        dt = f32(dt)
        fb(Reset=False, Sample=sample, RefAccel=vec(ref_acc), RefMag=vec(ref_mag), Blend=blend,
           SamplePeriodS=dt)
        out = qrow(fb.Orientation)
        assert is_unit(out)
        if not (period_ok(dt) and 0.0 <= blend <= 1.0):
            code = BAD_PARAMETER
        else:
            code = sample_code(sample, True)
            if code == 0 and not triad_ok(vrow(sample["Accel"]), vrow(sample["Mag"])):
                code = PARALLEL
        assert fb.ErrorId == code and fb.Error == (code != 0)
        if code:
            rejected += 1
            assert np.array_equal(out, prev) and fb.Valid == valid
        else:
            acc, mag = vrow(sample["Accel"]), vrow(sample["Mag"])
            qa = Rotation.from_matrix(triad.estimate(acc, mag).T).as_quat(scalar_first=True)
            assert angle_deg(qrow(fb.QuatAccelMag), qa) < 3e-4
            if not valid:
                want = qa
            else:
                qg = (rot(prev) * Rotation.from_rotvec(np.radians(vrow(sample["Gyro"])) * dt)
                      ).as_quat(scalar_first=True)
                qa = qa if np.dot(qa, qg) >= 0.0 else -qa
                mix = blend * qg + (1.0 - blend) * qa
                want = mix / np.linalg.norm(mix)
            assert angle_deg(out, want) < 5e-4
            valid = True
        assert fb.Valid == valid and fb.Rejected == rejected
        prev = out


def madgwick_residual(q: np.ndarray, acc: np.ndarray, mag: np.ndarray, marg: bool) -> float:
    """|f| of Madgwick's objective (gravity, and the field with b = (|h_xy|, 0, h_z))."""
    r = rot(q / np.linalg.norm(q))
    f = r.inv().apply([0.0, 0.0, 1.0]) - acc / np.linalg.norm(acc)
    if marg:
        m = mag / np.linalg.norm(mag)
        h = r.apply(m)
        b = np.array([math.hypot(h[0], h[1]), 0.0, h[2]])
        f = np.r_[f, r.inv().apply(b) - m]
    return float(np.linalg.norm(f))


betas = st.one_of(st.floats(0.0, 10.0, width=32), st.sampled_from(
    [0.033, 0.0, 10.0, f32(10.000001), -0.01, math.nan]))


@pytest.mark.parametrize("kind", ["MadgwickImu", "MadgwickMarg"])
@examples(50)
@given(q0=unit_quats, samples=st.lists(st.tuples(imu_samples(), periods), min_size=1,
                                       max_size=20),
       beta=betas, from_sensors=st.booleans())
def test_madgwick_sample_by_sample(st_module: Any, kind: str, q0: np.ndarray,
                                   samples: list[tuple[dict[str, Any], float]], beta: float,
                                   from_sensors: bool) -> None:
    """One update per sample equal to ahrs 0.4.0's updateIMU / updateMARG from the block's
    previous output (a zero gyro run through ahrs as 1e-30 rad/s: ahrs skips the whole update
    at exactly 0, the ST still corrects, see the header)."""
    marg = kind == "MadgwickMarg"
    fb = st_module.new_fb(kind)
    fb(Reset=True, InitialQuat=quat(q0), InitFromSensors=from_sensors)
    prev, pending, rejected, beta = qrow(fb.Orientation), from_sensors, 0, f32(beta)
    for sample, dt in samples:
        dt = f32(dt)
        fb(Reset=False, InitialQuat=quat(q0), InitFromSensors=from_sensors, Sample=sample,
           Beta=beta, SamplePeriodS=dt)
        out = qrow(fb.Orientation)
        assert is_unit(out)
        acc, mag, gyro = vrow(sample["Accel"]), vrow(sample["Mag"]), vrow(sample["Gyro"])
        code = BAD_PARAMETER if not (period_ok(dt) and 0.0 <= beta <= 10.0) else sample_code(
            sample, marg)
        if marg and pending and code == 0 and not triad_ok(acc, mag):
            code = PARALLEL
        assert fb.ErrorId == code and fb.Error == (code != 0)
        if code:
            rejected += 1
            assert np.array_equal(out, prev)
        elif pending:
            if marg:
                a_mat = ahrs_filters.TRIAD(v1=np.array([0.0, 0.0, 1.0]),
                                           v2=np.array([1.0, 0.0, 0.0])).estimate(acc, mag)
                want = Rotation.from_matrix(a_mat.T).as_quat(scalar_first=True)
                assert angle_deg(out, want) < 3e-4
            else:
                u = acc / np.linalg.norm(acc)
                if u[2] > -0.9999:
                    # the tilt's axis is resolved to float32 over 1 + u_z: it loosens as the
                    # accelerometer turns towards -Z
                    tol = 3e-6 + 1e-9 / (1.0 + u[2])
                    assert np.abs(rot(out).apply(u) - [0.0, 0.0, 1.0]).max() < tol
            pending = False
        else:
            # ahrs refuses a zero gain: 1e-30 leaves its correction term below any float
            mw = ahrs_filters.Madgwick(Dt=float(dt), gain=max(float(beta), 1e-30))
            gyr = np.radians(gyro) if np.any(gyro) else np.full(3, 1e-30)
            want = np.asarray(mw.updateMARG(prev, gyr, acc, mag) if marg else
                              mw.updateIMU(prev, gyr, acc), dtype=float)
            resid = madgwick_residual(prev, acc, mag, marg)
            if np.isfinite(want).all() and resid > 1e-3:
                want = want if np.dot(want, out) >= 0.0 else -want
                # float32: a few ulps of each component, and the float32 gradient's
                # direction resolved to ~1e-7 / |f| of the step Beta * dt
                assert np.abs(out - want).max() < 2e-5 + beta * dt * 1e-6 / resid
            else:
                # at (or next to) the filter's fixed point the normalised gradient has no
                # direction (ahrs divides 0 by 0): the correction is at most Beta * dt
                gyro_only = prev + 0.5 * hamilton(prev, np.r_[0.0, np.radians(gyro)]) * dt
                gyro_only /= np.linalg.norm(gyro_only)
                assert np.linalg.norm(out - gyro_only) <= 2.0 * beta * dt + 2e-5
        assert fb.Rejected == rejected
        prev = out


# --- Follower settings ------------------------------------------------------------------------

@examples(400)
@given(dead=real(0.0, 90.0), rate=real(0.0, 3600.0), acc=real(0.0, 1e6), cycle=real(0.0, 1.0),
       jerk=st.one_of(st.just(0.0), real(0.0, 1e7)))
def test_tool_follower_settings_ok(st_module: Any, dead: float, rate: float, acc: float,
                                   cycle: float, jerk: float) -> None:
    dead, rate, acc, cycle, jerk = f32(dead), f32(rate), f32(acc), f32(cycle), f32(jerk)
    # a jerk limit (0 = none, up to 1e7) only with an acceleration limit
    want = (0.0 <= dead <= 90.0 and 0.0 < rate <= 3600.0 and 0.0 <= acc <= 1e6
            and 0.0 < cycle <= 1.0 and 0.0 <= jerk <= 1e7 and (jerk <= 0.0 or acc > 0.0))
    assert st_module.call("ToolFollowerSettingsOk", dead, rate, acc, cycle, jerk) is want


@pytest.mark.parametrize("gyro", [(0.0, 130591.0, 999982.0), (1.0e6, 1.0e6, 1.0e6),
                                  (-7.0e5, 3.0e5, -9.9e5)])
def test_gyro_step_turns_beyond_a_million_degrees(st_module: Any,
                                                  gyro: tuple[float, float, float]) -> None:
    """The header takes each rate component up to 1e6 deg/s for up to 1 s: a turn of up to
    1.7e6 deg, beyond what QuatFromAxisAngle takes. It was the identity (113 deg off for the
    first case); whole turns are dropped first now."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    got = qrow(st_module.call("QuatIntegrateGyro", quat(q), vec(np.array(gyro)), 1.0))
    want = rot(q) * Rotation.from_rotvec(np.radians(np.array(gyro)))
    turn = float(np.linalg.norm(gyro))
    assert angle_deg(got, want.as_quat(scalar_first=True)) < 3e-4 + 4.0 * float(
        np.spacing(np.float32(turn)))


@pytest.mark.parametrize("q", [(0.0, 0.0, 0.0, math.nan), (0.0, math.nan, 0.0, 0.0),
                               (math.nan, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)])
def test_quat_norm_of_a_nan_behind_zeros_is_nan(st_module: Any,
                                                q: tuple[float, float, float, float]) -> None:
    """'NaN in gives NaN out': a NaN after zero components was skipped by the largest-component
    search and the norm came out 0.0."""
    norm = st_module.call("QuatNorm", quat(np.array(q)))
    assert math.isnan(norm) if any(math.isnan(v) for v in q) else norm == 0.0
