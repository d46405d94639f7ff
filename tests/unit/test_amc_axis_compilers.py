"""The PLCopen single-axis and axis-group layers (st/AMC*.st) on the real compilers: a
program using every AMC_* block (power, an absolute move aborted by a velocity move, MC_Stop
held for a while, homing, a relative move under an override, the read blocks) and a group
program (three axes in an AMC_GroupAxes array, the 3-DOF model, GroupEnable, an axis error
stopping the group, GroupReset, MoveDirectAbsolute, MoveLinearAbsolute, the read blocks),
each built and run for 260 scans by OpenPLC v3's MatIEC (MATIEC_CHECK / run-st.sh) with the
same results as the bench compiler, and built by STruC++ (OpenPLC v4, STRUCPP) and g++
against its runtime headers. Each skips with the reason when its tool is not set."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
from matiec_run import SKIP_REASON as MATIEC_SKIP
from matiec_run import run_tool

from strucpp_tool import SKIP_REASON as STRUCPP_SKIP
from strucpp_tool import V4_CXX_FLAGS, find_strucpp

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
SCANS = 260
# the layer and what it uses, in dependency order
FILES = ["ArmAngles.st", "Kinematics.st", "MG996R.st", "MotionJerkTypes.st",
         "MotionJerkRoots.st", "MotionJerkProfile.st",
         "MotionJerkStep1.st", "MotionJerkStep2.st", "MotionJerkVelocity.st",
         "MotionJerkSync.st", "MotionJerkOnline.st", "AMCTypes.st", "AMCAxisDrive.st",
         "AMCAxisMove.st", "AMCAxisAdmin.st", "AMCGroupTypes.st", "AMCGroupDrive.st",
         "AMCGroupAdmin.st", "AMCGroupMove.st"]
OUTPUTS = ["SCAN", "POS", "VEL", "STATE", "ABORTSEEN", "DONESEEN", "STOPDONE", "HOMEDONE",
           "RELDONE", "ERRSEEN", "ERRCODE", "INVELSEEN", "HOMED", "STATUSFLAGS"]

PROGRAM = """
PROGRAM AMCMain
  VAR
    Ax : AMC_AxisRef;
    Drive : AMC_AxisDrive;
    Power : AMC_Power;
    MoveA : AMC_MoveAbsolute;
    MoveV : AMC_MoveVelocity;
    Rel : AMC_MoveRelative;
    Halt1 : AMC_Halt;
    Stop1 : AMC_Stop;
    Home1 : AMC_Home;
    Reset1 : AMC_Reset;
    Ovr : AMC_SetOverride;
    Stat : AMC_ReadStatus;
    RPos : AMC_ReadActualPosition;
    RVel : AMC_ReadActualVelocity;
    RErr : AMC_ReadAxisError;
    Scan : INT;
    Pos : LREAL;
    Vel : LREAL;
    State : INT;
    AbortSeen : BOOL;
    DoneSeen : BOOL;
    StopDone : BOOL;
    HomeDone : BOOL;
    RelDone : BOOL;
    ErrSeen : BOOL;
    ErrCode : INT;
    InVelSeen : BOOL;
    Homed : BOOL;
    StatusFlags : INT;
  END_VAR
  Scan := Scan + 1;
  Power(Axis := Ax, Enable := TRUE);
  Reset1(Axis := Ax, Execute := Scan >= 250);
  Ovr(Axis := Ax, Enable := Scan >= 150, VelFactor := 0.5, AccFactor := 1.0, JerkFactor := 1.0);
  MoveA(Axis := Ax, Execute := Scan >= 2, Position := 45.0, Velocity := 100.0,
        Acceleration := 500.0, Deceleration := 600.0, Jerk := 5000.0, BufferMode := 0);
  MoveV(Axis := Ax, Execute := Scan >= 20, Velocity := 20.0, Acceleration := 300.0,
        Deceleration := 300.0, Jerk := 3000.0, Direction := -1, BufferMode := 0);
  Stop1(Axis := Ax, Execute := (Scan >= 60) AND (Scan < 90), Deceleration := 300.0,
        Jerk := 3000.0);
  Halt1(Axis := Ax, Execute := Scan >= 70, Deceleration := 300.0, Jerk := 3000.0,
        BufferMode := 0);
  Home1(Axis := Ax, Execute := Scan >= 100, Position := 10.0, BufferMode := 0);
  Rel(Axis := Ax, Execute := Scan >= 160, Distance := -25.0, Velocity := 50.0,
      Acceleration := 400.0, Deceleration := 400.0, Jerk := 4000.0, BufferMode := 0);
  Stat(Axis := Ax, Enable := TRUE);
  RPos(Axis := Ax, Enable := TRUE);
  RVel(Axis := Ax, Enable := TRUE);
  RErr(Axis := Ax, Enable := TRUE);
  Drive(Axis := Ax, CycleTime := 0.02);
  Pos := RPos.Position;
  Vel := RVel.Velocity;
  State := Ax.State;
  AbortSeen := AbortSeen OR MoveA.CommandAborted;
  DoneSeen := DoneSeen OR MoveA.Done;
  StopDone := StopDone OR Stop1.Done;
  HomeDone := HomeDone OR Home1.Done;
  RelDone := RelDone OR Rel.Done;
  ErrSeen := ErrSeen OR Halt1.Error;
  IF Halt1.Error THEN
    ErrCode := Halt1.ErrorID;
  END_IF;
  InVelSeen := InVelSeen OR MoveV.InVelocity;
  Homed := Ax.Homed;
  StatusFlags := 0;
  IF Stat.Standstill THEN
    StatusFlags := StatusFlags + 1;
  END_IF;
  IF Stat.Disabled OR Stat.ErrorStop OR Stat.Stopping THEN
    StatusFlags := StatusFlags + 10;
  END_IF;
  IF RErr.AxisErrorID <> 0 THEN
    StatusFlags := StatusFlags + 100;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : AMCMain;
  END_RESOURCE
