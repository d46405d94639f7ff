"""Bad input to the orientation blocks: NaN, Inf, absurd values, zero-norm accelerometer or
magnetometer, saturated registers, bad calibration and bad parameters give the documented
ErrorId (st/Quaternion.st header) and keep the last valid quaternion, never NaN; and the tool
orientation follower's dead band and rate limit (checked with scipy)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from float32_support import F32_EXTREMES

from armbench.orientation import quat_dict, quat_row, raw_dict, vec_dict
from armbench.plant.imu import HandTrajectory, ImuModel, angle_between_deg, simulate

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

BAD_PARAMETER, NOT_FINITE, ACCEL_ZERO, MAG_ZERO, SATURATED, PARALLEL, BAD_QUAT = (
    8, 40, 41, 42, 43, 44, 45)
BLOCKS = ("GyroIntegrator", "ComplementaryFilter", "MadgwickImu", "MadgwickMarg")
USES_ACCEL = {"ComplementaryFilter", "MadgwickImu", "MadgwickMarg"}
USES_MAG = {"ComplementaryFilter", "MadgwickMarg"}


def sample(gyro: Any = (1.0, -2.0, 3.0), accel: Any = (0.1, 0.2, 0.97),
           mag: Any = (0.25, 0.05, -0.43), code: int = 0) -> dict[str, Any]:
    return {"Gyro": vec_dict(gyro), "Accel": vec_dict(accel), "Mag": vec_dict(mag),
            "Code": code}


def started(st_module: Any, name: str) -> Any:
    fb = st_module.new_fb(name)
    if name == "ComplementaryFilter":
        fb(Reset=True)  # starts at the accel+mag orientation of the first sample
    else:
        fb(Reset=True, InitialQuat=quat_dict([0.9, 0.1, -0.2, 0.3]))
    for _ in range(5):
        fb(Reset=False, Sample=sample())
    assert fb.ErrorId == 0
    return fb


BAD_SAMPLES = [
    ("gyro NaN", sample(gyro=(math.nan, 0.0, 0.0)), NOT_FINITE, BLOCKS),
    ("gyro Inf", sample(gyro=(0.0, -math.inf, 0.0)), NOT_FINITE, BLOCKS),
    ("gyro 1e7", sample(gyro=(0.0, 0.0, 1.0e7)), NOT_FINITE, BLOCKS),
    ("accel NaN", sample(accel=(0.0, math.nan, 1.0)), NOT_FINITE, USES_ACCEL),
    ("mag Inf", sample(mag=(math.inf, 0.0, 0.0)), NOT_FINITE, USES_MAG),
    ("accel zero", sample(accel=(0.0, 0.0, 0.0)), ACCEL_ZERO, USES_ACCEL),
    ("accel 1e-7", sample(accel=(1e-7, 0.0, 0.0)), ACCEL_ZERO, USES_ACCEL),
    ("mag zero", sample(mag=(0.0, 0.0, 0.0)), MAG_ZERO, USES_MAG),
    ("saturated", sample(code=SATURATED), SATURATED, BLOCKS),
    ("bad calibration", sample(code=BAD_PARAMETER), BAD_PARAMETER, BLOCKS),
    ("accel parallel to mag", sample(accel=(0.0, 0.0, 1.0), mag=(0.0, 0.001, -0.5)), PARALLEL,
     {"ComplementaryFilter"}),
]


@pytest.mark.parametrize("block", BLOCKS)
@pytest.mark.parametrize(("label", "bad", "code", "affected"), BAD_SAMPLES,
                         ids=[b[0] for b in BAD_SAMPLES])
def test_bad_sample_keeps_the_last_quaternion(st_module: Any, block: str, label: str,
                                              bad: dict[str, Any], code: int,
                                              affected: Any) -> None:
    fb = started(st_module, block)
    before = quat_row(fb.Orientation)
    fb(Reset=False, Sample=bad)
    after = quat_row(fb.Orientation)
    assert all(math.isfinite(v) for v in after)
    if block in affected:
        assert (fb.Error, fb.ErrorId) == (True, code), label
        assert after == before
        assert fb.Rejected == 1
        fb(Reset=False, Sample=sample())  # a good sample clears the error and runs on
        assert (fb.Error, fb.ErrorId) == (False, 0)
        assert quat_row(fb.Orientation) != before
    else:
        assert (fb.Error, fb.ErrorId) == (False, 0), f"{block} does not use what {label} breaks"


@pytest.mark.parametrize(("block", "param", "value"), [
    ("GyroIntegrator", "SamplePeriodS", 0.0), ("GyroIntegrator", "SamplePeriodS", math.nan),
    ("ComplementaryFilter", "Blend", 1.5), ("ComplementaryFilter", "Blend", math.nan),
    ("ComplementaryFilter", "SamplePeriodS", -0.01),
    ("ComplementaryFilter", "RefMag", vec_dict([0.0, 0.0, 2.0])),
    ("MadgwickImu", "Beta", -0.1), ("MadgwickImu", "Beta", math.inf),
    ("MadgwickImu", "SamplePeriodS", 2.0),
    ("MadgwickMarg", "Beta", math.nan), ("MadgwickMarg", "SamplePeriodS", 0.0),
])
def test_bad_parameter(st_module: Any, block: str, param: str, value: Any) -> None:
    fb = started(st_module, block)
    before = quat_row(fb.Orientation)
    fb(Reset=False, Sample=sample(), **{param: value})
    assert (fb.Error, fb.ErrorId) == (True, BAD_PARAMETER)
    assert quat_row(fb.Orientation) == before


@pytest.mark.parametrize("block", ["GyroIntegrator", "MadgwickImu", "MadgwickMarg"])
def test_bad_initial_quaternion(st_module: Any, block: str) -> None:
    fb = st_module.new_fb(block)
    fb(Reset=True, InitialQuat=quat_dict([math.nan, 0.0, 0.0, 0.0]))
    assert (fb.Error, fb.ErrorId) == (True, BAD_QUAT)
    assert quat_row(fb.Orientation) == [1.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize("block", BLOCKS)
def test_garbage_never_gives_nan(st_module: Any, block: str) -> None:
    """500 samples whose fields are drawn from every float32 extreme (NaN, Inf, 1e30,
    denormals, 0) mixed with ordinary readings: every output stays a unit quaternion."""
    rng = np.random.default_rng(30)
    fb = started(st_module, block)
    pool = F32_EXTREMES + [0.5, -1.0, 0.001, 20.0]
    for _ in range(500):
        vals = [float(rng.choice(pool)) for _ in range(9)]
        fb(Reset=False, Sample=sample(vals[0:3], vals[3:6], vals[6:9]))
        q = quat_row(fb.Orientation)
        assert all(math.isfinite(v) for v in q)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-6)


def test_saturated_registers_are_flagged(st_module: Any) -> None:
    record = simulate(HandTrajectory(), ImuModel(), duration_s=0.1, rate_hz=100.0, seed=1)
    cal = record.model.calibration()
    good = raw_dict(record, 0)
    assert st_module.call("ImuRawToSample", Raw=good, Calibration=cal)["Code"] == 0
    for key, value in (("GyroX", 32767), ("GyroZ", -32768), ("AccelY", 32767),
                       ("AccelZ", -32768), ("MagX", -4096), ("MagZ", -4096)):
        got = st_module.call("ImuRawToSample", Raw={**good, key: value}, Calibration=cal)
        assert got["Code"] == SATURATED, key
    for bad_cal in ({"GyroLsbPerDps": 0.0}, {"AccelLsbPerG": math.nan},
                    {"MagLsbPerGauss": -1090.0}, {"AccelScaleX": 3.0},
                    {"GyroBiasDps": vec_dict([math.inf, 0.0, 0.0])}):
        got = st_module.call("ImuRawToSample", Raw=good, Calibration={**cal, **bad_cal})
        assert got["Code"] == BAD_PARAMETER, bad_cal
        assert all(math.isfinite(got[v][k]) for v in ("Gyro", "Accel", "Mag") for k in "XYZ")
    # the simulated chips saturate too: a spin at 400 deg/s on a 250 deg/s range
    fast = simulate(HandTrajectory(yaw=((120.0, 0.6, 0.0),)), ImuModel(), duration_s=2.0,
                    rate_hz=100.0, seed=2)
    assert np.any(np.abs(fast.gyro_raw) >= 32767)
    codes = [st_module.call("ImuRawToSample", Raw=raw_dict(fast, k), Calibration=cal)["Code"]
             for k in range(len(fast))]
    assert SATURATED in codes


# --- ToolOrientationFollower -----------------------------------------------------------------

def follower(st_module: Any, start: Any, **params: Any) -> Any:
    fb = st_module.new_fb("ToolOrientationFollower")
    settings: dict[str, Any] = {"Enable": True, "DeadBandDeg": 2.0, "MaxRateDps": 90.0,
                                "CycleTimeS": 0.01,
                                "MountOffset": quat_dict([1.0, 0.0, 0.0, 0.0])}
    fb.set(**{**settings, **params})
    fb(Reset=True, InitialQuat=quat_dict(start), Target=quat_dict(start))
    fb(Reset=False)
    return fb


def test_follower_ignores_noise_inside_the_dead_band(st_module: Any) -> None:
    start = Rotation.from_euler("ZYX", [30.0, 20.0, -10.0], degrees=True)
    fb = follower(st_module, start.as_quat(scalar_first=True))
    held = quat_row(fb.Orientation)
    rng = np.random.default_rng(40)
    for _ in range(500):
        axis = rng.normal(size=3)
        noise = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(
            rng.uniform(0.0, 1.9)))
        fb(Target=quat_dict((start * noise).as_quat(scalar_first=True)))
        assert quat_row(fb.Orientation) == held
        assert not fb.Tracking


def test_follower_limits_the_rate_and_reaches_the_goal(st_module: Any) -> None:
    start = Rotation.identity()
    goal = Rotation.from_euler("ZYX", [170.0, -40.0, 60.0], degrees=True)
    fb = follower(st_module, start.as_quat(scalar_first=True))
    total = np.degrees((start.inv() * goal).magnitude())
    prev = np.array(quat_row(fb.Orientation))
    steps = 0
    remaining = total
    while True:
        fb(Target=quat_dict(goal.as_quat(scalar_first=True)))
        q = np.array(quat_row(fb.Orientation))
        step = float(angle_between_deg(prev, q))
        assert step <= 0.9 + 1e-3  # 90 deg/s * 10 ms
        now = float(angle_between_deg(q, goal.as_quat(scalar_first=True)))
        assert now < remaining + 1e-4  # always closer, along the shortest arc
        remaining, prev = now, q
        steps += 1
        if not fb.Tracking:
            break
        assert steps < 1000
    assert steps == math.ceil(total / 0.9 - 1e-6)
    assert remaining < 1e-3
    direction = [fb.ToolDirection[k] for k in "XYZ"]
    assert direction == pytest.approx(goal.apply([1.0, 0.0, 0.0]), abs=1e-5)
    assert fb.ElevationDeg == pytest.approx(np.degrees(np.arcsin(direction[2])), abs=1e-3)
    yaw, pitch, roll = goal.as_euler("ZYX", degrees=True)
    assert [fb.Angles["RollDeg"], fb.Angles["PitchDeg"], fb.Angles["YawDeg"]] == pytest.approx(
        [roll, pitch, yaw], abs=1e-3)


def test_follower_mount_offset_and_bad_input(st_module: Any) -> None:
    mount = Rotation.from_euler("ZYX", [0.0, 90.0, 0.0], degrees=True)  # sensor X = tool down
    target = Rotation.from_euler("ZYX", [45.0, 0.0, 0.0], degrees=True)
    want = target * mount
    fb = follower(st_module, want.as_quat(scalar_first=True),
                  MountOffset=quat_dict(mount.as_quat(scalar_first=True)))
    fb(Target=quat_dict(target.as_quat(scalar_first=True)))
    assert fb.ErrorDeg == pytest.approx(0.0, abs=1e-3)
    assert [fb.ToolDirection[k] for k in "XYZ"] == pytest.approx(want.apply([1, 0, 0]),
                                                                 abs=1e-5)
    held = quat_row(fb.Orientation)
    for bad in ([math.nan, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0], [math.inf, 0, 0, 0]):
        fb(Target=quat_dict(bad))
        assert (fb.Error, fb.ErrorId) == (True, BAD_QUAT)
        assert quat_row(fb.Orientation) == held
    for param, value in (("DeadBandDeg", -1.0), ("MaxRateDps", 0.0), ("CycleTimeS", math.nan),
                         ("MaxRateDps", 1e9)):
        fb(Target=quat_dict(target.as_quat(scalar_first=True)), **{param: value})
        assert (fb.Error, fb.ErrorId) == (True, BAD_PARAMETER), param
        assert quat_row(fb.Orientation) == held
        fb.set(DeadBandDeg=2.0, MaxRateDps=90.0, CycleTimeS=0.01)
