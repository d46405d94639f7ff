"""Property tests of st/MG996R.st and st/PCA9685.st over their whole documented input range.

For every public POU the property is: either the documented error code, or an answer within
the documented tolerance of an independent reference written here from the documents (the
MG996R data of document 002: a linear map through the two calibration points; the PCA9685
datasheet: prescale = round(osc / (4096 f)) - 1, one count = (prescale + 1) / osc). Inputs
include NaN, +/-Inf, the float32 extremes and the extremes of every integer type.

The calibration bounds (ServoCalibrationCheck) are restated here from the audit and the
header, not read from the ST: Direction exactly +1/-1, 500 <= MinPulseUs < MaxPulseUs <= 2500
us, -90 <= MinAngleDeg < MaxAngleDeg <= 90 deg, |ZeroOffsetDeg| <= 180 deg, scale
(MaxPulseUs - MinPulseUs) / (MaxAngleDeg - MinAngleDeg) within 5..15 us/deg.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

hypothesis = pytest.importorskip("hypothesis")
from float32_support import DEFAULT_CAL, any_real, f32, finite  # noqa: E402
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

NO_ERROR, NOT_FINITE, BAD_CALIBRATION, BAD_CHANNEL, BAD_FREQUENCY = 0, 3, 5, 6, 7
PULSE_MIN_US, PULSE_MAX_US = 500.0, 2500.0
ANGLE_MIN_DEG, ANGLE_MAX_DEG = -90.0, 90.0
ZERO_MAX_DEG = 180.0
SCALE_MIN, SCALE_MAX = 5.0, 15.0  # us/deg
INT_MIN, INT_MAX = -32768, 32767










def int16() -> st.SearchStrategy[int]:
    return st.one_of(st.integers(INT_MIN, INT_MAX),
                     st.sampled_from([INT_MIN, INT_MIN + 1, -3, -2, -1, 0, 1, 2, 3, INT_MAX]))


# ----------------------------------------------------------------------------- calibration
def calibration_codes(c: dict[str, Any]) -> set[int]:
    """The codes ServoCalibrationCheck may give; two where float32 rounding makes a scale
    that lies within 1e-5 relative of a band edge legitimately go either way."""
    reals = [c[k] for k in ("ZeroOffsetDeg", "MinPulseUs", "MaxPulseUs", "MinAngleDeg",
                            "MaxAngleDeg")]
    if not all(finite(v) for v in reals):
        return {NOT_FINITE}
    plain_bad = (
        c["Direction"] not in (1, -1)
        or not PULSE_MIN_US <= c["MinPulseUs"] < c["MaxPulseUs"] <= PULSE_MAX_US
        or not ANGLE_MIN_DEG <= c["MinAngleDeg"] < c["MaxAngleDeg"] <= ANGLE_MAX_DEG
        or abs(c["ZeroOffsetDeg"]) > ZERO_MAX_DEG
    )
    if plain_bad:
        return {BAD_CALIBRATION}
    scale = (c["MaxPulseUs"] - c["MinPulseUs"]) / (c["MaxAngleDeg"] - c["MinAngleDeg"])
    near_edge = min(abs(scale - SCALE_MIN) / SCALE_MIN, abs(scale - SCALE_MAX) / SCALE_MAX) < 1e-5
    if near_edge:
        return {NO_ERROR, BAD_CALIBRATION}
    return {NO_ERROR} if SCALE_MIN <= scale <= SCALE_MAX else {BAD_CALIBRATION}


@st.composite
def calibrations(draw: st.DrawFn) -> dict[str, Any]:
    """Mostly near-valid calibrations (so the accepted set is well covered), each field now
    and then replaced by an arbitrary float32 / INT value or a bound."""
    lo = draw(st.floats(-92.0, 88.0, width=32))
    hi = draw(st.floats(lo, 92.0, width=32))
    scale = draw(st.floats(4.5, 15.5))
    p_span = scale * (hi - lo)
    p_lo = f32(draw(st.floats(480.0, max(480.0, 2520.0 - p_span))))
    c: dict[str, Any] = {
        "ZeroOffsetDeg": draw(st.floats(-185.0, 185.0, width=32)),
        "Direction": draw(st.sampled_from([1, -1])),
        "MinAngleDeg": lo,
        "MaxAngleDeg": hi,
        "MinPulseUs": p_lo,
        "MaxPulseUs": f32(p_lo + p_span),
    }
    bounds = {
        "ZeroOffsetDeg": [180.0, -180.0, f32(180.00002), 0.0, 70.0, 65.0],
        "Direction": [0, 2, -3, -2, INT_MIN, INT_MAX, 1, -1],
        "MinAngleDeg": [-90.0, f32(-90.00001), -60.0, -1.0e30],
        "MaxAngleDeg": [90.0, f32(90.00001), 60.0, 1.0e30],
        "MinPulseUs": [500.0, f32(499.99997), 0.0, 1000.0],
        "MaxPulseUs": [2500.0, f32(2500.0002), 20000.0, 2000.0],
    }
    for name, edges in bounds.items():
        choice = draw(st.integers(0, 19))
        if choice == 19:  # hypothesis favours small integers: the plain draw is the common case
            c[name] = draw(int16() if name == "Direction" else any_real())
        elif choice == 18:
            c[name] = draw(st.sampled_from(edges))
    return c


def reference_pulse(joint: float, c: dict[str, Any]) -> tuple[float, float, bool]:
    """(pulse us, servo angle deg, clamped) of document 002's linear map, float64."""
    servo = (joint - c["ZeroOffsetDeg"]) * float(c["Direction"])
    clamped = not c["MinAngleDeg"] <= servo <= c["MaxAngleDeg"]
    servo = min(max(servo, c["MinAngleDeg"]), c["MaxAngleDeg"])
    slope = (c["MaxPulseUs"] - c["MinPulseUs"]) / (c["MaxAngleDeg"] - c["MinAngleDeg"])
    return c["MinPulseUs"] + (servo - c["MinAngleDeg"]) * slope, servo, clamped


