"""Simulated hand-held IMU of document 004: an MPU6050 (gyro + accelerometer) and an
HMC5883L (magnetometer) with aligned axes, read at a fixed rate.

The hand's orientation is known exactly (`HandTrajectory`: Z-Y-X Euler angles that are sums
of sines, so the body angular rate has a closed form), and `simulate` turns it into the 16-bit
register values the chips would deliver, with white noise, a constant gyro bias and a bias
random walk (drift), from a seeded generator. Tests compare the filters' output with
`ImuRecord.quat_true`.

Frames and conventions are those of st/Quaternion.st: the quaternion rotates sensor (body)
vectors into the earth frame, earth Z up, X towards magnetic north. An accelerometer at rest
measures the specific force, +1 g along earth Z, i.e. ``R^T (0, 0, 1)`` in the body frame; the
magnetometer measures ``R^T h`` with ``h = B (cos dip, 0, -sin dip)`` (field pointing down into
the ground in the northern hemisphere).

Scale factors (datasheets):

* MPU6050 gyro, FS_SEL = 0 (±250 °/s): 131 LSB per °/s; FS_SEL 1/2/3: 65.5, 32.8, 16.4.
* MPU6050 accelerometer, AFS_SEL = 0 (±2 g): 16384 LSB/g; AFS_SEL 1/2/3: 8192, 4096, 2048.
  Both are 16-bit two's complement: a reading beyond full scale sticks at -32768 or 32767.
* HMC5883L, gain setting 1 (±1.3 Ga, the default): 1090 LSB/gauss; the data registers hold
  -2048..2047 and read -4096 on overflow.
* Noise (MPU6050 typicals): gyro rate noise density 0.005 °/s/√Hz, accelerometer 400 µg/√Hz;
  HMC5883L noise floor about 2 mG.

The defaults here are deliberately rougher than those typicals (gyro bias left after a poor
calibration, a visible bias drift) so that the drift of gyro-only integration shows within a
minute, as document 004 found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

MPU6050_GYRO_LSB_PER_DPS = {250: 131.0, 500: 65.5, 1000: 32.8, 2000: 16.4}
MPU6050_ACCEL_LSB_PER_G = {2: 16384.0, 4: 8192.0, 8: 4096.0, 16: 2048.0}
HMC5883L_LSB_PER_GAUSS = {0.88: 1370.0, 1.3: 1090.0, 1.9: 820.0, 2.5: 660.0, 4.0: 440.0,
                          4.7: 390.0, 5.6: 330.0, 8.1: 230.0}
INT16_MIN, INT16_MAX = -32768, 32767
HMC5883L_MIN, HMC5883L_MAX, HMC5883L_OVERFLOW = -2048, 2047, -4096


class ImuConfigError(ValueError):
    """A simulation parameter is out of its documented range."""


@dataclass(frozen=True)
class HandTrajectory:
    """Orientation of the hand: roll, pitch and yaw (Z-Y-X, deg) as sums of sines.

    Each angle is ``offset + sum(amp_i * sin(2 pi f_i t + phase_i))``. Pitch must stay inside
    ±80° (the Z-Y-X rate formula is singular at ±90°).
    """

    roll: tuple[tuple[float, float, float], ...] = ((40.0, 0.11, 0.0), (15.0, 0.37, 1.0))
    pitch: tuple[tuple[float, float, float], ...] = ((30.0, 0.07, 0.5), (10.0, 0.23, 2.0))
    yaw: tuple[tuple[float, float, float], ...] = ((70.0, 0.05, 0.3), (20.0, 0.19, 0.8))
    roll_offset_deg: float = 0.0
    pitch_offset_deg: float = 0.0
    yaw_offset_deg: float = 10.0

    def __post_init__(self) -> None:
        worst = abs(self.pitch_offset_deg) + sum(abs(a) for a, _, _ in self.pitch)
        if worst > 80.0:
            raise ImuConfigError(f"pitch may reach {worst:.1f} deg; keep offset + amplitudes "
                                 "within 80 deg (Z-Y-X angles are singular at 90)")

    @staticmethod
    def _series(terms: tuple[tuple[float, float, float], ...], offset: float,
                t: FloatArray) -> tuple[FloatArray, FloatArray]:
        value = np.full_like(t, offset)
        rate = np.zeros_like(t)
        for amp, freq, phase in terms:
            w = 2.0 * math.pi * freq
            value = value + amp * np.sin(w * t + phase)
            rate = rate + amp * w * np.cos(w * t + phase)
        return np.radians(value), np.radians(rate)

    def angles(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                              FloatArray, FloatArray, FloatArray]:
        """roll, pitch, yaw (rad) and their time derivatives (rad/s) at times t (s)."""
        r, dr = self._series(self.roll, self.roll_offset_deg, t)
        p, dp = self._series(self.pitch, self.pitch_offset_deg, t)
        y, dy = self._series(self.yaw, self.yaw_offset_deg, t)
        return r, p, y, dr, dp, dy

    def quaternions(self, t: FloatArray) -> FloatArray:
        """True orientation (sensor to earth), N x 4, scalar first, W >= 0."""
        r, p, y, _, _, _ = self.angles(t)
        return euler_zyx_to_quat(r, p, y)

    def body_rates_dps(self, t: FloatArray) -> FloatArray:
        """Angular rate in the body frame, deg/s, N x 3 (closed form of the Z-Y-X rates)."""
        r, p, _, dr, dp, dy = self.angles(t)
        wx = dr - dy * np.sin(p)
        wy = dp * np.cos(r) + dy * np.cos(p) * np.sin(r)
        wz = -dp * np.sin(r) + dy * np.cos(p) * np.cos(r)
        return np.degrees(np.stack([wx, wy, wz], axis=1))


def euler_zyx_to_quat(roll: FloatArray, pitch: FloatArray, yaw: FloatArray) -> FloatArray:
    """q = qz(yaw) qy(pitch) qx(roll), scalar first, W >= 0."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    q = np.stack([cy * cp * cr + sy * sp * sr,
                  cy * cp * sr - sy * sp * cr,
                  cy * sp * cr + sy * cp * sr,
                  sy * cp * cr - cy * sp * sr], axis=-1)
    return np.asarray(np.where(q[..., :1] < 0, -q, q), dtype=np.float64)


