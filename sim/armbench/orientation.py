"""Run the ST orientation blocks (st/Quaternion.st, st/OrientationFilters.st) over a simulated
IMU record (armbench.plant.imu), for the tests, the figures and the benchmark.

The raw register values go through the ST's own ImuRawToSample, so the filters see exactly
the REAL values a PLC would; `physical_samples` returns those values as float arrays so that
a reference implementation (ahrs) can be fed the very same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from armbench.plant.imu import ImuRecord, angle_between_deg

FloatArray = npt.NDArray[np.float64]

# Default gains: the ahrs package's defaults (Madgwick's report suggests beta = sqrt(3/4)
# times the gyro error; 0.033 and 0.041 rad/s are the values of his own code).
MADGWICK_IMU_BETA = 0.033
MADGWICK_MARG_BETA = 0.041
COMPLEMENTARY_BLEND = 0.98

METHODS = ("gyro", "complementary", "madgwick_imu", "madgwick_marg")


def quat_dict(q: Sequence[float]) -> dict[str, float]:
    return {"W": float(q[0]), "X": float(q[1]), "Y": float(q[2]), "Z": float(q[3])}


def quat_row(d: dict[str, float]) -> list[float]:
    return [d["W"], d["X"], d["Y"], d["Z"]]


def vec_dict(v: Sequence[float]) -> dict[str, float]:
    return {"X": float(v[0]), "Y": float(v[1]), "Z": float(v[2])}


def raw_dict(record: ImuRecord, k: int) -> dict[str, int]:
    g, a, m = record.gyro_raw[k], record.accel_raw[k], record.mag_raw[k]
    return {"GyroX": int(g[0]), "GyroY": int(g[1]), "GyroZ": int(g[2]),
            "AccelX": int(a[0]), "AccelY": int(a[1]), "AccelZ": int(a[2]),
            "MagX": int(m[0]), "MagY": int(m[1]), "MagZ": int(m[2])}


def st_samples(module: Any, record: ImuRecord,
               calibration: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """ImuSample dicts from the ST ImuRawToSample, one per record sample."""
    cal = record.model.calibration() if calibration is None else calibration
    return [module.call("ImuRawToSample", Raw=raw_dict(record, k), Calibration=cal)
            for k in range(len(record))]


@dataclass
class PhysicalSamples:
    """The float32 values of the ST samples, as float64 arrays (N x 3)."""

    gyro_dps: FloatArray
    accel_g: FloatArray
    mag_gauss: FloatArray
    codes: npt.NDArray[np.int64]


def physical_samples(samples: Sequence[dict[str, Any]]) -> PhysicalSamples:
    def col(key: str) -> FloatArray:
        return np.array([[s[key]["X"], s[key]["Y"], s[key]["Z"]] for s in samples],
                        dtype=np.float64)
    return PhysicalSamples(col("Gyro"), col("Accel"), col("Mag"),
                           np.array([s["Code"] for s in samples], dtype=np.int64))


@dataclass
class FilterRun:
    """Output of one ST block over a record: one quaternion and ErrorId per sample."""

    method: str
    quats: FloatArray  # N x 4
    error_ids: npt.NDArray[np.int64]
    params: dict[str, float] = field(default_factory=dict)

    def error_deg(self, truth: FloatArray) -> FloatArray:
        return angle_between_deg(self.quats, truth)


def run_filter(module: Any, method: str, samples: Sequence[dict[str, Any]], period_s: float,
               initial: Sequence[float], *, beta: float | None = None,
               blend: float = COMPLEMENTARY_BLEND,
               ref_mag: Sequence[float] = (1.0, 0.0, 0.0)) -> FilterRun:
    """Run one block from `initial` (sample 0 only sets the start: the complementary filter
    starts at its accel+mag orientation of sample 0, the others at `initial`)."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    params: dict[str, float] = {"SamplePeriodS": period_s}
    if method == "gyro":
        fb = module.new_fb("GyroIntegrator")
    elif method == "complementary":
        fb = module.new_fb("ComplementaryFilter")
        params["Blend"] = blend
        fb.set(RefMag=vec_dict(ref_mag))
    elif method == "madgwick_imu":
        fb = module.new_fb("MadgwickImu")
        params["Beta"] = MADGWICK_IMU_BETA if beta is None else beta
    else:
        fb = module.new_fb("MadgwickMarg")
        params["Beta"] = MADGWICK_MARG_BETA if beta is None else beta
    fb.set(**params)
    if method == "complementary":
        fb(Reset=True)
        fb(Reset=False, Sample=samples[0])
    else:
        fb(Reset=True, InitialQuat=quat_dict(initial))
    quats = [quat_row(fb.Orientation)]
    codes = [int(fb.ErrorId)]
    for s in samples[1:]:
        fb(Reset=False, Sample=s)
        quats.append(quat_row(fb.Orientation))
        codes.append(int(fb.ErrorId))
    return FilterRun(method, np.array(quats, dtype=np.float64),
                     np.array(codes, dtype=np.int64), params)