@examples(800)
@given(c=calibrations())
@example(c={**DEFAULT_CAL, "Direction": 0})
@example(c={**DEFAULT_CAL, "Direction": 2})
@example(c={**DEFAULT_CAL, "Direction": -3})
@example(c={**DEFAULT_CAL, "MinPulseUs": 0.0, "MaxPulseUs": 20000.0})
@example(c={**DEFAULT_CAL, "MinAngleDeg": -1.0e30, "MaxAngleDeg": 1.0e30})
def test_servo_calibration_check_rules(st_module: Any, figures: Any, c: dict[str, Any]) -> None:
    figures.case("ServoCalibrationCheck")
    assert st_module.call("ServoCalibrationCheck", c) in calibration_codes(c), c


@examples(800)  # about one in four calibrations is accepted
@given(c=calibrations(), joint=any_real(), step=st.floats(-10.0, 10.0, width=32))
def test_angle_to_pulse_cannot_jump(
    st_module: Any, figures: Any, c: dict[str, Any], joint: float, step: float
) -> None:
    """Accepted calibration: the pulse is the reference map's, inside 500..2500 us, and two
    angles `step` apart never give pulses more than 15 us/deg * |step| apart. Rejected one
    (or a non-finite angle): Error, the code, PulseUs 0.0 (channel off)."""
    figures.case("MG996R_AngleToPulse")
    code = st_module.call("ServoCalibrationCheck", c)
    got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=joint, Calibration=c)
    if code == NO_ERROR and not finite(joint):
        code = NOT_FINITE
    if code != NO_ERROR:
        assert got["Error"] and got["ErrorId"] == code and got["PulseUs"] == 0.0
        return
    pulse, servo, clamped = reference_pulse(joint, c)
    assert not got["Error"] and got["ErrorId"] == NO_ERROR
    err = abs(got["PulseUs"] - pulse)
    figures.error("MG996R_AngleToPulse", err, "us")
    assert err <= 2e-3, (got, pulse)
    assert PULSE_MIN_US <= got["PulseUs"] <= PULSE_MAX_US
    assert abs(got["ServoAngleDeg"] - servo) <= 1e-4 * max(1.0, abs(joint))
    if abs(abs(servo) - 90.0) > 1e-3:  # flag exact except at a float32 tie with a limit
        assert got["Clamped"] == clamped or abs(got["ServoAngleDeg"] - servo) < 1e-4
    nxt = st_module.call("MG996R_AngleToPulse", JointAngleDeg=f32(joint + step), Calibration=c)
    assert abs(nxt["PulseUs"] - got["PulseUs"]) <= SCALE_MAX * abs(f32(joint + step) - joint) + 4e-3


