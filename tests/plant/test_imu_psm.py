"""The PSM's IMU reader (plc_project/psm/arm_io_psm.py) against the MPU6050/HMC5883L models.

References: the chips' register layouts as the data sheets give them (armbench.plant.imu_chips:
big-endian words, the HMC5883L's X, Z, Y order, sleep at power-on, the GY-87 bypass) and the
simulator's raw samples (armbench.plant.imu), which must arrive unchanged in %IW0..8.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from armbench.plant.imu import HandTrajectory, ImuModel, ImuRecord, simulate
from armbench.plant.imu_chips import HMC5883L, MPU6050, Gy87Board
from armbench.registermap import controller_map
from psm_script import load_psm_script

psm_mod = load_psm_script("arm_io_psm_imu")


@dataclass
class RecordingPlc:
    """OpenPLC's psm module reduced to its input words; remembers every set_var call."""

    words: list[int] = field(default_factory=lambda: [0] * 50)
    calls: list[tuple[str, object]] = field(default_factory=list)

    def get_var(self, name: str) -> object:
        return self.words[int(name.removeprefix("IW"))]

    def set_var(self, name: str, value: object) -> None:
        self.calls.append((name, value))
        start = int(name.removeprefix("IW"))
        values = value if isinstance(value, list) else [value]
        for i, v in enumerate(values):
            assert isinstance(v, int) and 0 <= v <= 0xFFFF, "Modbus registers are unsigned"
            self.words[start + i] = v


def signed(words: list[int]) -> list[int]:
    return [w - 0x10000 if w & 0x8000 else w for w in words]


def make(board: Gy87Board | None = None, **kwargs: Any) -> tuple[Gy87Board, RecordingPlc, Any,
                                                                   list[str]]:
    board = board or Gy87Board()
    plc = RecordingPlc()
    logs: list[str] = []
    reader = psm_mod.ImuReader(bus=board, plc=plc, sleep=lambda _s: None, log=logs.append,
                               **kwargs)
    return board, plc, reader, logs


@pytest.fixture(scope="module")
def record() -> ImuRecord:
    return simulate(HandTrajectory(), ImuModel(), duration_s=3.0, rate_hz=50.0, seed=11)


def test_words_match_the_controller_map() -> None:
    cmap = controller_map()
    names = ("ImuGyroX", "ImuGyroY", "ImuGyroZ", "ImuAccelX", "ImuAccelY", "ImuAccelZ",
             "ImuMagX", "ImuMagY", "ImuMagZ", "ImuSampleSeq")
    for var, name in zip(psm_mod.IMU_WORD_VARS, names, strict=True):
        entry = cmap[name.upper()]
        assert f"%{var}" == entry.location, f"{name} is {entry.location}, the PSM writes %{var}"


def test_first_poll_wakes_and_configures_the_chips() -> None:
    board, plc, reader, logs = make()
    assert board.mpu.sleeping and not board.mpu.bypass and not board.hmc.continuous  # type: ignore[union-attr]
    board.load([1, 2, 3], [4, 5, 6], [7, 8, 9])  # asleep: the chips keep power-on zeros
    assert reader.poll(0.0)
    assert plc.words[:10] == [0] * 9 + [1]
    assert not board.mpu.sleeping and board.mpu.bypass
    assert board.mpu.gyro_fs_sel == 0 and board.mpu.accel_afs_sel == 0  # 131 / 16384 LSB
    hmc = board.hmc
    assert hmc is not None and hmc.continuous and hmc.gain_code == 1  # 1090 LSB/gauss
    assert len(logs) == 1 and logs[0].startswith("IMU ready") and "ImuSetPeriod 0.02" in logs[0]


def test_samples_arrive_unchanged_with_the_counter(record: ImuRecord) -> None:
    board, plc, reader, _ = make(period_s=record.period_s)
    reader.poll(-1.0)  # initialise; publishes the zero sample as counter 1
    plc.calls.clear()
    for k in range(len(record)):
        board.load(record.gyro_raw[k], record.accel_raw[k], record.mag_raw[k])
        assert reader.poll(float(record.t[k]))
        want = [*record.gyro_raw[k], *record.accel_raw[k], *record.mag_raw[k]]
        assert signed(plc.words[:9]) == [int(v) for v in want]
        assert plc.words[9] == (k + 2) & 0xFFFF
    # one call per sample, all ten words at once: the runtime never reads half a sample
    assert len(plc.calls) == len(record)
    assert all(name == "IW0" and isinstance(v, list) and len(v) == 10 for name, v in plc.calls)