def quat_to_matrix(q: FloatArray) -> FloatArray:
    """Rotation matrices (N x 3 x 3) of unit quaternions (N x 4, scalar first)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def angle_between_deg(q1: FloatArray, q2: FloatArray) -> FloatArray:
    """Rotation angle between orientations (deg, 0..180), row by row."""
    dot = np.abs(np.sum(q1 * q2, axis=-1)) / (np.linalg.norm(q1, axis=-1)
                                               * np.linalg.norm(q2, axis=-1))
    return np.asarray(np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0))), dtype=np.float64)


@dataclass(frozen=True)
class ImuModel:
    """Chip settings and error model. Rates in deg/s, accelerations in g, field in gauss."""

    gyro_range_dps: int = 250
    accel_range_g: int = 2
    mag_range_gauss: float = 1.3
    gyro_noise_dps: float = 0.05  # white noise, standard deviation per sample
    accel_noise_g: float = 0.004
    mag_noise_gauss: float = 0.003
    gyro_bias_dps: tuple[float, float, float] = (0.4, -0.3, 0.25)
    gyro_bias_walk_dps_per_sqrt_s: float = 0.01  # drift: bias random walk
    field_gauss: float = 0.5
    dip_deg: float = 60.0

    def __post_init__(self) -> None:
        if self.gyro_range_dps not in MPU6050_GYRO_LSB_PER_DPS:
            raise ImuConfigError(f"gyro_range_dps must be one of "
                                 f"{sorted(MPU6050_GYRO_LSB_PER_DPS)}, got {self.gyro_range_dps}")
        if self.accel_range_g not in MPU6050_ACCEL_LSB_PER_G:
            raise ImuConfigError(f"accel_range_g must be one of "
                                 f"{sorted(MPU6050_ACCEL_LSB_PER_G)}, got {self.accel_range_g}")
        if self.mag_range_gauss not in HMC5883L_LSB_PER_GAUSS:
            raise ImuConfigError(f"mag_range_gauss must be one of "
                                 f"{sorted(HMC5883L_LSB_PER_GAUSS)}, got {self.mag_range_gauss}")
        for name in ("gyro_noise_dps", "accel_noise_g", "mag_noise_gauss",
                     "gyro_bias_walk_dps_per_sqrt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ImuConfigError(f"{name} must be finite and >= 0, got {value}")
        if not (math.isfinite(self.field_gauss) and self.field_gauss > 0.0):
            raise ImuConfigError(f"field_gauss must be > 0, got {self.field_gauss}")
        if not -89.0 <= self.dip_deg <= 89.0:
            raise ImuConfigError(f"dip_deg must lie in -89..89 (the field must have a "
                                 f"horizontal part), got {self.dip_deg}")

    @property
    def gyro_lsb_per_dps(self) -> float:
        return MPU6050_GYRO_LSB_PER_DPS[self.gyro_range_dps]

    @property
    def accel_lsb_per_g(self) -> float:
        return MPU6050_ACCEL_LSB_PER_G[self.accel_range_g]

    @property
    def mag_lsb_per_gauss(self) -> float:
        return HMC5883L_LSB_PER_GAUSS[self.mag_range_gauss]

    @property
    def field_earth(self) -> FloatArray:
        dip = math.radians(self.dip_deg)
        return np.array([self.field_gauss * math.cos(dip), 0.0,
                         -self.field_gauss * math.sin(dip)])

    def calibration(self) -> dict[str, object]:
        """The ST ImuCalibration that undoes this model's scale factors (no bias removed)."""
        return {"GyroLsbPerDps": self.gyro_lsb_per_dps, "AccelLsbPerG": self.accel_lsb_per_g,
                "MagLsbPerGauss": self.mag_lsb_per_gauss}


