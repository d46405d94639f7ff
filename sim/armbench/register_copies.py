"""Which located register of plc_project/Controller.st shows what: the plain copies between
the PROGRAM's located variables and the state of its blocks, in one table.

The program keeps all of its state in unlocated variables and rewrites every located output
at the end of every scan (Controller.st, SELF-DEFENCE). Each row below is one such copy,
``(located variable, ST expression)`` for an output and ``(ST target, located variable)``
for an input; the conversions a register's type needs (BOOL_TO_DINT, INT_TO_DINT, ...) are
part of the expression. ``python -m armbench.batchgen`` writes the rows into the
``register copy in`` / ``register copy out`` regions of the PROGRAM's body and checks that
every located output is written by exactly one generated copy and that the hand-written
body names no located variable, so this table (with the mailbox and batch copies that
batchgen derives from its own layout) is the whole story of what each register shows.

Joint ``k`` of a JointVector (Setup's limits, the group, the output stage) is PCA9685
channel ``k - 1``: 1 Base .. 5 WristRoll, 6 Gripper.
"""

from __future__ import annotations

from typing import Final

Copy = tuple[str, str]  # (assigned, expression): "ScanCount", "Scans"
Section = tuple[str, tuple[Copy, ...]]  # (comment over the rows, rows)

ARM: Final = ("Base", "Shoulder", "Elbow")
WRIST: Final = ("WristPitch", "WristRoll")
JOINTS: Final = (*ARM, *WRIST, "Gripper")  # in channel order


def _joint(name: str) -> int:
    """JointVector index of a joint (= its channel + 1)."""
    return JOINTS.index(name) + 1


def _calibration(joint: str) -> tuple[Copy, ...]:
    """The read-back of a joint's ServoCalibration: <Joint>CalZeroDeg .. <Joint>CalMaxAngleDeg."""
    cal = f"Setup.Cals.{joint}"
    return ((f"{joint}CalZeroDeg", f"{cal}.ZeroOffsetDeg"),
            (f"{joint}CalDirection", f"INT_TO_DINT({cal}.Direction)"),
            (f"{joint}CalMinPulseUs", f"{cal}.MinPulseUs"),
            (f"{joint}CalMaxPulseUs", f"{cal}.MaxPulseUs"),
            (f"{joint}CalMinAngleDeg", f"{cal}.MinAngleDeg"),
            (f"{joint}CalMaxAngleDeg", f"{cal}.MaxAngleDeg"))


def _limits(joints: tuple[str, ...]) -> tuple[Copy, ...]:
    """Lim<Joint>Vel of each joint, then Lim<Joint>Acc of each (the register order)."""
    return (*((f"Lim{j}Vel", f"Setup.MaxVel[{_joint(j)}]") for j in joints),
            *((f"Lim{j}Acc", f"Setup.MaxAcc[{_joint(j)}]") for j in joints))


