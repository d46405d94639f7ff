"""The jerk-limited generator on the real MatIEC + OpenPLC toolchain.

1. A PROGRAM that plans three axes (moving start, target velocity), a jog (velocity
   interface) and runs MotionJerkGenerator for 60 scans through a target change, in its first
   scan: OpenPLC's own build (run-st.sh beside MATIEC_CHECK) and the bench compiler print the
   same LREALs (to 1e-12), and both equal Ruckig's (to 1e-9).
2. The library as the controller ships it (``armbench export`` of st/*.st and
   plc_project/Controller.st, written to a temporary folder) builds on OpenPLC: the jerk
   blocks the controller uses (all but MotionJerkOnline.st: profile 4, the jerk-limited
   halt, jog and follow) included. (An array element passed as a FUNCTION's VAR_IN_OUT made
   MatIEC emit C that does not compile; MotionJerkPlanner works on a copy.)
3. MotionJointMove's profile 4 and MotionHalt's jerk-limited braking run on OpenPLC's build
   as on the bench compiler, and the move equals Ruckig's.

Skips where the real toolchain is absent (MATIEC_CHECK=/opt/realplc/check-st.sh).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from jerk_support import AxisCase, ruckig_plan
from matiec_run import SKIP_REASON, first_scan_both, run_tool

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
FILES = ["MotionJerkTypes.st", "MotionJerkRoots.st", "MotionJerkProfile.st",
         "MotionJerkStep1.st", "MotionJerkStep2.st", "MotionJerkVelocity.st",
         "MotionJerkSync.st", "MotionJerkOnline.st"]

AXES = (AxisCase(0.5, 0.4, -0.3, 2.0, 0.2, 1.0, 2.0, 8.0),
        AxisCase(-1.0, 0.0, 0.0, -3.0, 0.0, 0.7, 3.0, 5.0),
        AxisCase(0.0, -0.2, 0.5, 0.25, 0.0, 2.0, 1.0, 3.0))
JOG = AxisCase(0.0, 0.3, 0.0, 0.0, -0.8, 1.0, 2.0, 6.0)
TIMES = (0.3, 1.1, 2.5)


def _check_tool() -> Path | None:
    check = os.environ.get("MATIEC_CHECK")
    return Path(check) if check and Path(check).is_file() else None


def _lreal(x: float) -> str:
    return f"{x!r}" if "." in repr(x) or "e" in repr(x) else f"{x!r}.0"


def _program() -> str:
    def vec(name: str, values: list[float]) -> str:
        return "\n".join(f"    {name}[{k}] := {_lreal(v)};" for k, v in enumerate(values, 1))

    lines = [vec("CurP", [c.p0 for c in AXES]), vec("CurV", [c.v0 for c in AXES]),
             vec("CurA", [c.a0 for c in AXES]), vec("TgtP", [c.pf for c in AXES]),
             vec("TgtV", [c.vf for c in AXES])]
    for k, c in enumerate(AXES, 1):
        lines.append(f"    Lim[{k}].MaxVel := {_lreal(c.vmax)};\n"
                     f"    Lim[{k}].MaxAcc := {_lreal(c.amax)};\n"
                     f"    Lim[{k}].MaxJerk := {_lreal(c.jmax)};")
    samples = []
    for i, t in enumerate(TIMES):
        for k in range(1, 4):
            samples.append(f"    Pt := MotionJerkAt(Prof := Plan.Profiles[{k}], "
                           f"TimeS := {_lreal(t)});\n    S{i}A{k} := Pt.Pos;")
    decl_samples = "\n".join(f"    S{i}A{k} : LREAL;" for i in range(len(TIMES))
                             for k in range(1, 4))
    return f"""PROGRAM JerkMain
  VAR
    Plan : MotionJerkPlanner;
    Jog : MotionJerkPlanner;
    Gen : MotionJerkGenerator;
    Lim : MotionJerkLimitSet;
    CurP : MotionJerkVector;
    CurV : MotionJerkVector;
    CurA : MotionJerkVector;
    TgtP : MotionJerkVector;
    TgtV : MotionJerkVector;
    Zero : MotionJerkVector;
    JogV : MotionJerkVector;
    JogT : MotionJerkVector;
    Pt : MotionJerkPoint;
    K : INT;
    Dur : LREAL;
    JogDur : LREAL;
    JogEnd : LREAL;
    GenP1 : LREAL;
    GenV2 : LREAL;
    GenA3 : LREAL;
    Plans : INT;
    Err : INT;
{decl_samples}
    Done : BOOL;
  END_VAR
  IF NOT Done THEN
{chr(10).join(lines)}
    Plan(Joints := 3, VelocityMode := FALSE, Sync := 0, CurrentPos := CurP,
         CurrentVel := CurV, CurrentAcc := CurA, TargetPos := TgtP, TargetVel := TgtV,
         TargetAcc := Zero, Limits := Lim);
    Dur := Plan.Duration;
    Err := Plan.ErrorId;
{chr(10).join(samples)}
    JogV[1] := {_lreal(JOG.v0)};
    JogT[1] := {_lreal(JOG.vf)};
    Lim[4].MaxVel := {_lreal(JOG.vmax)};
    Lim[4].MaxAcc := {_lreal(JOG.amax)};
    Lim[4].MaxJerk := {_lreal(JOG.jmax)};
    Lim[1] := Lim[4];
    Jog(Joints := 1, VelocityMode := TRUE, Sync := 0, CurrentPos := Zero,
        CurrentVel := JogV, CurrentAcc := Zero, TargetPos := Zero, TargetVel := JogT,
        TargetAcc := Zero, Limits := Lim);
    JogDur := Jog.Duration;
    Pt := MotionJerkAt(Prof := Jog.Profiles[1], TimeS := JogDur);
    JogEnd := Pt.Pos;
    FOR K := 1 TO 60 DO
      IF K = 30 THEN
        TgtP[2] := 1.0;
      END_IF;
      Gen(Enable := TRUE, CycleTime := 0.01, Joints := 3, VelocityMode := FALSE, Sync := 0,
          TargetPos := TgtP, TargetVel := Zero, TargetAcc := Zero, Limits := Lim,
          StartPos := CurP, StartVel := CurV, StartAcc := CurA);
      IF Gen.NewPlan THEN
        Plans := Plans + 1;
      END_IF;
    END_FOR;
    GenP1 := Gen.Position[1];
    GenV2 := Gen.Velocity[2];
    GenA3 := Gen.Acceleration[3];
    Done := TRUE;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : JerkMain;
  END_RESOURCE
