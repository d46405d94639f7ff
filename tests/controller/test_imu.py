"""The controller's IMU layer (Controller.st IMU COMMANDS) on the in-process soft PLC.

Samples go into the input registers through armbench.plant.imu_feed (the plant writes the
process image, as the PSM does on a Pi: %IW cannot be written over Modbus); commands and the
result block go over Modbus with ArmControllerClient. References:
- the ``ahrs`` package's Madgwick (updateIMU / updateMARG) run on the same samples, converted
  to physical units in float32 exactly as ImuRawToSample does (one IEEE division, one
  subtraction per value: the same bits as the PLC);
- the simulator's ground truth (quat_true) for drift and calibration effects.
"""

from __future__ import annotations

import math
import struct
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from fast_plc import FastPlc
from imu_support import float32_physical

from armbench.controller_client import (
    CMD_IMU_RESET,
    ERR_BAD_PARAMETER,
    ERR_BAD_QUATERNION,
    ERR_OK,
    ERR_UNKNOWN_COMMAND,
    ArmControllerClient,
)
from armbench.plant.imu import (
    HandTrajectory,
    ImuModel,
    ImuRecord,
    angle_between_deg,
    simulate,
)
from armbench.plant.imu_feed import ImuFeeder
from armbench.registermap import controller_map

ahrs_filters = pytest.importorskip("ahrs.filters")

AGREEMENT_TOL = 2.0e-6  # per quaternion component, as tests/unit/test_orientation_filters.py
RATE_HZ = 100.0


@pytest.fixture()
def feeder(fast_controller: FastPlc) -> ImuFeeder:
    f = ImuFeeder(fast_controller.plc.image, fast_controller.plc.lock)
    with fast_controller.plc.lock:  # continue the counter where an earlier test left it
        f.seq = fast_controller.plc.image.iw[controller_map()["IMUSAMPLESEQ"].index]
    return f


@pytest.fixture(scope="module")
def record() -> ImuRecord:
    return simulate(HandTrajectory(), ImuModel(), duration_s=20.0, rate_hz=RATE_HZ, seed=7)


_QUAT_MD = tuple(controller_map()[n].index for n in ("IMUQUATW", "IMUQUATX", "IMUQUATY",
                                                       "IMUQUATZ"))


def plc_quat(fast_controller: FastPlc) -> np.ndarray:
    """The PLC's quaternion straight from the image (stable between two samples)."""
    with fast_controller.plc.lock:
        words = [fast_controller.plc.image.md[i] for i in _QUAT_MD]
    return np.array(struct.unpack("<4f", struct.pack("<4I", *words)), dtype=np.float64)


def run_plc(fast_controller: FastPlc, ctl: ArmControllerClient, feeder: ImuFeeder,
            record: ImuRecord, method: str, gain: float, *, raw: dict[str, np.ndarray] | None = None
            ) -> np.ndarray:
    """Start ``method`` at the true start orientation, feed samples 1..N-1; quaternion per
    sample (row 0 = the start)."""
    assert ctl.imu_select_filter(method, gain) == ERR_OK
    assert ctl.imu_set_period(record.period_s) == ERR_OK
    assert ctl.imu_reset(tuple(record.quat_true[0])) == ERR_OK
    g = record.gyro_raw if raw is None else raw["gyro"]
    a = record.accel_raw if raw is None else raw["accel"]
    m = record.mag_raw if raw is None else raw["mag"]
    out = [plc_quat(fast_controller)]
    for k in range(1, len(record)):
        feeder.feed([*map(int, g[k]), *map(int, a[k]), *map(int, m[k])])
        out.append(plc_quat(fast_controller))
    return np.array(out)


@pytest.mark.parametrize(("method", "beta"), [("madgwick_imu", 0.033), ("madgwick_marg", 0.041),
                                              ("madgwick_marg", 0.2)])
def test_plc_madgwick_matches_ahrs(fast_controller: FastPlc, ctl: ArmControllerClient,
                                   feeder: ImuFeeder, record: ImuRecord, method: str,
                                   beta: float) -> None:
    gyro, accel, mag = float32_physical(record)
    # ahrs skips the update when all three rates are exactly 0; the trajectory never rests
    assert not np.any(np.all(gyro == 0.0, axis=1))
    mw = ahrs_filters.Madgwick(Dt=record.period_s, gain=beta)
    q = record.quat_true[0].copy()
    want = [q]
    for k in range(1, len(record)):
        if method == "madgwick_imu":
            q = mw.updateIMU(q, np.radians(gyro[k]), accel[k])
        else:
            q = mw.updateMARG(q, np.radians(gyro[k]), accel[k], mag[k])
        want.append(q)
    got = run_plc(fast_controller, ctl, feeder, record, method, beta)
    diff = np.abs(got - np.array(want)).max(axis=1)
    st = ctl.imu_state()
    print(f"\nPLC {method} beta={beta} vs ahrs, {len(record)} samples over Modbus/IW: "
          f"max |dq| {diff.max():.2e}")
    assert st.samples == len(record) - 1 and st.error_id == ERR_OK and st.missed == 0
    assert np.allclose(st.quat, got[-1], atol=0.0, rtol=0.0)
    assert diff.max() < AGREEMENT_TOL


