"""The fixed-point 003 line and the 5-axis IK on the real MatIEC + OpenPLC runtime.

One PROGRAM runs document 003's line (Reset + 100 steps of ChainResolvedRateFixed) and a
5-axis IK in its first scan; OpenPLC's own toolchain (the scripts MATIEC_CHECK and MATIEC_RUN
name, see the README) and the bench compiler must print the same integers and REAL joints, bit
for bit. Skips where the real toolchain is absent.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from matiec_run import SKIP_REASON, first_scan_both, run_tool

from armbench.plant import redundant_chain as rc

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
FILES = ["ArmAngles.st", "Kinematics.st", "KinematicsFixedTables.st", "KinematicsFixed.st",
         "KinematicsChainFixed.st", "Kinematics5Axis.st"]


def _program() -> str:
    init = rc.to_turn24(rc.start_configuration(rc.line_points()[0]))
    inits = "\n".join(f"    Init[{k}] := {v};" for k, v in enumerate(init, start=1))
    return f"""PROGRAM ChainLineMain
  VAR
    Rr : ChainResolvedRateFixed;
    Ik : InverseKinematik5Axis;
    Geo : ChainGeometryFixed;
    Geo5 : FiveAxisGeometry;
    Init : ChainJointsFixed;
    K : DINT;
    Q1 : DINT;
    Q2 : DINT;
    Q3 : DINT;
    Q4 : DINT;
    Sum : LINT;
    Fails : DINT;
    Done : BOOL;
    Base5 : REAL;
    Shoulder5 : REAL;
    Elbow5 : REAL;
    Wrist5 : REAL;
    Err5 : INT;
  END_VAR
  IF NOT Done THEN
{inits}
    Rr(TargetXUm := 0, TargetYUm := 0, TargetZUm := 0, Geometry := Geo, DampingUm := 0,
       Reset := TRUE, InitJoints := Init);
    FOR K := 1 TO 100 DO
      Rr(TargetXUm := 522689 + (248750 * K) / 100, TargetYUm := -818450 - (147250 * K) / 100,
         TargetZUm := 472752 + (248750 * K) / 100, Geometry := Geo, DampingUm := 0,
         Reset := FALSE, InitJoints := Init);
      IF NOT Rr.Valid THEN
        Fails := Fails + 1;
      END_IF;
      Sum := Sum + DINT_TO_LINT(Rr.Joints[1]) + DINT_TO_LINT(Rr.Joints[2])
             + DINT_TO_LINT(Rr.Joints[3]) + DINT_TO_LINT(Rr.Joints[4]);
    END_FOR;
    Q1 := Rr.Joints[1];
    Q2 := Rr.Joints[2];
    Q3 := Rr.Joints[3];
    Q4 := Rr.Joints[4];
    Ik(XMm := 150.0, YMm := 60.0, ZMm := 90.0, TipFixed := TRUE, UseToolVector := FALSE,
       PitchDeg := -30.0, RollDeg := 20.0, DirX := 0.0, DirY := 0.0, DirZ := 0.0,
       ElbowUp := TRUE, Geometry := Geo5);
    Base5 := Ik.Angles.Base;
    Shoulder5 := Ik.Angles.Shoulder;
    Elbow5 := Ik.Angles.Elbow;
    Wrist5 := Ik.Angles.GripperUpDown;
    Err5 := Ik.ErrorId;
    Done := TRUE;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : ChainLineMain;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_real_matiec_runs_the_003_line_bit_for_bit(tmp_path: Path) -> None:
    real, prog = first_scan_both(tmp_path, "chain_line_main.st", FILES, _program())
    ints = ["Q1", "Q2", "Q3", "Q4", "SUM", "FAILS", "ERR5"]
    ours = {n: int(prog.get(n)) for n in ints}
    print(f"\nreal MatIEC: {[real.get(n) for n in ints]}\nbench:       "
          f"{[ours[n] for n in ints]}")
    for n in ints:
        assert int(real[n]) == ours[n], n
    assert ours["FAILS"] == 0 and ours["ERR5"] == 0
    for n in ("BASE5", "SHOULDER5", "ELBOW5", "WRIST5"):  # REALs printed to 9 digits
        assert struct.pack("<f", float(real[n])) == struct.pack("<f", float(prog.get(n))), n