END_CONFIGURATION
"""


def _source(folder: Path, program: str = "") -> Path:
    """The layer's files and ``program`` (the axis program by default) as one upload file."""
    stem = "amc_group_main" if program else "amc_main"
    path = folder / f"{stem}.st"
    path.write_text("\n".join((ST / f).read_text(encoding="utf-8") for f in FILES)
                    + (program or PROGRAM), encoding="utf-8")
    return path


def _bench(path: Path, scans: int = 0, outputs: list[str] | None = None) -> dict[str, float]:
    """The program's ``outputs`` after ``scans`` scans (the axis program's by default) on the
    bench's compiler."""
    from armbench.compiler import compile_files
    mod = compile_files([path])
    prog = mod.instance("instance0")
    mod.config_init()
    for k in range(scans or SCANS):
        mod.run_task_index(0, k * 20_000_000)
    return {n: float(prog.get(n)) for n in outputs or OUTPUTS}


def _assert_real_matiec_as_bench(path: Path, outputs: list[str]) -> None:
    """The real OpenPLC v3 build runs SCANS scans of ``path`` to the bench's values."""
    bash = shutil.which("bash") or "/bin/bash"
    run_st = run_tool()
    assert run_st is not None
    run = subprocess.run([bash, str(run_st), "-n", str(SCANS), str(path)], capture_output=True,
                         text=True, timeout=1200, check=False)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    real = {k.upper(): v for k, v in
            re.findall(r"^instance0\.(\w+)=(\S+)$", run.stdout, flags=re.M)}
    bench = _bench(path, SCANS, outputs)
    for name in outputs:
        value = real[name]
        num = 1.0 if value == "TRUE" else 0.0 if value == "FALSE" else float(value)
        assert num == pytest.approx(bench[name], rel=1e-12, abs=1e-12), name