COPY_OUT: Final[tuple[Section, ...]] = (
    ("status", (
        ("ScanCount", "Scans"),
        ("CtlState", "SEL(Pwm.BusyMailbox <> 0, StateReady, StateBusy)"),  # Busy: InitPwm runs
        ("BusyMailbox", "Pwm.BusyMailbox"),
        ("CommandsAnswered", "Mailboxes.Answered"),
        ("CommandsIgnored", "Mailboxes.Ignored"),
        *((f"{j}Deg", f"Moves.Joints.{j}") for j in ARM),
        *((f"Echo{a}", f"Moves.Echo.{a}") for a in "XYZ"),
        *((f"{j}PulseUs", f"Pulses[{_joint(j) - 1}]") for j in ARM),
        ("PwmPrescale", "BYTE_TO_DINT(Pwm.Prescale)"),
        ("PwmReady", "BOOL_TO_DINT(Pwm.Ready)"),
        ("InitFrames", "Pwm.Frames"),
        ("BatchOwner", "Batch.Holder"),
        ("BatchCount", "Batch.Count"),
        ("BatchFailures", "Batch.Failures"),
        ("DriverFaultHeld", "BOOL_TO_DINT(Motion.FaultHeld)"),
        ("DriverFaults", "Motion.FaultEdges"),
    )),
    ("calibration read-back", tuple(c for j in ARM for c in _calibration(j))),
    ("motion progress and setpoints", (
        ("MotionScan", "Scans"),
        ("MotionKind", "Motion.Kind"),
        ("MotionBusy", "BOOL_TO_DINT(Motion.ActBusy)"),
        ("MotionDone", "BOOL_TO_DINT(Motion.ActDone)"),
        ("MotionError", "BOOL_TO_DINT(Motion.ActError)"),
        ("MotionErrorId", "Motion.ActErrorId"),
        ("MotionAborted", "BOOL_TO_DINT(Motion.ActAborted)"),
        ("MotionMailbox", "Motion.ActMailbox"),
        ("MotionSession", "Motion.ActSession"),
        ("MotionSeq", "Motion.ActSeq"),
        ("MotionStarts", "Motion.Starts"),
        ("MotionProgress", "Motion.ActProgress"),
        ("MotionDeviation", "Motion.ActDeviation"),
        ("MotionAtLimit", "BOOL_TO_DINT(Motion.ActAtLimit)"),
        ("MotionDuration", "Motion.ActDuration"),
        *((f"Set{j}Deg", f"Group.Position[{_joint(j)}]") for j in ARM),
        *((f"Set{j}Vel", f"Group.Velocity[{_joint(j)}]") for j in ARM),
        *((f"Out{j}Deg", f"StageDeg[{_joint(j)}]") for j in ARM),
        *((f"Out{j}Vel", f"StageVel[{_joint(j)}]") for j in ARM),
        ("CartValid", "BOOL_TO_DINT(Group.CartesianValid)"),
        *((f"Cart{a}", f"Group.CartesianPos[{i}]") for i, a in enumerate("XYZ", 1)),
        ("SlewLimited", "BOOL_TO_DINT(Stage.Limited)"),
        ("SlewErrorId", "INT_TO_DINT(Stage.ErrorId)"),
        *_limits(ARM),
    )),
    ("PCA9685 init frames, for the I2C hook", tuple(
        c for k in range(1, 6)
        for c in ((f"InitReg{k}", f"Pwm.Regs[{k}]"), (f"InitData{k}", f"Pwm.Datas[{k}]")))),
    ("PSM driver handshake", (
        ("PwmInitRequest", "Pwm.Request"),
    )),
    ("PCA9685 LEDn_OFF words", tuple((f"Ch{n:02d}Off", f"Pwm.Words[{n}]") for n in range(16))),
    ("LUT results", (
        ("LutSession", "Batch.Lut.Session"),
        ("LutSeq", "Batch.Lut.Seq"),
        ("LutErrorId", "Batch.Lut.ErrorId"),
        *((f"Lut{a}Mm100", f"Batch.Lut.{a}Mm100") for a in "XYZ"),
        *((f"Lut{j}Deg100", f"Batch.Lut.Angles.{j}Deg100") for j in ARM),
        *((f"LutEcho{a}Mm100", f"Batch.Lut.Echo{a}Mm100") for a in "XYZ"),
        ("LutSolves", "Batch.LutSolves"),
    )),
    ("5-AXIS: wrist calibration", tuple(c for j in WRIST for c in _calibration(j))),
    ("5-AXIS: the last 5-axis command and its FK echo", (
        ("FiveSession", "Moves.FiveSession"),
        ("FiveSeq", "Moves.FiveSeq"),
        ("FiveErrorId", "Moves.FiveErrorId"),
        *((f"Five{j}Deg", f"Moves.FiveJoints[{_joint(j)}]") for j in (*ARM, *WRIST)),
        *((f"FiveTip{a}", f"Moves.FiveTip[{i}]") for i, a in enumerate("XYZ", 1)),
        *((f"FiveDir{a}", f"Moves.FiveDir[{i}]") for i, a in enumerate("XYZ", 1)),
        ("FiveToolPitchDeg", "Moves.FiveToolPitch"),
        ("FiveToolRollDeg", "Moves.FiveToolRoll"),
    )),
    ("5-AXIS: the wrist's motion layer", (
        *((f"Set{j}Deg", f"Group.Position[{_joint(j)}]") for j in WRIST),
        *((f"Out{j}Deg", f"StageDeg[{_joint(j)}]") for j in WRIST),
        *((f"{j}PulseUs", f"Pulses[{_joint(j) - 1}]") for j in WRIST),
        *_limits(WRIST),
    )),
    ("gripper, channel 5", (
        *_calibration("Gripper"),
        ("GripperOpeningPct", "Gripper.OpeningPct"),
        ("OutGripperDeg", f"Stage.AngleDeg[{_joint('Gripper')}]"),
        ("GripperPulseUs", f"Pulses[{_joint('Gripper') - 1}]"),
        *_limits(("Gripper",)),
        ("GripperMoving", "BOOL_TO_DINT(Stage.GripperLimited OR Stage.GripperMoving)"),
    )),
    ("IMU results", (
        ("ImuSamples", "Imu.Samples"),
        ("ImuErrorId", "INT_TO_DINT(Imu.ErrorId)"),
        ("ImuRejected", "Imu.Rejected"),
        ("ImuMissed", "Imu.Missed"),
        *((f"ImuQuat{a}", f"Imu.Orientation.{a}") for a in "WXYZ"),
        *((f"Imu{a}Deg", f"Imu.Angles.{a}Deg") for a in ("Roll", "Pitch", "Yaw")),
        *((f"ImuTool{a}", f"Imu.Tool.{a}") for a in "XYZ"),
        ("ImuFilter", "Imu.Filter"),
        ("ImuGain", "Imu.Gain"),
        ("ImuPeriodS", "Imu.PeriodS"),
        *((f"ImuGyroBias{a}", f"Imu.Calibration.GyroBiasDps.{a}") for a in "XYZ"),
        *((f"ImuAccelScale{a}", f"Imu.Calibration.AccelScale{a}") for a in "XYZ"),
        *((f"ImuMagOffset{a}", f"Imu.Calibration.MagOffsetGauss.{a}") for a in "XYZ"),
        ("ImuLastSeq", "Imu.LastSeq"),
    )),
    ("FOLLOW (FollowImu)", (
        ("FollowState", "Follow.State"),
        ("FollowErrorId", "Follow.LastEnd"),
        ("FollowAborted", "BOOL_TO_DINT(Follow.Aborted)"),
        ("FollowFlangeFixed", "BOOL_TO_DINT(Follow.FlangeFixed)"),
        ("FollowHeadingDeg", "Follow.HeadingDeg"),
        ("FollowDeadBandDeg", "Follow.DeadBandDeg"),
        ("FollowMaxRateDps", "Follow.MaxRateDps"),
        *((f"FollowAnchor{a}", f"Follow.Anchor[{i}]") for i, a in enumerate("XYZ", 1)),
        *((f"FollowDir{a}", f"Follow.Direction.{a}") for a in "XYZ"),
        ("FollowPitchDeg", "Follow.PitchDeg"),
        ("FollowRollDeg", "Follow.RollDeg"),
        ("FollowLagDeg", "Follow.LagDeg"),
        ("FollowOffPlaneDeg", "Follow.OffPlaneDeg"),
        ("FollowErrorDeg", "Follow.ErrorDeg"),
        ("FollowDriftMm", "Follow.DriftMm"),
        ("FollowUnreachable", "BOOL_TO_DINT(Follow.Unreachable)"),
        ("FollowUnreachCount", "Follow.UnreachCount"),
        ("FollowUnreachId", "Follow.UnreachId"),
        ("FollowSteps", "Follow.Steps"),
    )),
)

# Inputs: (internal target, located variable). Copied at the start of every scan, with the
# mailbox blocks: the I/O layer writes them between scans, never during one.
COPY_IN: Final[tuple[Section, ...]] = (
    ("the IMU's raw sample words and its counter", (
        *((f"ImuRaw.{w}", f"Imu{w}") for w in
          ("GyroX", "GyroY", "GyroZ", "AccelX", "AccelY", "AccelZ", "MagX", "MagY", "MagZ")),
        ("ImuSeq", "ImuSampleSeq"),
    )),
    ("the PCA9685 driver's fault bit", (
        ("FaultIn", "PwmDriverFault"),
    )),
)