END_CONFIGURATION
"""


def _ruckig_generator() -> tuple[float, float, float]:
    """Ruckig.update over the program's 60 scans (the jog axis' limits on axis 1, as the
    program sets Lim[1] := Lim[4] before starting the generator)."""
    import ruckig

    otg = ruckig.Ruckig(3, 0.01)
    inp, out = ruckig.InputParameter(3), ruckig.OutputParameter(3)
    inp.current_position = [c.p0 for c in AXES]
    inp.current_velocity = [c.v0 for c in AXES]
    inp.current_acceleration = [c.a0 for c in AXES]
    target = [c.pf for c in AXES]
    inp.max_velocity = [JOG.vmax] + [c.vmax for c in AXES[1:]]
    inp.max_acceleration = [JOG.amax] + [c.amax for c in AXES[1:]]
    inp.max_jerk = [JOG.jmax] + [c.jmax for c in AXES[1:]]
    for k in range(1, 61):
        if k == 30:
            target[1] = 1.0
        inp.target_position = target
        otg.update(inp, out)
        out.pass_to_input(inp)
    return out.new_position[0], out.new_velocity[1], out.new_acceleration[2]


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_real_matiec_runs_the_planner_and_generator(tmp_path: Path) -> None:
    pytest.importorskip("ruckig")
    real, prog = first_scan_both(tmp_path, "jerk_main.st", FILES, _program())
    names = ["DUR", "JOGDUR", "JOGEND", "GENP1", "GENV2", "GENA3"] + [
        f"S{i}A{k}" for i in range(len(TIMES)) for k in range(1, 4)]
    for n in names:
        assert float(real[n]) == pytest.approx(float(prog.get(n)), rel=1e-12, abs=1e-12), n
    assert int(real["ERR"]) == 0 and int(real["PLANS"]) == 2

    ref = ruckig_plan(AXES)
    assert float(real["DUR"]) == pytest.approx(ref.duration, rel=1e-12)
    for i, t in enumerate(TIMES):
        p_ref = ref.at(t)[0]
        for k in range(3):
            assert float(real[f"S{i}A{k + 1}"]) == pytest.approx(p_ref[k], abs=1e-9)
    jog = ruckig_plan((JOG,), interface="Velocity")
    assert float(real["JOGDUR"]) == pytest.approx(jog.duration, rel=1e-12)
    assert float(real["JOGEND"]) == pytest.approx(jog.at(jog.duration)[0][0], abs=1e-9)
    p1, v2, a3 = _ruckig_generator()
    assert float(real["GENP1"]) == pytest.approx(p1, abs=1e-9)
    assert float(real["GENV2"]) == pytest.approx(v2, abs=1e-9)
    assert float(real["GENA3"]) == pytest.approx(a3, abs=1e-9)


@pytest.mark.skipif(_check_tool() is None,
                    reason="MATIEC_CHECK (e.g. /opt/realplc/check-st.sh) not set or missing")
def test_real_openplc_builds_the_library_with_the_jerk_blocks(tmp_path: Path) -> None:
    from armbench.export.generate import OPENPLC_FILE, generate

    exp = generate()
    names = [s.name for s in exp.sources]
    used = [f for f in FILES if f != "MotionJerkOnline.st"]  # the generator: not used
    assert all(f"st/{f}" in names for f in used), names
    whole = tmp_path / "arm_controller.st"
    whole.write_bytes(exp.files[OPENPLC_FILE])
    check = _check_tool()
    assert check is not None
    bash = shutil.which("bash") or "/bin/bash"
    run = subprocess.run([bash, str(check), str(whole)], capture_output=True, text=True,
                         timeout=900, check=False)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]


JOINT_FILES = ["ArmAngles.st", "Kinematics.st", "MotionTypes.st", "MotionProfiles.st",
               *FILES, "MotionJoint.st"]


def _joint_program() -> str:
    """MotionJointMove with profile 4 for 40 calls (10 ms each), then MotionHalt with a jerk
    limit taking the group over for 40 more: the setpoints at three calls of each."""
    marks = (5, 20, 40)
    decl = "\n".join(f"    M{m}J{j} : REAL;\n    H{m}J{j} : REAL;"
                     for m in marks for j in range(1, 4))
    keep_m = "\n".join(f"      IF K = {m} THEN M{m}J1 := G.Position[1]; M{m}J2 := G.Position[2];"
                       f" M{m}J3 := G.Position[3]; END_IF;" for m in marks)
    keep_h = "\n".join(f"      IF K = {m} THEN H{m}J1 := G.Position[1]; H{m}J2 := G.Position[2];"
                       f" H{m}J3 := G.Position[3]; END_IF;" for m in marks)
    return f"""PROGRAM JointMain
  VAR
    G : MotionGroup;
    MoveFb : MotionJointMove;
    HaltFb : MotionHalt;
    Tgt : JointVector;
    K : INT;
    Dur : REAL;
    HaltErr : INT;
{decl}
    Done : BOOL;
  END_VAR
  IF NOT Done THEN
    G.Joints := 3;
    FOR K := 1 TO 6 DO
      G.Limits.LowerDeg[K] := -170.0;
      G.Limits.UpperDeg[K] := 170.0;
      G.Limits.MaxVelDeg[K] := 150.0;
      G.Limits.MaxAccDeg[K] := 1000.0;
    END_FOR;
    G.Position[1] := -40.0;
    G.Position[2] := 40.0;
    G.Position[3] := 95.0;
    Tgt[1] := 45.0;
    Tgt[2] := 110.0;
    Tgt[3] := 30.0;
    FOR K := 1 TO 40 DO
      MoveFb(Execute := TRUE, Target := Tgt, Profile := 4, Velocity := 140.0,
           Acceleration := 800.0, Jerk := 6000.0, CycleTime := 0.01, Group := G);
{keep_m}
    END_FOR;
    Dur := MoveFb.Duration;
    FOR K := 1 TO 40 DO
      HaltFb(Execute := TRUE, Deceleration := 500.0, Jerk := 6000.0, CycleTime := 0.01,
           Group := G);
{keep_h}
    END_FOR;
    HaltErr := HaltFb.ErrorId;
    Done := TRUE;
  END_IF;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : JointMain;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_real_matiec_runs_profile4_and_the_jerk_halt(tmp_path: Path) -> None:
    """MotionJointMove's profile 4 and MotionHalt's jerk-limited braking built by OpenPLC's
    MatIEC: the same REAL setpoints as the bench compiler's (to float32 rounding) and, for
    the move, Ruckig's."""
    pytest.importorskip("ruckig")
    real, prog = first_scan_both(tmp_path, "joint_main.st", JOINT_FILES, _joint_program(),
                                 timeout=900)
    names = ["DUR"] + [f"{p}{m}J{j}" for p in "MH" for m in (5, 20, 40) for j in range(1, 4)]
    for n in names:
        assert float(real[n]) == pytest.approx(float(prog.get(n)), rel=2e-7, abs=1e-5), n
    assert int(real["HALTERR"]) == 0
    f32 = [float(x) for x in (-40.0, 40.0, 95.0)]
    axes = [AxisCase(p, 0.0, 0.0, t, 0.0, 140.0, 800.0, 6000.0)
            for p, t in zip(f32, (45.0, 110.0, 30.0), strict=True)]
    ref = ruckig_plan(axes, "Phase")
    assert float(real["DUR"]) == pytest.approx(ref.duration, rel=1e-6)
    dt32 = 0.009999999776482582  # REAL 0.01
    for m in (5, 20, 40):
        p = ref.at(m * dt32)[0]
        for j in range(3):
            assert float(real[f"M{m}J{j + 1}"]) == pytest.approx(p[j], abs=2e-5)