def _assert_strucpp_builds(path: Path) -> None:
    """STruC++ compiles ``path`` and g++ builds its C++ with OpenPLC v4's flags."""
    tool = find_strucpp()
    assert tool is not None
    out = path.with_suffix(".cpp")
    res = tool.compile(path, out)
    assert res.ok, res.output[-3000:]
    obj = tool.cxx(*V4_CXX_FLAGS, "-DSTRUCPP_THREADED", "-c", str(out), "-o",
                   str(path.with_suffix(".o")))
    assert obj.ok, obj.output[-3000:]


def test_bench_run_of_the_program_is_the_scripted_story(tmp_path: Path) -> None:
    """What the program must show (independent of any compiler): the move aborted by the
    velocity move, MC_Stop held, Halt refused while Stopping (51), homing, the relative move
    under the override, Standstill at the end at 10 - 25 deg."""
    got = _bench(_source(tmp_path))
    assert got["ABORTSEEN"] == 1 and got["DONESEEN"] == 0 and got["INVELSEEN"] == 1
    assert got["STOPDONE"] == 1 and got["ERRSEEN"] == 1 and got["ERRCODE"] == 51
    assert got["HOMEDONE"] == 1 and got["HOMED"] == 1 and got["RELDONE"] == 1
    assert got["STATE"] == 1 and got["STATUSFLAGS"] == 1
    assert got["POS"] == pytest.approx(-15.0, abs=1e-9) and got["VEL"] == 0.0


@pytest.mark.skipif(run_tool() is None, reason=MATIEC_SKIP)
def test_real_matiec_runs_the_layer_as_the_bench(tmp_path: Path) -> None:
    _assert_real_matiec_as_bench(_source(tmp_path), OUTPUTS)


@pytest.mark.skipif(find_strucpp() is None, reason=STRUCPP_SKIP)
def test_strucpp_builds_the_layer(tmp_path: Path) -> None:
    _assert_strucpp_builds(_source(tmp_path))


# ------------------------------------------------------------------------ the group layer
GROUP_OUTPUTS = ["SCAN", "GSTATE", "ERRSTOPSEEN", "GROUPERR", "ERRAXIS", "AXISERR", "RESETDONE",
                 "ENABLEDONE", "KINDONE", "ENABLEREFUSED", "CARTX", "CARTY", "CARTZ", "JOINT1",
                 "JOINT2", "JOINT3", "FLAGS", "DIRDONE", "DIRSCANS", "LINDONE", "LINERR"]

