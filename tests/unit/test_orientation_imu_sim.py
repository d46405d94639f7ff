"""The simulated MPU6050/HMC5883L (armbench.plant.imu): its ground truth against scipy, its
seeding, its error model and its parameter checks."""

from __future__ import annotations

import numpy as np
import pytest

from armbench.plant.imu import (
    HandTrajectory,
    ImuConfigError,
    ImuModel,
    quat_to_matrix,
    simulate,
)

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation


def test_truth_matches_scipy_euler_and_its_derivative() -> None:
    traj = HandTrajectory()
    t = np.linspace(0.0, 40.0, 97)
    q = traj.quaternions(t)
    r, p, y, _, _, _ = traj.angles(t)
    want = Rotation.from_euler("ZYX", np.column_stack([y, p, r]))
    assert np.allclose(quat_to_matrix(q), want.as_matrix(), atol=1e-12)
    # body rate: the rotation between t and t + h, seen in the body frame, over h
    h = 1e-6
    r1 = Rotation.from_quat(traj.quaternions(t + h), scalar_first=True)
    numeric = np.degrees((want.inv() * r1).as_rotvec() / h)
    assert np.allclose(traj.body_rates_dps(t), numeric, atol=1e-3)


def test_readings_are_the_truth_plus_the_documented_errors() -> None:
    model = ImuModel()
    rec = simulate(HandTrajectory(), model, duration_s=20.0, rate_hz=100.0, seed=4)
    rot_t = np.transpose(quat_to_matrix(rec.quat_true), (0, 2, 1))
    accel_true = rot_t @ np.array([0.0, 0.0, 1.0])
    mag_true = rot_t @ model.field_earth
    gyro_err = rec.gyro_dps() - rec.gyro_true_dps - rec.gyro_bias_dps
    accel_err = rec.accel_g() - accel_true
    mag_err = rec.mag_gauss() - mag_true
    # white noise plus quantisation (one LSB uniform: sd = LSB / sqrt(12))
    for err, sd, lsb in ((gyro_err, model.gyro_noise_dps, 1 / 131.0),
                         (accel_err, model.accel_noise_g, 1 / 16384.0),
                         (mag_err, model.mag_noise_gauss, 1 / 1090.0)):
        want = np.sqrt(sd ** 2 + lsb ** 2 / 12.0)
        assert np.std(err) == pytest.approx(want, rel=0.05)
        assert abs(np.mean(err)) < 4 * want / np.sqrt(err.size)
    # the bias starts at the constant and wanders by the random walk
    assert rec.gyro_bias_dps[0] == pytest.approx(model.gyro_bias_dps, abs=0.01)
    walk = np.diff(rec.gyro_bias_dps, axis=0)
    assert np.std(walk) == pytest.approx(model.gyro_bias_walk_dps_per_sqrt_s * np.sqrt(0.01),
                                         rel=0.05)


def test_seeded() -> None:
    a = simulate(HandTrajectory(), ImuModel(), duration_s=2.0, rate_hz=100.0, seed=9)
    b = simulate(HandTrajectory(), ImuModel(), duration_s=2.0, rate_hz=100.0, seed=9)
    c = simulate(HandTrajectory(), ImuModel(), duration_s=2.0, rate_hz=100.0, seed=10)
    assert np.array_equal(a.gyro_raw, b.gyro_raw) and np.array_equal(a.mag_raw, b.mag_raw)
    assert not np.array_equal(a.gyro_raw, c.gyro_raw)
    assert np.array_equal(a.quat_true, c.quat_true)


@pytest.mark.parametrize(("make", "words"), [
    (lambda: ImuModel(gyro_range_dps=300), "gyro_range_dps"),
    (lambda: ImuModel(accel_range_g=3), "accel_range_g"),
    (lambda: ImuModel(mag_range_gauss=1.0), "mag_range_gauss"),
    (lambda: ImuModel(gyro_noise_dps=-1.0), "gyro_noise_dps"),
    (lambda: ImuModel(field_gauss=0.0), "field_gauss"),
    (lambda: ImuModel(dip_deg=90.0), "dip_deg"),
    (lambda: HandTrajectory(pitch=((85.0, 0.1, 0.0),)), "pitch"),
    (lambda: simulate(HandTrajectory(), ImuModel(), duration_s=1.0, rate_hz=0.0, seed=0),
     "rate_hz"),
    (lambda: simulate(HandTrajectory(), ImuModel(), duration_s=-1.0, rate_hz=100.0, seed=0),
     "duration_s"),
])
def test_bad_parameters_say_what_to_fix(make: object, words: str) -> None:
    with pytest.raises(ImuConfigError, match=words):
        make()  # type: ignore[operator]