def test_marg_stays_bounded_while_gyro_only_drifts(
        fast_controller: FastPlc, ctl: ArmControllerClient, feeder: ImuFeeder,
        record: ImuRecord) -> None:
    gyro = angle_between_deg(run_plc(fast_controller, ctl, feeder, record, "gyro", 0.0),
                             record.quat_true)
    marg = angle_between_deg(run_plc(fast_controller, ctl, feeder, record, "madgwick_marg", 0.041),
                             record.quat_true)
    # the uncorrected bias (0.4, -0.3, 0.25) deg/s integrates to about |b| t = 11 deg in 20 s
    bias = float(np.linalg.norm(record.model.gyro_bias_dps))
    print(f"\n20 s: gyro-only error {gyro[-1]:.2f} deg (|bias| t = {bias * 20:.1f}), "
          f"MARG worst {marg.max():.2f} deg")
    assert gyro[-1] > 0.3 * bias * 20.0
    assert marg.max() < 0.25 * gyro[-1]
    # bounded: the second half is no worse than the first (no growth with time)
    half = len(marg) // 2
    assert marg[half:].max() <= marg[:half].max() + 0.5


def test_gyro_bias_calibration_takes_effect(fast_controller: FastPlc, ctl: ArmControllerClient,
                                            feeder: ImuFeeder, record: ImuRecord) -> None:
    raw_err = angle_between_deg(run_plc(fast_controller, ctl, feeder, record, "gyro", 0.0),
                                record.quat_true)[-1]
    assert ctl.imu_set_gyro_bias(record.model.gyro_bias_dps) == ERR_OK
    try:
        st = ctl.imu_state()
        assert st.gyro_bias_dps == pytest.approx(record.model.gyro_bias_dps, abs=1e-6)
        cal_err = angle_between_deg(run_plc(fast_controller, ctl, feeder, record, "gyro", 0.0),
                                    record.quat_true)[-1]
    finally:
        assert ctl.imu_set_gyro_bias((0.0, 0.0, 0.0)) == ERR_OK
    print(f"\ngyro-only after 20 s: {raw_err:.2f} deg raw, {cal_err:.2f} deg with the bias")
    assert cal_err < 0.3 * raw_err


def _tampered(record: ImuRecord, accel_gain: float, mag_offset_lsb: np.ndarray
              ) -> dict[str, np.ndarray]:
    return {"gyro": record.gyro_raw,
            "accel": np.round(record.accel_raw * np.array([accel_gain, 1.0, 1.0])).astype(int),
            "mag": record.mag_raw + mag_offset_lsb.astype(int)}


def test_accel_scale_and_hard_iron_calibration_take_effect(
        fast_controller: FastPlc, ctl: ArmControllerClient, feeder: ImuFeeder,
        record: ImuRecord) -> None:
    short = replace(record, t=record.t[:800], quat_true=record.quat_true[:800],
                    gyro_true_dps=record.gyro_true_dps[:800],
                    gyro_bias_dps=record.gyro_bias_dps[:800], gyro_raw=record.gyro_raw[:800],
                    accel_raw=record.accel_raw[:800], mag_raw=record.mag_raw[:800])
    offset_gauss = np.array([0.15, -0.1, 0.05])
    tamper = _tampered(short, 1.25, offset_gauss * record.model.mag_lsb_per_gauss)
    clean = angle_between_deg(run_plc(fast_controller, ctl, feeder, short, "madgwick_marg", 0.2),
                              short.quat_true)
    bad = angle_between_deg(run_plc(fast_controller, ctl, feeder, short, "madgwick_marg", 0.2,
                                    raw=tamper), short.quat_true)
    assert ctl.imu_set_accel_scale((0.8, 1.0, 1.0)) == ERR_OK
    assert ctl.imu_set_mag_offset(offset_gauss) == ERR_OK
    try:
        st = ctl.imu_state()
        assert st.accel_scale == pytest.approx((0.8, 1.0, 1.0), abs=1e-7)
        assert st.mag_offset_gauss == pytest.approx(offset_gauss, abs=1e-7)
        fixed = angle_between_deg(run_plc(fast_controller, ctl, feeder, short, "madgwick_marg", 0.2,
                                          raw=tamper), short.quat_true)
    finally:
        assert ctl.imu_set_accel_scale((1.0, 1.0, 1.0)) == ERR_OK
        assert ctl.imu_set_mag_offset((0.0, 0.0, 0.0)) == ERR_OK
    tail = slice(400, None)  # after the filter has converged
    print(f"\nMARG mean error: clean {clean[tail].mean():.2f}, tampered {bad[tail].mean():.2f}, "
          f"calibrated {fixed[tail].mean():.2f} deg")
    assert bad[tail].mean() > 3.0 * clean[tail].mean() + 1.0
    assert fixed[tail].mean() < clean[tail].mean() + 0.2


