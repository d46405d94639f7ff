"""Ground truth: the orientation error of each ST method on one noisy simulated hand motion.

Document 004 found that gyro-only integration drifts and that its complementary filter and
Madgwick's filter do not. The simulated IMU (armbench.plant.imu) knows the true orientation;
its gyro has a 0.56 deg/s bias (|(0.4, -0.3, 0.25)|) plus a random walk, so integrating it
alone must drift by tens of degrees a minute, while the filters that see gravity and the field
stay within a degree. Madgwick's IMU form (no magnetometer) keeps the tilt but not the
heading: its yaw drifts like the gyro's. The figures are printed (run with -s) and drawn by
``python -m armbench.plots.orientation`` for docs/orientation.md (checked in
tests/docs/test_figure_scripts.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from armbench.orientation import METHODS, run_filter, st_samples
from armbench.plant.imu import HandTrajectory, ImuModel, quat_to_matrix, simulate

DURATION_S = 60.0
RATE_HZ = 100.0


@pytest.fixture(scope="module")
def runs(st_module: Any) -> dict[str, Any]:
    record = simulate(HandTrajectory(), ImuModel(), duration_s=DURATION_S, rate_hz=RATE_HZ,
                      seed=11)
    samples = st_samples(st_module, record)
    out: dict[str, Any] = {"record": record}
    for method in METHODS:
        out[method] = run_filter(st_module, method, samples, record.period_s,
                                 record.quat_true[0])
    return out


def tilt_error_deg(q: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Angle between the estimated and the true 'up' direction in the body frame."""
    up = np.array([0.0, 0.0, 1.0])
    a = np.transpose(quat_to_matrix(q), (0, 2, 1)) @ up
    b = np.transpose(quat_to_matrix(truth), (0, 2, 1)) @ up
    return np.asarray(np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))))


def window(err: np.ndarray, t: np.ndarray, lo: float, hi: float) -> float:
    return float(np.mean(err[(t >= lo) & (t < hi)]))


def test_gyro_drifts_and_the_filters_do_not(runs: dict[str, Any]) -> None:
    record = runs["record"]
    t, truth = record.t, record.quat_true
    errors = {m: runs[m].error_deg(truth) for m in METHODS}
    print(f"\nground-truth orientation error, deg ({DURATION_S:.0f} s at {RATE_HZ:.0f} Hz, "
          f"gyro bias {np.linalg.norm(record.model.gyro_bias_dps):.2f} deg/s + walk)")
    print(f"{'method':15} {'0-10 s':>8} {'20-30 s':>8} {'50-60 s':>8} {'max':>8}  "
          f"{'tilt 50-60 s':>12}")
    for m in METHODS:
        e = errors[m]
        tilt = tilt_error_deg(runs[m].quats, truth)
        print(f"{m:15} {window(e, t, 0, 10):8.3f} {window(e, t, 20, 30):8.3f} "
              f"{window(e, t, 50, 61):8.3f} {e.max():8.3f}  {window(tilt, t, 50, 61):12.3f}")
        assert np.all(np.isfinite(runs[m].quats))
        assert not runs[m].error_ids.any()
    gyro = errors["gyro"]
    assert window(gyro, t, 50, 61) > 10.0
    assert window(gyro, t, 50, 61) > 3.0 * window(gyro, t, 0, 10)
    for m in ("complementary", "madgwick_marg"):
        assert errors[m][t >= 10.0].max() < 2.0
        assert window(errors[m], t, 50, 61) < 1.0
    imu = runs["madgwick_imu"]
    assert window(tilt_error_deg(imu.quats, truth), t, 50, 61) < 1.0  # gravity fixes tilt
    assert window(errors["madgwick_imu"], t, 50, 61) > 5.0  # ... but not the heading
