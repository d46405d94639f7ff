"""The whole IMU input chain a Raspberry Pi runs, on the bench: chip registers (MPU6050 and
HMC5883L models) -> the PSM's ImuReader (plc_project/psm/arm_io_psm.py) -> the soft PLC's
input words, exactly where OpenPLC's PSM layer puts them -> the controller's Madgwick MARG.

Reference: the ``ahrs`` package's Madgwick.updateMARG on the simulator's samples, converted in
float32 as ImuRawToSample does. A wrong register, byte order or axis order anywhere on the way
(the HMC5883L sends X, Z, Y) breaks the agreement by far more than float32 rounding.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from fast_plc import FastPlc
from imu_support import float32_physical

from armbench.controller_client import ERR_OK, ArmControllerClient
from armbench.plant.imu import HandTrajectory, ImuModel, simulate
from armbench.plant.imu_chips import Gy87Board
from armbench.registermap import controller_map
from armbench.softplc.modbus_client import PlcClient
from psm_script import ImageVars, load_psm_script

ahrs_filters = pytest.importorskip("ahrs.filters")

AGREEMENT_TOL = 2.0e-6  # per quaternion component, as tests/controller/test_imu.py
BETA = 0.041




def test_chip_registers_to_controller_filter(fast_controller: FastPlc) -> None:
    psm = load_psm_script("arm_io_psm_chain")
    record = simulate(HandTrajectory(), ImuModel(), duration_s=4.0, rate_hz=50.0, seed=5)
    gyro, accel, mag = float32_physical(record)

    board = Gy87Board()
    inputs = ImageVars(fast_controller.plc.image, fast_controller.plc.lock)
    taken_md = controller_map()["IMULASTSEQ"].index
    quat_md = [controller_map()[n].index for n in ("IMUQUATW", "IMUQUATX", "IMUQUATY",
                                                    "IMUQUATZ")]
    reader = psm.ImuReader(bus=board, plc=inputs, period_s=record.period_s,
                           sleep=lambda _s: None, log=lambda _m: None)
    with inputs.lock:  # continue the counter where an earlier test left it
        reader.seq = inputs.image.iw[9]
    with PlcClient(*fast_controller.address) as modbus, ArmControllerClient(modbus) as ctl:
        assert ctl.imu_select_filter("madgwick_marg", BETA) == ERR_OK
        assert ctl.imu_set_period(record.period_s) == ERR_OK
        assert ctl.imu_reset(tuple(record.quat_true[0])) == ERR_OK
        assert reader.initialise() is None  # wakes the chips; no sample published yet

        mw = ahrs_filters.Madgwick(Dt=record.period_s, gain=BETA)
        q = record.quat_true[0].copy()
        worst = 0.0
        for k in range(1, len(record)):
            board.load(record.gyro_raw[k], record.accel_raw[k], record.mag_raw[k])
            assert reader.poll(float(record.t[k]))
            deadline = time.monotonic() + 5.0
            while True:
                with inputs.lock:
                    if inputs.image.md[taken_md] == reader.seq:
                        words = [inputs.image.md[i] for i in quat_md]
                        break
                assert time.monotonic() < deadline, "the PLC did not take the PSM's sample"
                time.sleep(0.0005)
            got = np.frombuffer(np.array(words, dtype=np.uint32).tobytes(), dtype=np.float32)
            q = mw.updateMARG(q, np.radians(gyro[k]), accel[k], mag[k])
            worst = max(worst, float(np.abs(got.astype(np.float64) - q).max()))
        st = ctl.imu_state()
    print(f"\nchip registers -> PSM -> PLC Madgwick MARG vs ahrs, {len(record) - 1} samples: "
          f"max |dq| {worst:.2e}")
    assert st.samples == len(record) - 1 and st.missed == 0 and st.error_id == ERR_OK
    assert worst < AGREEMENT_TOL
