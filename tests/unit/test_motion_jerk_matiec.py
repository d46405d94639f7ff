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
import struct
import subprocess
import textwrap
from pathlib import Path

import pytest
from jerk_support import (
    CROSS_AXES,
    CROSS_DECLS,
    CROSS_JOG,
    CROSS_TIMES,
    AxisCase,
    CrossOutputs,
    cross_body,
    cross_ruckig_generator,
    ruckig_plan,
)
from matiec_run import SKIP_REASON, first_scan_both, run_tool

REPO = Path(__file__).resolve().parents[2]
ST = REPO / "st"
FILES = ["MotionJerkTypes.st", "MotionJerkRoots.st", "MotionJerkProfile.st",
         "MotionJerkStep1.st", "MotionJerkStep2.st", "MotionJerkVelocity.st",
         "MotionJerkSync.st", "MotionJerkOnline.st"]

AXES, JOG, TIMES = CROSS_AXES, CROSS_JOG, CROSS_TIMES


def _check_tool() -> Path | None:
    check = os.environ.get("MATIEC_CHECK")
    return Path(check) if check and Path(check).is_file() else None


def _lreal(x: float) -> str:
    return f"{x!r}" if "." in repr(x) or "e" in repr(x) else f"{x!r}.0"


def _program() -> str:
    outputs = CrossOutputs("Dur", "Err", lambda i, k: f"S{i}A{k}", "JogDur", "JogEnd",
                           "GenP1", "GenV2", "GenA3", "Plans")
    body = textwrap.indent(cross_body(_lreal, outputs), "  ")
    decl_samples = "\n".join(f"    S{i}A{k} : LREAL;" for i in range(len(TIMES))
                             for k in range(1, 4))
    return f"""PROGRAM JerkMain
  VAR
{CROSS_DECLS}
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
{body}
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
    p1, v2, a3 = cross_ruckig_generator()
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
    MatIEC: the same REAL setpoints as the bench compiler's (bit for bit) and, for
    the move, Ruckig's."""
    pytest.importorskip("ruckig")
    real, prog = first_scan_both(tmp_path, "joint_main.st", JOINT_FILES, _joint_program(),
                                 timeout=900)
    names = ["DUR"] + [f"{p}{m}J{j}" for p in "MH" for m in (5, 20, 40) for j in range(1, 4)]
    for n in names:  # REALs, printed to 9 digits: the same float32, bit for bit
        assert struct.pack("<f", float(real[n])) == struct.pack("<f", float(prog.get(n))), n
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
