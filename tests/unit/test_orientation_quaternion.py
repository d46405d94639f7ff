"""st/Quaternion.st against scipy.spatial.transform.Rotation (float64).

Every case runs the ST (REAL = float32) on float32 inputs and compares with scipy on the
same inputs. Tolerances: 4e-7 per component for single products/matrix entries (a few float32
ulp of 1.0: each entry is a sum of at most four products), 1e-5 deg for angles from ArcTan2/ASIN
(float32 rounding of the argument, amplified near the asin limits only inside the clamp), and
wider where the text says why.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from armbench.orientation import quat_dict, quat_row

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation
Slerp = pytest.importorskip("scipy.spatial.transform").Slerp

CASES = 300
TOL = 4.0e-7


def f32q(q: np.ndarray) -> np.ndarray:
    return np.asarray(q, dtype=np.float32).astype(np.float64)


def random_quats(n: int, seed: int) -> np.ndarray:
    q = Rotation.random(n, rng=seed).as_quat(scalar_first=True)
    return np.array([f32q(r / np.linalg.norm(r)) for r in q])


def sp(q: np.ndarray) -> Any:
    return Rotation.from_quat(q, scalar_first=True)


def same_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest component difference, up to the sign of the quaternion."""
    return float(min(np.abs(a - b).max(), np.abs(a + b).max()))


def test_product_matches_scipy_composition(st_module: Any) -> None:
    a, b = random_quats(CASES, 1), random_quats(CASES, 2)
    worst = 0.0
    for qa, qb in zip(a, b, strict=True):
        got = np.array(quat_row(st_module.call("QuatProduct", quat_dict(qa), quat_dict(qb))))
        want = (sp(qa) * sp(qb)).as_quat(scalar_first=True)
        worst = max(worst, same_rotation(got, want))
    print(f"\nQuatProduct: {CASES} cases, worst |dq| {worst:.2e}")
    assert worst < TOL


@pytest.mark.parametrize(("a", "b", "want"), [
    ((0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0)),   # i j = k
    ((0.0, 0.0, 1.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.0, -1.0)),  # j i = -k
    ((1.0, 2.0, 3.0, 4.0), (0.5, -1.0, 0.2, 0.1), (1.5, -0.5, -2.5, 5.5)),  # by hand
])
def test_product_unit_table(st_module: Any, a: tuple[float, ...], b: tuple[float, ...],
                            want: tuple[float, ...]) -> None:
    got = quat_row(st_module.call("QuatProduct", quat_dict(a), quat_dict(b)))
    assert got == pytest.approx(want, abs=1e-6)


def test_conjugate_is_inverse(st_module: Any) -> None:
    for q in random_quats(50, 3):
        got = np.array(quat_row(st_module.call("QuatConjugate", quat_dict(q))))
        assert same_rotation(got, sp(q).inv().as_quat(scalar_first=True)) < TOL


def test_normalise_and_zero_guard(st_module: Any) -> None:
    rng = np.random.default_rng(4)
    for _ in range(100):
        q = f32q(rng.normal(size=4) * 10.0 ** rng.uniform(-6, 6))
        got = np.array(quat_row(st_module.call("QuatNormalise", quat_dict(q), quat_dict(
            [1.0, 0.0, 0.0, 0.0]))))
        assert np.abs(got - q / np.linalg.norm(q)).max() < TOL
    fallback = [0.0, 0.0, 2.0, 0.0]
    for bad in ([0.0, 0.0, 0.0, 0.0], [np.nan, 0.0, 0.0, 1.0], [np.inf, 0.0, 0.0, 0.0],
                [1e-13, 0.0, 0.0, 0.0]):
        got = quat_row(st_module.call("QuatNormalise", quat_dict(bad), quat_dict(fallback)))
        assert got == [0.0, 0.0, 1.0, 0.0]
    got = quat_row(st_module.call("QuatNormalise", quat_dict([0.0] * 4),
                                  quat_dict([np.nan] * 4)))
    assert got == [1.0, 0.0, 0.0, 0.0]
    # huge components: scaled before squaring, no overflow to inf
    got = quat_row(st_module.call("QuatNormalise", quat_dict([3e29, 4e29, 0.0, 0.0]),
                                  quat_dict([1.0, 0.0, 0.0, 0.0])))
    assert got == pytest.approx([0.6, 0.8, 0.0, 0.0], abs=1e-6)