GROUP_PROGRAM = """
PROGRAM AMCGroupMain
  VAR
    Grp : AMC_AxesGroupRef;
    Axs : AMC_GroupAxes;
    Pw1 : AMC_Power;
    Pw2 : AMC_Power;
    Pw3 : AMC_Power;
    Mv1 : AMC_MoveAbsolute;
    Vl2 : AMC_MoveVelocity;
    Dr1 : AMC_AxisDrive;
    Dr2 : AMC_AxisDrive;
    Dr3 : AMC_AxisDrive;
    Kin : AMC_SetKinTransform;
    GEn : AMC_GroupEnable;
    Dis : AMC_GroupDisable;
    Rst : AMC_GroupReset;
    GDir : AMC_MoveDirectAbsolute;
    GLin : AMC_MoveLinearAbsolute;
    LinTgt : AMC_GroupVector;
    LinDone : BOOL;
    LinErr : INT;
    Tgt : AMC_GroupVector;
    DirDone : BOOL;
    DirScans : INT;
    Joint1 : LREAL;
    Joint3 : LREAL;
    Mon : AMC_GroupDrive;
    Stat : AMC_GroupReadStatus;
    RErr : AMC_GroupReadError;
    RPos : AMC_GroupReadActualPosition;
    Geo : ArmGeometry;
    Init : BOOL;
    Scan : INT;
    GState : INT;
    ErrStopSeen : BOOL;
    GroupErr : INT;
    ErrAxis : INT;
    AxisErr : INT;
    ResetDone : BOOL;
    EnableDone : BOOL;
    KinDone : BOOL;
    EnableRefused : INT;
    CartX : LREAL;
    CartY : LREAL;
    CartZ : LREAL;
    Joint2 : LREAL;
    Flags : INT;
  END_VAR
  IF NOT Init THEN
    Init := TRUE;
    Axs[3].MinPosDeg := 0.0;
    Axs[3].MaxPosDeg := 180.0;
    Axs[3].SetPosDeg := 90.0;
    Tgt[1] := 10.0;
    Tgt[2] := 20.0;
    Tgt[3] := 100.0;
  END_IF;
  Scan := Scan + 1;
  Pw1(Axis := Axs[1], Enable := TRUE);
  Pw2(Axis := Axs[2], Enable := TRUE);
  Pw3(Axis := Axs[3], Enable := TRUE);
  Mv1(Axis := Axs[1], Execute := Scan >= 3, Position := 30.0, Velocity := 90.0,
      Acceleration := 400.0, Deceleration := 400.0, Jerk := 4000.0, BufferMode := 0);
  Vl2(Axis := Axs[2], Execute := Scan >= 80, Velocity := 60.0, Acceleration := 300.0,
      Deceleration := 300.0, Jerk := 3000.0, Direction := 1, BufferMode := 0);
  Kin(AxesGroup := Grp, Execute := Scan >= 2, KinModel := 1, Geometry := Geo);
  GEn(AxesGroup := Grp, Axes := Axs, Execute := (Scan >= 4) AND (Scan < 60) OR (Scan >= 62));
  Rst(AxesGroup := Grp, Axes := Axs, Execute := Scan >= 175);
  GDir(AxesGroup := Grp, Axes := Axs, Execute := Scan >= 185, Position := Tgt,
       VelFactor := 1.0, AccFactor := 1.0, JerkFactor := 1.0, BufferMode := 0);
  IF GDir.Busy THEN
    DirScans := DirScans + 1;
  END_IF;
  DirDone := DirDone OR GDir.Done;
  IF Scan = 229 THEN   (* the group at rest after the direct move *)
    LinTgt := Grp.SetCart;
    LinTgt[2] := LinTgt[2] + 20.0;
    LinTgt[3] := LinTgt[3] - 10.0;
  END_IF;
  GLin(AxesGroup := Grp, Axes := Axs, Execute := Scan >= 230, Position := LinTgt,
       Velocity := 100.0, Acceleration := 1000.0, Jerk := 20000.0, BufferMode := 0);
  LinDone := LinDone OR GLin.Done;
  IF GLin.Error THEN
    LinErr := GLin.ErrorID;
  END_IF;
  Dis(AxesGroup := Grp, Execute := Scan >= 255);
  Mon(AxesGroup := Grp, Axes := Axs, CycleTime := 0.02);
  Stat(AxesGroup := Grp, Enable := TRUE);
  RErr(AxesGroup := Grp, Axes := Axs, Enable := TRUE);
  RPos(AxesGroup := Grp, Enable := TRUE);
  Dr1(Axis := Axs[1], CycleTime := 0.02);
  Dr2(Axis := Axs[2], CycleTime := 0.02);
  Dr3(Axis := Axs[3], CycleTime := 0.02);
  GState := Grp.State;
  ErrStopSeen := ErrStopSeen OR Stat.GroupErrorStop;
  IF RErr.GroupErrorID <> 0 THEN
    GroupErr := RErr.GroupErrorID;
    ErrAxis := RErr.ErrorAxis;
    AxisErr := RErr.AxisErrorID;
  END_IF;
  ResetDone := ResetDone OR Rst.Done;
  EnableDone := EnableDone OR GEn.Done;
  KinDone := KinDone OR Kin.Done;
  IF GEn.Error THEN
    EnableRefused := GEn.ErrorID;
  END_IF;
  CartX := RPos.Position[1];
  CartY := RPos.Position[2];
  CartZ := RPos.Position[3];
  Joint1 := RPos.JointPosition[1];
  Joint2 := RPos.JointPosition[2];
  Joint3 := RPos.JointPosition[3];
  Flags := 0;
  IF Stat.GroupDisabled THEN
    Flags := Flags + 1;
  END_IF;
  IF Stat.GroupStandby THEN
    Flags := Flags + 10;
  END_IF;
  IF Stat.GroupErrorStop THEN
    Flags := Flags + 100;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : AMCGroupMain;
  END_RESOURCE
END_CONFIGURATION
"""


