"""MadgwickImu and MadgwickMarg chained over 6,000 samples on the real MatIEC + OpenPLC
runtime and in the bench: the same REALs, bit for bit.

The filters' update is REAL arithmetic full of literals (`2.0 * (Q.X * Q.Z - Q.W * Q.Y)`),
which MatIEC's C computes in double and rounds where the value lands; the bench computes the
same. The samples come from a deterministic formula in the PROGRAM (no input files); the
PROGRAM sums every output quaternion as LREAL, so one bit of difference at any step shows,
and keeps the last one. Skips where the real toolchain is absent.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from matiec_run import SKIP_REASON, first_scan_both, run_tool

FILES = ["ArmAngles.st", "Kinematics.st", "Quaternion.st", "OrientationFilters.st"]
STEPS = 6000

PROGRAM = f"""
PROGRAM MadgwickChain
  VAR
    Imu : MadgwickImu;
    Marg : MadgwickMarg;
    S : ImuSample;
    Q0 : Quaternion;
    K : DINT;
    T : REAL;
    SumImu : LREAL;
    SumMarg : LREAL;
    IW : REAL;
    IX : REAL;
    IY : REAL;
    IZ : REAL;
    MW : REAL;
    MX : REAL;
    MY : REAL;
    MZ : REAL;
    Errs : DINT;
    Done : BOOL;
  END_VAR
  IF NOT Done THEN
    Q0.W := 1.0;
    Imu(Reset := TRUE, InitialQuat := Q0, Beta := 0.033, SamplePeriodS := 0.01);
    Marg(Reset := TRUE, InitialQuat := Q0, Beta := 0.041, SamplePeriodS := 0.01);
    FOR K := 1 TO {STEPS} DO
      T := DINT_TO_REAL(K) * 0.01;
      S.Gyro.X := 40.0 * SIN(T * 0.7) + 3.1;
      S.Gyro.Y := 25.0 * COS(T * 1.3) - 1.7;
      S.Gyro.Z := 12.5 * SIN(T * 0.31 + 0.4);
      S.Accel.X := 0.3 * SIN(T * 0.5);
      S.Accel.Y := 0.2 * COS(T * 0.9);
      S.Accel.Z := 0.93 + 0.05 * SIN(T * 2.1);
      S.Mag.X := 0.21 + 0.1 * COS(T * 0.35);
      S.Mag.Y := 0.05 * SIN(T * 0.6);
      S.Mag.Z := -0.42;
      S.Code := 0;
      Imu(Reset := FALSE, Sample := S);
      Marg(Reset := FALSE, Sample := S);
      SumImu := SumImu + REAL_TO_LREAL(Imu.Orientation.W) + REAL_TO_LREAL(Imu.Orientation.X)
                + REAL_TO_LREAL(Imu.Orientation.Y) + REAL_TO_LREAL(Imu.Orientation.Z);
      SumMarg := SumMarg + REAL_TO_LREAL(Marg.Orientation.W)
                 + REAL_TO_LREAL(Marg.Orientation.X) + REAL_TO_LREAL(Marg.Orientation.Y)
                 + REAL_TO_LREAL(Marg.Orientation.Z);
      IF Imu.Error OR Marg.Error THEN
        Errs := Errs + 1;
      END_IF;
    END_FOR;
    IW := Imu.Orientation.W;
    IX := Imu.Orientation.X;
    IY := Imu.Orientation.Y;
    IZ := Imu.Orientation.Z;
    MW := Marg.Orientation.W;
    MX := Marg.Orientation.X;
    MY := Marg.Orientation.Y;
    MZ := Marg.Orientation.Z;
    Done := TRUE;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : MadgwickChain;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_madgwick_filters_chained_are_bit_identical_with_matiec(tmp_path: Path) -> None:
    real, prog = first_scan_both(tmp_path, "madgwick_chain.st", FILES, PROGRAM, timeout=900)
    assert int(real["ERRS"]) == 0 and int(prog.get("Errs")) == 0
    differ = []
    for n in ("SUMIMU", "SUMMARG"):  # LREALs printed to 17 digits: exact
        if float(real[n]) != float(prog.get(n)):
            differ.append(f"{n}: bench {float(prog.get(n))!r}, MatIEC {real[n]}")
    for n in ("IW", "IX", "IY", "IZ", "MW", "MX", "MY", "MZ"):  # REALs printed to 9 digits
        if struct.pack("<f", float(real[n])) != struct.pack("<f", float(prog.get(n))):
            differ.append(f"{n}: bench {float(prog.get(n))!r}, MatIEC {real[n]}")
    assert not differ, "\n".join(differ)
