"""st/MG996R.st against the MG996R data of document 002.

Reference: 1000 us = -60 deg, 1500 us = 0 deg, 2000 us = +60 deg, linear in between
(8.333 us/deg), servo angle = Direction * (joint angle - ZeroOffsetDeg).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from float32_support import DEFAULT_CAL

NO_ERROR, NOT_FINITE, BAD_CALIBRATION = 0, 3, 5



def cal(**changes: Any) -> dict[str, Any]:
    out = dict(DEFAULT_CAL)
    out.update(changes)
    return out


def reference_pulse(joint_deg: float, c: dict[str, Any]) -> float:
    servo = (joint_deg - c["ZeroOffsetDeg"]) * (1.0 if c["Direction"] >= 0 else -1.0)
    servo = min(max(servo, c["MinAngleDeg"]), c["MaxAngleDeg"])
    slope = (c["MaxPulseUs"] - c["MinPulseUs"]) / (c["MaxAngleDeg"] - c["MinAngleDeg"])
    return float(c["MinPulseUs"] + (servo - c["MinAngleDeg"]) * slope)


def test_exact_end_points_and_centre(st_module: Any) -> None:
    for angle, pulse in ((-60.0, 1000.0), (0.0, 1500.0), (60.0, 2000.0)):
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=angle, Calibration=DEFAULT_CAL)
        assert got["PulseUs"] == pulse  # exact, not approximately
        assert not got["Clamped"] and not got["Error"] and got["ErrorId"] == NO_ERROR
        back = st_module.call("MG996R_PulseToAngle", PulseUs=pulse, Calibration=DEFAULT_CAL)
        assert back["JointAngleDeg"] == angle
        assert not back["Clamped"] and not back["Error"]
    # 8.333 us per degree in between
    got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=30.0, Calibration=DEFAULT_CAL)
    assert got["PulseUs"] == pytest.approx(1750.0, abs=1e-3)


def test_matches_reference_and_monotonic(st_module: Any) -> None:
    sweep = np.arange(-60.0, 60.0001, 0.25)
    for c, increasing in (
        (DEFAULT_CAL, True),
        (cal(Direction=-1), False),
        (cal(ZeroOffsetDeg=90.0), True),
        (cal(ZeroOffsetDeg=-30.0, Direction=-1, MinPulseUs=900.0, MaxPulseUs=2100.0), False),
    ):
        offset = c["ZeroOffsetDeg"]
        pulses = []
        worst = 0.0
        for a in sweep:
            joint = offset + float(a)
            got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=joint, Calibration=c)
            assert not got["Clamped"] and not got["Error"]
            worst = max(worst, abs(got["PulseUs"] - reference_pulse(joint, c)))
            pulses.append(got["PulseUs"])
        diffs = np.diff(pulses)
        assert (diffs > 0).all() if increasing else (diffs < 0).all()
        assert worst < 1e-3, worst


def test_clamping_raises_flag(st_module: Any) -> None:
    for angle, pulse in ((-60.5, 1000.0), (-1000.0, 1000.0), (61.0, 2000.0), (1.0e6, 2000.0)):
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=angle, Calibration=DEFAULT_CAL)
        assert got["Clamped"] and not got["Error"]
        assert got["PulseUs"] == pulse
        assert got["ServoAngleDeg"] == math.copysign(60.0, angle)
    for pulse, angle in ((999.0, -60.0), (0.0, -60.0), (2000.5, 60.0), (20000.0, 60.0)):
        back = st_module.call("MG996R_PulseToAngle", PulseUs=pulse, Calibration=DEFAULT_CAL)
        assert back["Clamped"] and not back["Error"]
        assert back["JointAngleDeg"] == angle
    # Reversed servo with an offset: the joint limits move accordingly.
    c = cal(ZeroOffsetDeg=90.0, Direction=-1)
    got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=160.0, Calibration=c)  # servo -70
    assert got["Clamped"] and got["PulseUs"] == 1000.0
    got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=140.0, Calibration=c)  # servo -50
    assert not got["Clamped"]
    assert got["PulseUs"] == pytest.approx(1500.0 - 50.0 * 500.0 / 60.0, abs=1e-3)


def test_round_trip_angle_pulse_angle(st_module: Any) -> None:
    rng = np.random.default_rng(11)
    worst = 0.0
    for c in (
        DEFAULT_CAL,
        cal(ZeroOffsetDeg=90.0, Direction=-1),
        cal(MinAngleDeg=-45.0, MinPulseUs=1125.0),
    ):
        lo = c["ZeroOffsetDeg"] + c["MinAngleDeg"]
        hi = c["ZeroOffsetDeg"] + c["MaxAngleDeg"]
        if c["Direction"] < 0:
            lo, hi = c["ZeroOffsetDeg"] - c["MaxAngleDeg"], c["ZeroOffsetDeg"] - c["MinAngleDeg"]
        for joint in rng.uniform(lo, hi, 1000):
            pulse = st_module.call("MG996R_AngleToPulse", JointAngleDeg=float(joint), Calibration=c)
            back = st_module.call("MG996R_PulseToAngle", PulseUs=pulse["PulseUs"], Calibration=c)
            worst = max(worst, abs(back["JointAngleDeg"] - joint))
    print(f"\nMG996R angle -> us -> angle: worst {worst:.3e} deg over 3000 angles")
    assert worst < 1e-3


def test_non_finite_and_bad_calibration(st_module: Any) -> None:
    for bad in (math.nan, math.inf, -math.inf):
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=bad, Calibration=DEFAULT_CAL)
        assert got["Error"] and got["ErrorId"] == NOT_FINITE and got["PulseUs"] == 0.0
        back = st_module.call("MG996R_PulseToAngle", PulseUs=bad, Calibration=DEFAULT_CAL)
        assert back["Error"] and back["ErrorId"] == NOT_FINITE
        assert back["JointAngleDeg"] == 0.0
    for c in (
        cal(MinAngleDeg=60.0, MaxAngleDeg=-60.0),
        cal(MinPulseUs=2000.0, MaxPulseUs=1000.0),
        cal(MaxPulseUs=25000.0),
        cal(MinPulseUs=-10.0),
    ):
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=0.0, Calibration=c)
        assert got["Error"] and got["ErrorId"] == BAD_CALIBRATION and got["PulseUs"] == 0.0
        back = st_module.call("MG996R_PulseToAngle", PulseUs=1500.0, Calibration=c)
        assert back["Error"] and back["ErrorId"] == BAD_CALIBRATION
        assert st_module.call("ServoCalibrationCheck", c) == BAD_CALIBRATION
    got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=0.0,
                         Calibration=cal(MinPulseUs=math.nan))
    assert got["Error"] and got["ErrorId"] == NOT_FINITE
    assert st_module.call("ServoCalibrationCheck", DEFAULT_CAL) == NO_ERROR