@examples(800)
@given(c=calibrations(), pulse=st.one_of(st.floats(300.0, 2700.0, width=32), any_real()))
def test_pulse_to_angle_vs_reference(
    st_module: Any, figures: Any, c: dict[str, Any], pulse: float
) -> None:
    figures.case("MG996R_PulseToAngle")
    code = st_module.call("ServoCalibrationCheck", c)
    got = st_module.call("MG996R_PulseToAngle", PulseUs=pulse, Calibration=c)
    if code == NO_ERROR and not finite(pulse):
        code = NOT_FINITE
    if code != NO_ERROR:
        assert got["Error"] and got["ErrorId"] == code
        assert got["JointAngleDeg"] == 0.0 and got["ServoAngleDeg"] == 0.0
        return
    p = min(max(pulse, c["MinPulseUs"]), c["MaxPulseUs"])
    servo = c["MinAngleDeg"] + (p - c["MinPulseUs"]) * (c["MaxAngleDeg"] - c["MinAngleDeg"]) / (
        c["MaxPulseUs"] - c["MinPulseUs"])
    joint = c["ZeroOffsetDeg"] + c["Direction"] * servo
    err = abs(got["JointAngleDeg"] - joint)
    figures.error("MG996R_PulseToAngle", err, "deg")
    assert not got["Error"] and err <= 1e-4, (got, joint)
    assert got["Clamped"] == (not c["MinPulseUs"] <= pulse <= c["MaxPulseUs"])


def test_defect_calibration_bounds_prevent_the_jump_of_issue_8(st_module: Any) -> None:
    """Regression: SetCalibration took 0..20,000 us and +/-1e30 deg; MoveJoints(10, 70, 65)
    then gave an 11.7 ms pulse. Such a calibration is now refused; the controller's
    defaults (zero offsets 0 / 70 / 65) pass and give in-range pulses."""
    wide = {**DEFAULT_CAL, "MinPulseUs": 0.0, "MaxPulseUs": 20000.0,
            "MinAngleDeg": -1.0e30, "MaxAngleDeg": 1.0e30}
    huge_scale = {**DEFAULT_CAL, "MinPulseUs": 500.0, "MaxPulseUs": 2500.0,
                  "MinAngleDeg": -1.0, "MaxAngleDeg": 1.0}  # 1000 us/deg
    for bad in (wide, huge_scale, {**DEFAULT_CAL, "Direction": 0},
                {**DEFAULT_CAL, "Direction": 2}, {**DEFAULT_CAL, "Direction": -3}):
        assert st_module.call("ServoCalibrationCheck", bad) == BAD_CALIBRATION, bad
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=10.0, Calibration=bad)
        assert got["Error"] and got["PulseUs"] == 0.0
    for zero, joint in ((0.0, 10.0), (70.0, 70.0), (65.0, 65.0)):
        c = {**DEFAULT_CAL, "ZeroOffsetDeg": zero}
        assert st_module.call("ServoCalibrationCheck", c) == NO_ERROR
        got = st_module.call("MG996R_AngleToPulse", JointAngleDeg=joint, Calibration=c)
        assert 1000.0 <= got["PulseUs"] <= 2000.0
    # the two real-servo scales named in the header pass: 8.33 and 11.1 us/deg
    full = {**DEFAULT_CAL, "MinPulseUs": 500.0, "MaxPulseUs": 2500.0,
            "MinAngleDeg": -90.0, "MaxAngleDeg": 90.0}
    assert st_module.call("ServoCalibrationCheck", full) == NO_ERROR


# ----------------------------------------------------------------------------- PCA9685
@given(freq=st.one_of(st.floats(20.0, 2000.0, width=32), any_real()),
       osc=st.one_of(st.floats(20.0e6, 30.0e6, width=32), any_real()))
def test_pca9685_prescale_vs_datasheet(
    st_module: Any, figures: Any, freq: float, osc: float
) -> None:
    figures.case("PCA9685_Prescale")
    got = st_module.call("PCA9685_Prescale", FrequencyHz=freq, OscillatorHz=osc)
    if not (finite(freq) and finite(osc)) or freq <= 0.0 or osc <= 0.0:
        assert got["Error"] and got["ErrorId"] == BAD_FREQUENCY and got["Prescale"] == 0
        assert got["ActualHz"] == 0.0
        return
    ratio = osc / (4096.0 * freq)
    raw = math.floor(ratio + 0.5) - 1 if ratio < 1.0e4 else 10**6
    allowed = {min(max(raw, 3), 255)}
    if abs(ratio + 0.5 - round(ratio + 0.5)) < 1e-6 * max(1.0, ratio):  # float32 tie
        allowed |= {min(max(raw - 1, 3), 255), min(max(raw + 1, 3), 255)}
    assert not got["Error"] and got["Prescale"] in allowed, (got, ratio)
    actual = osc / (4096.0 * (got["Prescale"] + 1))
    assert got["ActualHz"] == pytest.approx(actual, rel=1e-6, abs=1e-37)  # abs: float32 underflow
    if actual > 1e-30:
        figures.error("PCA9685_Prescale", abs(got["ActualHz"] - actual) / actual, "rel (ActualHz)")


