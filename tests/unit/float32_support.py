"""Helpers shared by the unit suites: float32 values as the PLC holds them, the REAL range
IsFiniteReal accepts, hypothesis strategies over it, and the MG996R default calibration."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

FINITE_LIMIT = float(np.float32(1.0e30))  # IsFiniteReal compares with the REAL 1.0E30

# float32 values exactly (what the PLC holds)
F32_EXTREMES = [float(np.float32(v)) for v in (
    0.0, -0.0, 1.0, -1.0, 1.0e30, -1.0e30, 1.0000001e30, 3.4028235e38, -3.4028235e38,
    1.0e-45, math.nan, math.inf, -math.inf,
)]

DEFAULT_CAL: dict[str, Any] = {  # ServoCalibration's defaults: the MG996R data
    "ZeroOffsetDeg": 0.0,
    "Direction": 1,
    "MinPulseUs": 1000.0,
    "MaxPulseUs": 2000.0,
    "MinAngleDeg": -60.0,
    "MaxAngleDeg": 60.0,
}


def f32(x: float) -> float:
    return float(np.float32(x))


def finite(x: float) -> bool:
    return math.isfinite(x) and abs(x) <= FINITE_LIMIT


def any_real(extra: Sequence[float] = ()) -> Any:
    """Every float32, with the boundaries that matter (and ``extra``) drawn often."""
    from hypothesis import strategies as st

    return st.one_of(st.floats(width=32),
                     st.sampled_from(F32_EXTREMES + [f32(v) for v in extra]))