def test_from_axis_angle_matches_rotvec(st_module: Any) -> None:
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(CASES):
        axis = f32q(rng.normal(size=3))
        angle = float(np.float32(rng.uniform(-400.0, 400.0)))
        got = np.array(quat_row(st_module.call("QuatFromAxisAngle", *axis, angle)))
        want = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(angle)).as_quat(
            scalar_first=True)
        worst = max(worst, same_rotation(got, want))
    print(f"\nQuatFromAxisAngle: {CASES} cases, worst |dq| {worst:.2e}")
    assert worst < 2e-6  # float32 sin/cos of angles up to 3.5 rad: a few ulp of the argument
    assert quat_row(st_module.call("QuatFromAxisAngle", 0.0, 0.0, 0.0, 30.0)) == [1, 0, 0, 0]
    assert quat_row(st_module.call("QuatFromAxisAngle", np.nan, 0.0, 1.0, 30.0)) == [1, 0, 0, 0]


def test_matrix_round_trip_matches_scipy(st_module: Any) -> None:
    worst_m = worst_q = 0.0
    for q in random_quats(CASES, 6):
        m = np.array(st_module.call("QuatToMatrix", quat_dict(q)))
        worst_m = max(worst_m, float(np.abs(m - sp(q).as_matrix()).max()))
        back, _ = st_module.call_full("QuatFromMatrix", Rm=sp(q).as_matrix().tolist())
        worst_q = max(worst_q, same_rotation(np.array(quat_row(back)), q))
        assert back["W"] >= 0.0
    print(f"\nQuatToMatrix worst {worst_m:.2e}; QuatFromMatrix worst {worst_q:.2e}")
    assert worst_m < 1e-6
    assert worst_q < 1e-6
    # the four branches of Shepperd's method: 180 deg about x, y, z and the identity
    for axis in np.eye(3):
        q = Rotation.from_rotvec(axis * np.pi).as_quat(scalar_first=True)
        back, _ = st_module.call_full("QuatFromMatrix", Rm=sp(q).as_matrix().tolist())
        assert same_rotation(np.array(quat_row(back)), q) < 1e-6


def test_roll_pitch_yaw_matches_scipy_zyx(st_module: Any) -> None:
    worst = 0.0
    for q in random_quats(CASES, 7):
        got = st_module.call("QuatToRollPitchYaw", quat_dict(q))
        yaw, pitch, roll = sp(q).as_euler("ZYX", degrees=True)
        if abs(pitch) > 89.0:
            continue  # gimbal lock: roll and yaw are not unique (checked below)
        for a, b in ((got["RollDeg"], roll), (got["PitchDeg"], pitch), (got["YawDeg"], yaw)):
            worst = max(worst, abs((a - b + 180.0) % 360.0 - 180.0))
    print(f"\nQuatToRollPitchYaw worst {worst:.2e} deg")
    assert worst < 2e-3  # ASIN near +/-89 deg amplifies a 1-ulp argument error to 1e-3 deg
    # straight up: pitch clamps to -90, never NaN, and the angles rebuild the rotation
    q = Rotation.from_euler("ZYX", [30.0, -90.0, 0.0], degrees=True).as_quat(scalar_first=True)
    got = st_module.call("QuatToRollPitchYaw", quat_dict(f32q(q)))
    assert got["PitchDeg"] == pytest.approx(-90.0, abs=0.05)
    rebuilt = Rotation.from_euler("ZYX", [got["YawDeg"], got["PitchDeg"], got["RollDeg"]],
                                  degrees=True)
    assert (rebuilt.inv() * sp(q)).magnitude() < np.radians(0.1)