@given(pulse=st.one_of(st.floats(-10.0, 25000.0, width=32), any_real()),
       prescale=st.integers(0, 255),
       osc=st.one_of(st.floats(20.0e6, 30.0e6, width=32), any_real()),
       phase=st.one_of(st.integers(0, 65535), st.sampled_from([0, 4095, 4096, 65535])))
def test_pca9685_pulse_to_counts_vs_datasheet(
    st_module: Any, figures: Any, pulse: float, prescale: int, osc: float, phase: int
) -> None:
    figures.case("PCA9685_PulseToCounts")
    got = st_module.call("PCA9685_PulseToCounts", PulseUs=pulse, Prescale=prescale,
                         OscillatorHz=osc, PhaseCounts=phase)
    full = 0x1000
    if not finite(osc) or osc <= 0.0 or not finite(pulse):
        code = BAD_FREQUENCY if not finite(osc) or osc <= 0.0 else NOT_FINITE
        assert got["Error"] and got["ErrorId"] == code
        assert got["FullOff"] and got["OffWord"] == full and got["OnWord"] == 0
        return
    exact = pulse * osc / 1.0e6 / (max(prescale, 3) + 1)
    if exact <= 0.0:
        allowed = {0}
    elif exact >= 4096.0:
        allowed = {4096}
    else:
        n = math.floor(exact + 0.5)
        allowed = {min(n, 4096)}
        if abs(exact + 0.5 - round(exact + 0.5)) < 1e-6 * max(1.0, exact):
            allowed |= {max(n - 1, 0), min(n + 1, 4096)}
    assert not got["Error"]
    if got["FullOff"]:
        assert 0 in allowed and got["OnWord"] == 0 and got["OffWord"] == full
    elif got["FullOn"]:
        assert 4096 in allowed and got["OnWord"] == full and got["OffWord"] == 0
    else:
        counts = (got["OffCount"] - got["OnCount"]) % 4096
        assert counts in allowed, (got, exact)
        assert got["OnCount"] == phase % 4096 and got["OnWord"] == phase % 4096
        assert got["OffWord"] == got["OffCount"] < 4096


@given(channel=int16(), address=st.integers(0, 255), on=st.integers(0, 65535),
       off=st.integers(0, 65535))
def test_pca9685_led_register_and_channel_frame(
    st_module: Any, figures: Any, channel: int, address: int, on: int, off: int
) -> None:
    figures.case("PCA9685_LedRegister")
    figures.case("PCA9685_ChannelFrame")
    reg = st_module.call("PCA9685_LedRegister", channel)
    frame = st_module.call("PCA9685_ChannelFrame", Address=address, Channel=channel,
                           OnWord=on, OffWord=off)
    if 0 <= channel <= 15:
        assert reg == 0x06 + 4 * channel
        assert frame["Length"] == 4 and frame["Register"] == reg and frame["Address"] == address
        assert frame["Data"] == [on & 0xFF, on >> 8, off & 0xFF, off >> 8]
    else:
        assert reg == 0x00 and frame["Length"] == 0


@given(index=int16(), address=st.integers(0, 255), prescale=st.integers(0, 255))
def test_pca9685_init_frame_any_index(
    st_module: Any, figures: Any, index: int, address: int, prescale: int
) -> None:
    figures.case("PCA9685_InitFrame")
    frame = st_module.call("PCA9685_InitFrame", Address=address, Prescale=prescale, Index=index)
    datasheet = {1: (0x00, 0x11), 2: (0xFE, max(prescale, 3)), 3: (0x01, 0x04),
                 4: (0x00, 0x01), 5: (0x00, 0xA1)}
    if index in datasheet:
        assert frame["Length"] == 1 and frame["Address"] == address
        assert (frame["Register"], frame["Data"][0]) == datasheet[index]
    else:
        assert frame["Length"] == 0