def _group_source(folder: Path) -> Path:
    return _source(folder, GROUP_PROGRAM)


def _group_bench(path: Path, scans: int) -> dict[str, float]:
    return _bench(path, scans, GROUP_OUTPUTS)


def test_bench_run_of_the_group_program_is_the_scripted_story(tmp_path: Path) -> None:
    """Independent of any compiler: the group enabled with the 3-DOF model, the enable refused
    while axis 1 moves (AxisNotReady 57), axis 2 running into its range end stops the group
    (GroupAxisError 58, axis 2, JointLimit 10), GroupReset brings it back to GroupStandby, and
    the Cartesian position is the closed-form FK of the joints, and a MoveDirectAbsolute
    to (10, 20, 100) deg and a MoveLinearAbsolute from there by (0, 20, -10) mm arrive."""
    import math
    got = _group_bench(_group_source(tmp_path), 250)
    assert got["KINDONE"] == 1 and got["ENABLEDONE"] == 1 and got["ENABLEREFUSED"] == 57
    assert got["ERRSTOPSEEN"] == 1 and got["GROUPERR"] == 58 and got["ERRAXIS"] == 2
    assert got["AXISERR"] == 10 and got["RESETDONE"] == 1
    assert got["GSTATE"] == 1 and got["FLAGS"] == 10
    assert got["DIRDONE"] == 1 and got["DIRSCANS"] > 5
    assert got["LINDONE"] == 1 and got["LINERR"] == 0
    t1, t2, t3 = (math.radians(got["JOINT1"]), math.radians(got["JOINT2"]),
                  math.radians(got["JOINT3"] - 180.0))
    reach = 20.0 + 120.0 * math.cos(t2) + 130.0 * math.cos(t2 + t3)
    assert got["CARTX"] == pytest.approx(reach * math.cos(t1), abs=2e-3)
    assert got["CARTY"] == pytest.approx(reach * math.sin(t1), abs=2e-3)
    assert got["CARTZ"] == pytest.approx(100.0 + 120.0 * math.sin(t2)
                                         + 130.0 * math.sin(t2 + t3), abs=2e-3)
    # the line ended where it should: FK(10, 20, 100 deg) + (0, 20, -10) mm
    t1, t2, t3 = math.radians(10.0), math.radians(20.0), math.radians(100.0 - 180.0)
    reach = 20.0 + 120.0 * math.cos(t2) + 130.0 * math.cos(t2 + t3)
    want = (reach * math.cos(t1), reach * math.sin(t1) + 20.0,
            100.0 + 120.0 * math.sin(t2) + 130.0 * math.sin(t2 + t3) - 10.0)
    assert (got["CARTX"], got["CARTY"], got["CARTZ"]) == pytest.approx(want, abs=1e-2)
    end = _group_bench(_group_source(tmp_path), 260)
    assert end["GSTATE"] == 0 and end["FLAGS"] == 1


@pytest.mark.skipif(run_tool() is None, reason=MATIEC_SKIP)
def test_real_matiec_runs_the_group_layer_as_the_bench(tmp_path: Path) -> None:
    _assert_real_matiec_as_bench(_group_source(tmp_path), GROUP_OUTPUTS)


@pytest.mark.skipif(find_strucpp() is None, reason=STRUCPP_SKIP)
def test_strucpp_builds_the_group_layer(tmp_path: Path) -> None:
    _assert_strucpp_builds(_group_source(tmp_path))