@pytest.mark.parametrize("call", [
    ("imu_select_filter", ("madgwick_imu", -0.1)), ("imu_select_filter", ("madgwick_imu", 11.0)),
    ("imu_select_filter", ("madgwick_marg", math.nan)),
    ("imu_select_filter", ("complementary", 1.5)), ("imu_set_period", (0.0,)),
    ("imu_set_period", (2.0,)), ("imu_set_period", (math.nan,)),
    ("imu_set_gyro_bias", ((1.0e4, 0.0, 0.0),)), ("imu_set_gyro_bias", ((0.0, math.inf, 0.0),)),
    ("imu_set_accel_scale", ((1.0, 0.2, 1.0),)), ("imu_set_accel_scale", ((1.0, 1.0, math.nan),)),
    ("imu_set_mag_offset", ((0.0, 0.0, -2.0e3),)),
    ("imu_reset", ((0.0, 0.0, 0.0, 0.0),)), ("imu_reset", ((math.nan, 0.0, 0.0, 1.0),)),
])
def test_bad_commands_change_nothing(ctl: ArmControllerClient, call: tuple[str, Any]) -> None:
    name, args = call
    before = ctl.imu_state()
    result = getattr(ctl, name)(*args)
    want = ERR_BAD_QUATERNION if name == "imu_reset" else ERR_BAD_PARAMETER
    assert result == want
    after = ctl.imu_state()
    assert (after.filter, after.gain, after.period_s, after.gyro_bias_dps, after.accel_scale,
            after.mag_offset_gauss, after.quat) == \
           (before.filter, before.gain, before.period_s, before.gyro_bias_dps,
            before.accel_scale, before.mag_offset_gauss, before.quat)


def test_bad_filter_and_free_codes(ctl: ArmControllerClient) -> None:
    assert ctl.command(40, ints=(4, 0)).error_id == ERR_BAD_PARAMETER
    assert ctl.command(CMD_IMU_RESET, ints=(0, 2), args=(1.0,)).error_id == ERR_BAD_PARAMETER
    assert ctl.command(47).error_id == ERR_UNKNOWN_COMMAND  # 46 is FollowImu, 47..49 free


@pytest.mark.parametrize("method", ["gyro", "complementary", "madgwick_imu", "madgwick_marg"])
def test_zero_and_saturated_samples_never_give_nan(
        fast_controller: FastPlc, ctl: ArmControllerClient, feeder: ImuFeeder,
        record: ImuRecord, method: str) -> None:
    assert ctl.imu_select_filter(method) == ERR_OK
    assert ctl.imu_set_period(record.period_s) == ERR_OK
    assert ctl.imu_reset(tuple(record.quat_true[0])) == ERR_OK
    feeder.feed([*map(int, record.gyro_raw[1]), *map(int, record.accel_raw[1]),
                 *map(int, record.mag_raw[1])])
    for k in range(2, 6):  # a few good samples: the complementary filter is then started
        feeder.feed([*map(int, record.gyro_raw[k]), *map(int, record.accel_raw[k]),
                     *map(int, record.mag_raw[k])])
    good = ctl.imu_state()
    assert good.error_id == ERR_OK
    bad_samples = [[0] * 9, [32767] * 9, [-32768] * 9, [0, 0, 0, 0, 0, 0, -4096, -4096, -4096],
                   [32767, -32768, 32767, 0, 0, 16384, 300, 0, -500]]
    for raw in bad_samples:
        feeder.feed(raw)
        st = ctl.imu_state()
        values = (*st.quat, *st.rpy_deg, *st.tool)
        assert all(math.isfinite(v) for v in values), (raw, values)
        # gyro integration uses only the gyro: all zeros is a valid zero-rate sample there
        accepted = method == "gyro" and raw == [0] * 9
        assert (st.error_id == ERR_OK) == accepted, raw
        assert st.quat == good.quat  # rejected (or zero-rate): the orientation is kept
    assert ctl.imu_state().rejected == len(bad_samples) - (method == "gyro")


def test_counter_jumps_count_missed_samples(fast_controller: FastPlc, ctl: ArmControllerClient,
                                            feeder: ImuFeeder, record: ImuRecord) -> None:
    assert ctl.imu_reset() == ERR_OK
    raw = [*map(int, record.gyro_raw[1]), *map(int, record.accel_raw[1]),
           *map(int, record.mag_raw[1])]
    feeder.feed(raw)
    feeder.seq = (feeder.seq + 3) & 0xFFFF  # three samples the PLC never saw
    feeder.feed(raw)
    st = ctl.imu_state()
    assert (st.samples, st.missed, st.last_seq) == (2, 3, feeder.seq)