def test_pitch_near_the_lock_matches_scipy(st_module: Any) -> None:
    """Between the lock band (0.0573 deg) and 3 deg from pitch +/-90 the pitch is as exact
    as a REAL angle of 90 deg can be: it comes from atan2 of the matrix's pitch sine and its
    column norm, whose rounding does not grow near the lock (asin of the sine alone turned
    the 2.4e-7 error of its argument into 2.4e-7 / cos(pitch) rad: 0.011 deg at 0.07 deg from
    the lock). Reference: scipy on the same float32 quaternion, in float64."""
    rng = np.random.default_rng(12)
    worst = 0.0
    for _ in range(400):
        off = 10.0 ** rng.uniform(np.log10(0.07), np.log10(3.0))
        pitch = rng.choice([-1.0, 1.0]) * (90.0 - off)
        yaw, roll = rng.uniform(-180.0, 180.0, 2)
        q = f32q(Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)
                 .as_quat(scalar_first=True))
        got = st_module.call("QuatToRollPitchYaw", quat_dict(q))
        want = sp(q / np.linalg.norm(q)).as_euler("ZYX", degrees=True)[1]
        worst = max(worst, abs(got["PitchDeg"] - want))
    print(f"\npitch within 3 deg of the lock: worst {worst:.2e} deg")
    assert worst < 5e-5  # a few ulps of 90.0 in REAL (7.6e-6)


def test_angle_between_matches_scipy(st_module: Any) -> None:
    a, b = random_quats(CASES, 8), random_quats(CASES, 9)
    for qa, qb in zip(a, b, strict=True):
        got = st_module.call("QuatAngleDeg", quat_dict(qa), quat_dict(qb))
        assert got == pytest.approx(np.degrees((sp(qa).inv() * sp(qb)).magnitude()), abs=1e-4)
    tiny = f32q(Rotation.from_rotvec([1e-4, 0.0, 0.0]).as_quat(scalar_first=True))
    got = st_module.call("QuatAngleDeg", quat_dict([1.0, 0, 0, 0]), quat_dict(tiny))
    assert got == pytest.approx(np.degrees(1e-4), rel=1e-3)  # acos would give 0 here


def test_slerp_matches_scipy(st_module: Any) -> None:
    a, b = random_quats(100, 10), random_quats(100, 11)
    worst = 0.0
    for qa, qb in zip(a, b, strict=True):
        slerp = Slerp([0.0, 1.0], Rotation.concatenate([sp(qa), sp(qb)]))
        for t in (0.0, 0.25, 0.5, 0.9, 1.0):
            got = np.array(quat_row(st_module.call("QuatSlerp", quat_dict(qa), quat_dict(qb), t)))
            want = slerp([t])[0].as_quat(scalar_first=True)
            worst = max(worst, same_rotation(got, want))
    print(f"\nQuatSlerp worst {worst:.2e}")
    assert worst < 2e-6
    # T outside 0..1 or NaN is clamped
    qa, qb = a[0], b[0]
    assert same_rotation(np.array(quat_row(st_module.call(
        "QuatSlerp", quat_dict(qa), quat_dict(qb), np.nan))), qa) < TOL
    assert same_rotation(np.array(quat_row(st_module.call(
        "QuatSlerp", quat_dict(qa), quat_dict(qb), 7.0))), qb) < 2e-6
    # nearly equal quaternions (below the sine threshold): still unit, between the two
    qc = f32q((sp(qa) * Rotation.from_rotvec([1e-6, 0, 0])).as_quat(scalar_first=True))
    got = np.array(quat_row(st_module.call("QuatSlerp", quat_dict(qa), quat_dict(qc), 0.5)))
    assert np.linalg.norm(got) == pytest.approx(1.0, abs=1e-6)
    assert same_rotation(got, qa) < 1e-6


def test_tool_direction_is_first_matrix_column(st_module: Any) -> None:
    for q in random_quats(CASES, 12):
        got = st_module.call("QuatToolDirection", quat_dict(q))
        want = sp(q).apply([1.0, 0.0, 0.0])
        assert [got["X"], got["Y"], got["Z"]] == pytest.approx(want, abs=1e-6)


def test_from_roll_pitch_yaw_matches_scipy_zyx(st_module: Any) -> None:
    rng = np.random.default_rng(11)
    worst = 0.0
    for roll, pitch, yaw in rng.uniform(-180.0, 180.0, size=(CASES, 3)):
        got = np.array(quat_row(st_module.call("QuatFromRollPitchYaw", float(roll),
                                               float(pitch), float(yaw))))
        want = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)
        worst = max(worst, same_rotation(got, want.as_quat(scalar_first=True)))
    print(f"\nQuatFromRollPitchYaw worst {worst:.2e}")
    assert worst < 1e-6