@dataclass
class ImuRecord:
    """A simulated run: times, ground truth and the raw register values."""

    t: FloatArray  # s, N
    period_s: float
    quat_true: FloatArray  # N x 4, sensor to earth, scalar first
    gyro_true_dps: FloatArray  # N x 3, body rate without errors
    gyro_bias_dps: FloatArray  # N x 3, the bias actually added (constant + walk)
    gyro_raw: IntArray  # N x 3, MPU6050 register values
    accel_raw: IntArray  # N x 3
    mag_raw: IntArray  # N x 3, HMC5883L register values (-4096 = overflow)
    model: ImuModel = field(default_factory=ImuModel)

    def __len__(self) -> int:
        return len(self.t)

    def gyro_dps(self) -> FloatArray:
        return np.asarray(self.gyro_raw / self.model.gyro_lsb_per_dps, dtype=np.float64)

    def accel_g(self) -> FloatArray:
        return np.asarray(self.accel_raw / self.model.accel_lsb_per_g, dtype=np.float64)

    def mag_gauss(self) -> FloatArray:
        return np.asarray(self.mag_raw / self.model.mag_lsb_per_gauss, dtype=np.float64)


def _quantise_mpu(values: FloatArray, lsb: float) -> IntArray:
    raw = np.rint(values * lsb)
    return np.clip(raw, INT16_MIN, INT16_MAX).astype(np.int64)


def _quantise_hmc(values: FloatArray, lsb: float) -> IntArray:
    raw = np.rint(values * lsb).astype(np.int64)
    return np.where((raw < HMC5883L_MIN) | (raw > HMC5883L_MAX), HMC5883L_OVERFLOW, raw)


def simulate(trajectory: HandTrajectory, model: ImuModel, *, duration_s: float,
             rate_hz: float, seed: int) -> ImuRecord:
    """Sample the trajectory at `rate_hz` for `duration_s` with `model`'s errors.

    Sample k is taken at t = k / rate_hz; its gyro value is the rate at that instant, so a
    filter stepping from sample k-1 to k with the rate of sample k sees what a real IMU read
    at a fixed rate delivers.
    """
    if not (math.isfinite(rate_hz) and 1.0 <= rate_hz <= 10_000.0):
        raise ImuConfigError(f"rate_hz must lie in 1..10000, got {rate_hz}")
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= 3600.0):
        raise ImuConfigError(f"duration_s must lie in (0, 3600], got {duration_s}")
    rng = np.random.default_rng(seed)
    period = 1.0 / rate_hz
    n = int(round(duration_s * rate_hz)) + 1
    t = np.arange(n, dtype=np.float64) * period
    quat = trajectory.quaternions(t)
    rates = trajectory.body_rates_dps(t)
    rot_t = np.transpose(quat_to_matrix(quat), (0, 2, 1))  # earth -> body
    accel = rot_t @ np.array([0.0, 0.0, 1.0])
    mag = rot_t @ model.field_earth
    walk = np.cumsum(rng.normal(0.0, model.gyro_bias_walk_dps_per_sqrt_s * math.sqrt(period),
                                size=(n, 3)), axis=0)
    bias = np.asarray(model.gyro_bias_dps, dtype=np.float64) + walk
    gyro_meas = rates + bias + rng.normal(0.0, model.gyro_noise_dps, size=(n, 3))
    accel_meas = accel + rng.normal(0.0, model.accel_noise_g, size=(n, 3))
    mag_meas = mag + rng.normal(0.0, model.mag_noise_gauss, size=(n, 3))
    return ImuRecord(
        t=t, period_s=period, quat_true=quat, gyro_true_dps=rates, gyro_bias_dps=bias,
        gyro_raw=_quantise_mpu(gyro_meas, model.gyro_lsb_per_dps),
        accel_raw=_quantise_mpu(accel_meas, model.accel_lsb_per_g),
        mag_raw=_quantise_hmc(mag_meas, model.mag_lsb_per_gauss),
        model=model)