def test_magnetometer_axis_order_and_mapping() -> None:
    board, plc, reader, _ = make(mag_axes=((1, -1), (0, 1), (2, 1)))
    reader.poll(0.0)
    board.load([0, 0, 0], [0, 0, 16384], [100, -200, -4096])
    reader.poll(1.0)
    # the chip sends X, Z, Y; the map takes -Y as X and X as Y; overflow keeps its code
    assert signed(plc.words[6:9]) == [200, 100, -4096]


def test_period_grid_and_late_cycles() -> None:
    board, plc, reader, _ = make(period_s=0.02)
    published = sum(reader.poll(k * 0.01) for k in range(100))  # 10 ms PSM cycles for 1 s
    assert published == 50 and reader.overruns == 0
    # one 75 ms stall: one sample on the next cycle, then the 20 ms grid again, no burst
    assert reader.poll(1.075)
    assert not reader.poll(1.085)
    assert reader.poll(1.095)
    assert reader.overruns == 1


def test_catching_up_keeps_samples_apart() -> None:
    # 5 ms PSM cycles, one cycle 19 ms late: the grid is caught up over the next samples,
    # never with two samples closer than 3/4 of a period (the PLC takes one per 10 ms scan)
    _, _, reader, _ = make(period_s=0.02)
    times = [k * 0.005 for k in range(40)]
    times = [t for t in times if not 0.040 <= t < 0.059] + [0.059]
    times = sorted(set(times) | {0.059 + 0.005 * k for k in range(1, 30)})
    published = [t for t in times if reader.poll(t)]
    gaps = np.diff(published)
    assert gaps.min() >= 0.015 - 1e-9
    assert reader.overruns == 0 and 0.040 not in published and 0.059 in published
    # then one sample per 20 ms again
    assert gaps[-5:] == pytest.approx([0.02] * 5)


def test_missing_magnetometer_says_why_and_retries() -> None:
    board = Gy87Board(hmc=None)
    _, plc, reader, logs = make(board, retry_s=2.0)
    assert not reader.poll(0.0)
    assert "no HMC5883L answers at 0x1E" in logs[-1] and "QMC5883L" in logs[-1]
    assert plc.calls == []
    board.hmc = HMC5883L()
    assert not reader.poll(1.0)  # before the retry time
    assert reader.poll(2.0)
    assert logs[-2].startswith("IMU ready") and logs[-1] == "IMU OK"


def test_wrong_chip_is_named() -> None:
    board = Gy87Board(mpu=MPU6050(who_am_i=0x70))  # an MPU6500 clone
    _, plc, reader, logs = make(board)
    assert not reader.poll(0.0)
    assert "WHO_AM_I 0x70" in logs[-1] and plc.calls == []


def test_lost_chip_stops_the_counter_then_recovers(record: ImuRecord) -> None:
    board, plc, reader, logs = make(period_s=0.02, retry_s=0.5)
    for k in range(5):
        reader.poll(k * 0.02)
    seq = plc.words[9]
    mpu = board.mpu
    board.mpu = MPU6050(address=0x69)  # the 0x68 chip is gone (loose wire)
    assert not reader.poll(0.10)
    assert "IMU read failed" in logs[-1] and plc.words[9] == seq
    assert not reader.poll(0.12) and not reader.poll(0.5)
    board.mpu = mpu  # back, but power-cycled: asleep again
    mpu.power_on_reset()
    assert reader.poll(0.61)
    board.load([10, 20, 30], [0, 0, 16384], [300, 0, -500])
    assert reader.poll(0.63)
    assert plc.words[9] == seq + 2 and signed(plc.words[:3]) == [10, 20, 30]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"period_s": 0.0}, "period"),
    ({"period_s": float("nan")}, "period"),
    ({"mpu_address": 0x40}, "0x68 or 0x69"),
    ({"mag_axes": ((0, 1), (0, 1), (2, 1))}, "MAG_AXES"),
    ({"mag_axes": ((0, 2), (1, 1), (2, 1))}, "MAG_AXES"),
])
def test_bad_settings_are_named(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make(**kwargs)


def test_decoders_against_the_data_sheet_layout() -> None:
    # ACCEL X/Y/Z, TEMP, GYRO X/Y/Z, each MSB first
    data = [0x40, 0x00, 0xC0, 0x00, 0x00, 0x01, 0x12, 0x34, 0xFF, 0xFF, 0x80, 0x00, 0x7F, 0xFF]
    gyro, accel = psm_mod.decode_mpu6050(data)
    assert accel == [16384, -16384, 1] and gyro == [-1, -32768, 32767]
    assert psm_mod.decode_hmc5883l([0xF0, 0x00, 0x00, 0x05, 0x07, 0xFF]) == [-4096, 2047, 5]
    with pytest.raises(ValueError, match="14 bytes"):
        psm_mod.decode_mpu6050(data[:12])
    assert np.array_equal(signed([0x8000, 0x7FFF]), [-32768, 32767])
