"""The controller's IMU input conversion restated in float32, for the tests that compare the
PLC's filters with the ``ahrs`` package."""

from __future__ import annotations

import numpy as np

from armbench.plant.imu import ImuRecord


def float32_physical(record: ImuRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ImuRawToSample (st/OrientationFilters.st) with the default calibration, in float32
    (bit-identical to the PLC): gyro deg/s, accel g, mag gauss, as float64 arrays."""
    m = record.model

    def conv(raw: np.ndarray, lsb: float) -> np.ndarray:
        # the "- 0.0" is the PLC's subtraction of the default zero bias/offset, kept so the
        # expression is the ST's term for term (it is exact in IEEE arithmetic)
        return (raw.astype(np.float32) / np.float32(lsb) - np.float32(0.0)).astype(np.float64)

    return (conv(record.gyro_raw, m.gyro_lsb_per_dps), conv(record.accel_raw, m.accel_lsb_per_g),
            conv(record.mag_raw, m.mag_lsb_per_gauss))
