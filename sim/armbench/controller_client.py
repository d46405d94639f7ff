"""Client side of ``plc_project/Controller.st``: the mailbox handshake over Modbus (HANDSHAKE in
the program's header, docs/register-map.md), with every address taken from the register map
derived from the program (:mod:`armbench.registermap`), so the client cannot drift from the ST.
The map is that of a Modbus flavor: OpenPLC's (docs/register-map.md, the default) or, with
``flavor="codesys"``, the CODESYS variant's (plc_project/codesys/register-map.md: outputs read
as input registers with function 4, 32-bit values least significant word first).

One client = one random session id and, while it talks to the PLC, one of the controller's
mailboxes. A command is one FC16 write of the mailbox's command block, then polls of the
mailbox's answer (Owner, AckSeq, Result, AckCheck) with a short sleep between them (a busy
loop of Modbus reads steals the CPU, and in-process the GIL, from the PLC's scan thread).
The client believes a command acknowledged only when the answer carries its own sequence
number and check word in a mailbox it owns, so it never takes another client's result.
When the mailbox was lost before the PLC took the command (another client overwrote the block
while claiming it), nothing ran: the client claims another mailbox and sends it again. When its
own block was overwritten in a mailbox it still owns, it writes it again (the PLC answers a
block once, so a second copy of an answered block runs nothing). A connection that breaks
mid-command is reopened and the command followed up the same way. What cannot be decided
(the client was silent for longer than the PLC's mailbox lease) raises
:class:`HandshakeLost` instead of guessing.
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import astuple, dataclass, replace
from typing import TypeVar

from .mailbox_check import check_word
from .registermap import Register, controller_constants, controller_map
from .softplc import modbus_map as mm
from .softplc.modbus_client import ModbusIoError, PlcClient
from .softplc.modbus_map import Flavor

# Command codes, result codes and states come from Controller.st's constants (one source).
_K = controller_constants()
CMD_MOVE_XYZ = _K["CmdMoveXyz"]
CMD_MOVE_JOINTS = _K["CmdMoveJoints"]
CMD_INIT_PWM = _K["CmdInitPwm"]
CMD_RELAX = _K["CmdRelax"]
CMD_SET_CALIBRATION = _K["CmdSetCalibration"]
CMD_SOLVE_BATCH = _K["CmdSolveBatch"]
CMD_RESERVE_BATCH = _K["CmdReserveBatch"]
CMD_RELEASE_BATCH = _K["CmdReleaseBatch"]
CMD_CLOSE = _K["CmdClose"]
CMD_HELLO = _K["CmdHello"]
CMD_LUT_SOLVE = _K["CmdLutSolve"]
CMD_LUT_MOVE_XYZ = _K["CmdLutMoveXyz"]
CMD_LUT_SOLVE_BATCH = _K["CmdLutSolveBatch"]
CMD_MOVE_JOINTS_PROFILE = _K["CmdMoveJointsProfile"]
CMD_MOVE_LINEAR = _K["CmdMoveLinear"]
CMD_JOG_START = _K["CmdJogStart"]
CMD_JOG_UPDATE = _K["CmdJogUpdate"]
CMD_JOG_STOP = _K["CmdJogStop"]
CMD_STOP = _K["CmdStop"]
CMD_SET_MOTION_LIMITS = _K["CmdSetMotionLimits"]
CMD_MOVE_TOOL_ANGLES = _K["CmdMoveToolAngles"]
CMD_MOVE_TOOL_VECTOR = _K["CmdMoveToolVector"]
FIVE_FLAG_ELBOW_DOWN = _K["FiveFlagElbowDown"]
FIVE_FLAG_FLANGE_FIXED = _K["FiveFlagFlangeFixed"]
FIVE_ROLL_MAX_100 = _K["FiveRollMax100"]
JOINT_WRIST_PITCH = _K["JointWristPitch"]
JOINT_WRIST_ROLL = _K["JointWristRoll"]
# wrist jog and gripper (codes 32, 33; Controller.st 5-AXIS)
CMD_JOG_WRIST = _K["CmdJogWrist"]
CMD_SET_GRIPPER = _K["CmdSetGripper"]
KIND_JOG_WRIST = _K["KindJogWrist"]
JOINT_GRIPPER = _K["JointGripper"]
# IMU commands 40..45 (Controller.st IMU COMMANDS)
CMD_IMU_SELECT_FILTER = _K["CmdImuSelectFilter"]
CMD_IMU_SET_PERIOD = _K["CmdImuSetPeriod"]
CMD_IMU_SET_GYRO_BIAS = _K["CmdImuSetGyroBias"]
CMD_IMU_SET_ACCEL_SCALE = _K["CmdImuSetAccelScale"]
CMD_IMU_SET_MAG_OFFSET = _K["CmdImuSetMagOffset"]
CMD_IMU_RESET = _K["CmdImuReset"]
IMU_FILTERS = {"gyro": _K["ImuFilterGyro"], "complementary": _K["ImuFilterCompl"],
               "madgwick_imu": _K["ImuFilterMadgwick"], "madgwick_marg": _K["ImuFilterMarg"]}
ERR_BAD_QUATERNION = _K["OErr.BadQuaternion"]
CMD_FOLLOW_IMU = _K["CmdFollowImu"]
FOLLOW_FLAG_START = _K["FollowFlagStart"]
FOLLOW_FLAG_FLANGE_FIXED = _K["FollowFlagFlangeFixed"]
FOLLOW_TIMEOUT_SCANS = _K["FollowTimeoutScans"]
KIND_FOLLOW = _K["KindFollow"]
ERR_IMU_TIMEOUT = _K["CtlErr.ImuTimeout"]
KIND_JOINT = _K["KindJoint"]
KIND_LINE = _K["KindLine"]
KIND_JOG = _K["KindJog"]
KIND_STOP = _K["KindStop"]
JOG_DEADMAN_SCANS = _K["JogDeadmanScans"]

ERR_OK = _K["Err.NoError"]
ERR_UNREACHABLE = _K["Err.Unreachable"]
ERR_SINGULAR = _K["Err.Singular"]
ERR_NOT_FINITE = _K["Err.NotFinite"]
ERR_BAD_CALIBRATION = _K["Err.BadCalibration"]
ERR_UNKNOWN_COMMAND = _K["CtlErr.UnknownCommand"]
ERR_JOINT_LIMIT = _K["CtlErr.JointLimit"]
ERR_BAD_JOINT = _K["CtlErr.BadJoint"]
ERR_BAD_COUNT = _K["CtlErr.BadCount"]
ERR_BUSY = _K["CtlErr.Busy"]
ERR_BAD_SEQUENCE = _K["CtlErr.BadSequence"]
ERR_BAD_CHECK = _K["CtlErr.BadCheck"]
ERR_NOT_BATCH_OWNER = _K["CtlErr.NotBatchOwner"]
ERR_NOT_MOTION_OWNER = _K["CtlErr.NotMotionOwner"]
ERR_JOG_TIMEOUT = _K["CtlErr.JogTimeout"]
ERR_DRIVER_FAULT = _K["CtlErr.DriverFault"]
ERR_BAD_PARAMETER = _K["Err.BadParameter"]
ERR_TOOL_OUT_OF_PLANE = _K["FiveErr.ToolOutOfPlane"]
ERR_TOOL_VECTOR_ZERO = _K["FiveErr.ToolVectorZero"]
ERR_FLANGE_UNREACHABLE = _K["FiveErr.FlangeUnreachable"]

STATE_READY = _K["StateReady"]
STATE_BUSY = _K["StateBusy"]
MAILBOXES = _K["MailboxMax"]
LEASE_SCANS = _K["MailboxLeaseScans"]
MAX_SEQ = 2**31 - 1  # the largest DINT: MailboxServer follows it with 1

JOINTS = ("Base", "Shoulder", "Elbow")  # SetCalibration Int1 0, 1, 2 = PCA9685 channels 0..2
WRIST_JOINTS = ("WristPitch", "WristRoll")  # 5-axis arm: Int1 3, 4 = channels 3, 4

# FC16 carries at most 123 registers and FC03 returns at most 125 (Modbus spec §6.12/§6.3).
_MAX_WRITE_REGS = 123
_MAX_READ_REGS = 125

_COMMAND_FIELDS = ("Seq", "Session", "Code", "Int1", "Int2", "Arg1", "Arg2", "Arg3", "Arg4",
                   "Arg5", "Arg6", "Check")
_ANSWER_FIELDS = ("Owner", "AckSeq", "Result", "AckCheck")
_STATUS_FIELDS = ("ScanCount", "CtlState", "BusyMailbox", "CommandsAnswered",
                  "CommandsIgnored", "BaseDeg", "ShoulderDeg", "ElbowDeg", "EchoX", "EchoY",
                  "EchoZ", "BasePulseUs", "ShoulderPulseUs", "ElbowPulseUs", "PwmPrescale",
                  "PwmReady", "InitFrames", "BatchOwner", "BatchCount", "BatchFailures",
                  "DriverFaultHeld", "DriverFaults")
_MOTION_FIELDS = ("MotionScan", "MotionKind", "MotionBusy", "MotionDone", "MotionError",
                  "MotionErrorId", "MotionAborted", "MotionMailbox", "MotionSession",
                  "MotionSeq", "MotionStarts", "MotionProgress", "MotionDeviation",
                  "MotionAtLimit", "MotionDuration", "SetBaseDeg", "SetShoulderDeg",
                  "SetElbowDeg", "SetBaseVel", "SetShoulderVel", "SetElbowVel", "OutBaseDeg",
                  "OutShoulderDeg", "OutElbowDeg", "OutBaseVel", "OutShoulderVel",
                  "OutElbowVel", "CartValid", "CartX", "CartY", "CartZ", "SlewLimited",
                  "SlewErrorId", "LimBaseVel", "LimShoulderVel", "LimElbowVel", "LimBaseAcc",
                  "LimShoulderAcc", "LimElbowAcc")
_CAL_SUFFIXES = ("ZeroDeg", "Direction", "MinPulseUs", "MaxPulseUs", "MinAngleDeg",
                 "MaxAngleDeg")
_LUT_FIELDS = ("LutSession", "LutSeq", "LutErrorId", "LutXMm100", "LutYMm100", "LutZMm100",
               "LutBaseDeg100", "LutShoulderDeg100", "LutElbowDeg100", "LutEchoXMm100",
               "LutEchoYMm100", "LutEchoZMm100", "LutSolves")
_FIVE_FIELDS = ("FiveSession", "FiveSeq", "FiveErrorId", "FiveBaseDeg", "FiveShoulderDeg",
                "FiveElbowDeg", "FiveWristPitchDeg", "FiveWristRollDeg", "FiveTipX", "FiveTipY",
                "FiveTipZ", "FiveDirX", "FiveDirY", "FiveDirZ", "FiveToolPitchDeg",
                "FiveToolRollDeg")
_GRIPPER_FIELDS = ("GripperOpeningPct", "OutGripperDeg", "GripperPulseUs", "LimGripperVel",
                   "LimGripperAcc", "GripperMoving")
_WRIST_FIELDS = ("SetWristPitchDeg", "SetWristRollDeg", "OutWristPitchDeg", "OutWristRollDeg",
                 "WristPitchPulseUs", "WristRollPulseUs", "LimWristPitchVel", "LimWristRollVel",
                 "LimWristPitchAcc", "LimWristRollAcc")
# answers of commands that did not run (the LUT result block is then someone else's)
_NOT_RUN = (ERR_BUSY, ERR_BAD_SEQUENCE, ERR_BAD_CHECK, ERR_UNKNOWN_COMMAND)
# InverseKinematikFixed's input range: |coordinate| <= 1,000,000 x 0.01 mm (KinematicsFixed.st)
LUT_MAX_MM100 = 1_000_000
_IMU_FIELDS = ("ImuSamples", "ImuErrorId", "ImuRejected", "ImuMissed", "ImuQuatW", "ImuQuatX",
               "ImuQuatY", "ImuQuatZ", "ImuRollDeg", "ImuPitchDeg", "ImuYawDeg", "ImuToolX",
               "ImuToolY", "ImuToolZ", "ImuFilter", "ImuGain", "ImuPeriodS", "ImuGyroBiasX",
               "ImuGyroBiasY", "ImuGyroBiasZ", "ImuAccelScaleX", "ImuAccelScaleY",
               "ImuAccelScaleZ", "ImuMagOffsetX", "ImuMagOffsetY", "ImuMagOffsetZ",
               "ImuLastSeq")
_FOLLOW_FIELDS = ("FollowState", "FollowErrorId", "FollowAborted", "FollowFlangeFixed",
                  "FollowHeadingDeg", "FollowDeadBandDeg", "FollowMaxRateDps", "FollowAnchorX",
                  "FollowAnchorY", "FollowAnchorZ", "FollowDirX", "FollowDirY", "FollowDirZ",
                  "FollowPitchDeg", "FollowRollDeg", "FollowLagDeg", "FollowOffPlaneDeg",
                  "FollowErrorDeg", "FollowDriftMm", "FollowUnreachable", "FollowUnreachCount",
                  "FollowUnreachId", "FollowSteps")
_RESULT_PREFIXES = ("ResBase", "ResShoulder", "ResElbow", "ResX", "ResY", "ResZ", "ResErrorId")

# Between two looks at the answer, the client re-reads its command block this often (s): a
# block overwritten by a claiming client is written again.
_BLOCK_RECHECK_S = 0.02
_BUSY_RETRY_S = 0.005


class HandshakeError(Exception):
    """The handshake could not be completed; the message says what is known."""


class HandshakeTimeout(HandshakeError):
    """The PLC did not answer a command in time."""


class HandshakeLost(HandshakeError):
    """The client cannot tell whether its command ran (it was silent longer than the lease)."""


class NoFreeMailbox(HandshakeError):
    """Every mailbox of the controller is held by another client."""


class CommandRejected(Exception):
    """A command the caller needed came back with a non-zero result code."""

    def __init__(self, what: str, error_id: int) -> None:
        super().__init__(f"{what}: result code {error_id}")
        self.error_id = error_id


class MailboxLost(HandshakeError):
    """Another session took the mailbox before the PLC took the command: nothing ran."""


@dataclass(frozen=True)
class Answer:
    """A mailbox's answer block."""

    owner: int
    ack_seq: int
    result: int
    ack_check: int


@dataclass(frozen=True)
class Status:
    """The controller's status after a command, with that command's result as ``error_id``;
    ``ticket`` names the motion the command started (None: it started none), so the status a
    motion command returns can be given to :meth:`ArmControllerClient.wait_motion`."""

    mailbox: int
    ack_seq: int
    error_id: int
    state: int
    busy_mailbox: int
    scan_count: int
    commands_answered: int
    commands_ignored: int
    joints_deg: tuple[float, float, float]
    echo_mm: tuple[float, float, float]
    pulses_us: tuple[float, float, float]
    prescale: int
    pwm_ready: bool
    init_frames: int
    batch_owner: int
    batch_count: int
    batch_failures: int
    driver_fault: bool  # PwmDriverFault holds the arm: what would move is ERR_DRIVER_FAULT
    driver_faults: int  # the fault's rising edges the controller saw since start
    ticket: MotionTicket | None = None


Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class MotionTicket:
    """Who started a motion: the command's mailbox, session and sequence number (what the
    PLC shows in MotionMailbox/MotionSession/MotionSeq while that motion is the last one)."""

    mailbox: int
    session: int
    seq: int


@dataclass(frozen=True)
class MotionSample:
    """One read of the motion registers (%MD724..762), tagged with the PLC's scan."""

    scan: int
    kind: int
    busy: bool
    done: bool
    error: bool
    error_id: int
    aborted: bool
    ticket: MotionTicket
    starts: int
    progress: float
    deviation_mm: float
    at_limit: bool
    duration_s: float
    set_deg: Vec3  # group setpoints (the motion generator's)
    set_vel: Vec3
    out_deg: Vec3  # the slew limiter's output: what the servos are sent
    out_vel: Vec3
    cart_valid: bool
    cart_mm: Vec3
    slew_limited: bool
    slew_error_id: int
    limit_vel: Vec3
    limit_acc: Vec3

    @classmethod
    def decode(cls, v: Sequence[float]) -> MotionSample:
        i = [int(x) for x in v[:11]]
        t = tuple(float(x) for x in v)

        def v3(k: int) -> Vec3:
            return (t[k], t[k + 1], t[k + 2])

        return cls(scan=i[0], kind=i[1], busy=bool(i[2]), done=bool(i[3]), error=bool(i[4]),
                   error_id=i[5], aborted=bool(i[6]), ticket=MotionTicket(i[7], i[8], i[9]),
                   starts=i[10], progress=t[11], deviation_mm=t[12], at_limit=bool(t[13]),
                   duration_s=t[14], set_deg=v3(15), set_vel=v3(18), out_deg=v3(21),
                   out_vel=v3(24), cart_valid=bool(t[27]), cart_mm=v3(28),
                   slew_limited=bool(t[31]), slew_error_id=int(t[32]), limit_vel=v3(33),
                   limit_acc=v3(36))


@dataclass(frozen=True)
class MotionOutcome:
    """How a motion ended for the client that started it: "done", "error" (with
    ``error_id``), "aborted" (Relax) or "superseded" (another motion took the group;
    ``by`` says whose)."""

    state: str
    error_id: int
    by: MotionTicket | None
    sample: MotionSample


class MotionTimeout(HandshakeError):
    """A motion did not end in time."""


@dataclass(frozen=True)
class Calibration:
    """One joint's ServoCalibration (MG996R.st); the defaults are the MG996R data."""

    zero_offset_deg: float = 0.0
    direction: int = 1
    min_pulse_us: float = 1000.0
    max_pulse_us: float = 2000.0
    min_angle_deg: float = -60.0
    max_angle_deg: float = 60.0

    def servo_to_joint(self, servo_deg: float) -> float:
        """Joint angle for a servo horn angle (MG996R_PulseToAngle's last step)."""
        return self.zero_offset_deg + self.direction * servo_deg


@dataclass(frozen=True)
class BatchPoint:
    """One SolveBatch result: joints (deg), FK echo (mm), the point's ErrorId."""

    joints_deg: tuple[float, float, float]
    echo_mm: tuple[float, float, float]
    error_id: int


@dataclass(frozen=True)
class LutResult:
    """The LUT result block (LutSolve, LutMoveXyz) in the controller's integer units."""

    session: int
    seq: int
    error_id: int
    target_mm100: tuple[int, int, int]  # 0.01 mm, the integer target the PLC solved
    angles_deg100: tuple[int, int, int]  # 0.01 deg, Base, Shoulder, Elbow
    echo_mm100: tuple[int, int, int]  # 0.01 mm, ForwardKinematicFixed of the angles
    solves: int  # LutSolves: points solved with the LUT since the PLC started


@dataclass(frozen=True)
class LutBatchPoint:
    """One LutSolveBatch result in integer units (the PLC publishes them as REAL deg and mm
    that hold whole 0.01 steps)."""

    angles_deg100: tuple[int, int, int]
    echo_mm100: tuple[int, int, int]
    error_id: int


@dataclass(frozen=True)
class ImuState:
    """The IMU result block (%MD850..876): the fused orientation and the settings in use."""

    samples: int  # samples filtered since the last reset
    error_id: int  # the filter's ErrorId for the last sample, 0 ok
    rejected: int
    missed: int  # samples the PLC never saw (the counter jumped)
    quat: tuple[float, float, float, float]  # W, X, Y, Z: sensor to earth
    rpy_deg: tuple[float, float, float]  # Z-Y-X roll, pitch, yaw
    tool: tuple[float, float, float]  # body X axis in the earth frame
    filter: int  # IMU_FILTERS value
    gain: float  # F or beta (rad/s)
    period_s: float
    gyro_bias_dps: tuple[float, float, float]
    accel_scale: tuple[float, float, float]
    mag_offset_gauss: tuple[float, float, float]
    last_seq: int  # ImuSampleSeq of the last filtered sample

    @classmethod
    def decode(cls, v: Sequence[float]) -> ImuState:
        def v3(k: int) -> tuple[float, float, float]:
            return (float(v[k]), float(v[k + 1]), float(v[k + 2]))
        return cls(int(v[0]), int(v[1]), int(v[2]), int(v[3]),
                   (float(v[4]), float(v[5]), float(v[6]), float(v[7])), v3(8), v3(11),
                   int(v[14]), float(v[15]), float(v[16]), v3(17), v3(20), v3(23), int(v[26]))


@dataclass(frozen=True)
class FollowState:
    """The FollowImu block (%MD877..899): the follow's state and figures."""

    state: int  # 0 off, 1 following, 2 braking
    error_id: int  # why the last follow ended: 0, ERR_IMU_TIMEOUT, the filter's code
    aborted: bool  # a Stop, a new motion or Relax took it over
    flange_fixed: bool
    heading_deg: float  # the arm's X axis from magnetic north, about Z up
    dead_band_deg: float
    max_rate_dps: float
    anchor_mm: tuple[float, float, float]  # the held point (tip or flange)
    direction: tuple[float, float, float]  # commanded unit tool direction, base frame
    pitch_deg: float
    roll_deg: float
    lag_deg: float  # follower orientation vs the hand's (dead band, rate limit)
    off_plane_deg: float  # hand direction out of the arm plane (not followable)
    error_deg: float  # hand tool direction vs FK of the output stage
    drift_mm: float  # output stage's held point from the anchor
    unreachable: bool  # the last sample was unreachable: the arm holds
    unreachable_count: int
    unreachable_id: int
    steps: int  # samples followed since the start

    @property
    def following(self) -> bool:
        return self.state == 1

    @classmethod
    def decode(cls, v: Sequence[float]) -> FollowState:
        def v3(k: int) -> tuple[float, float, float]:
            return (float(v[k]), float(v[k + 1]), float(v[k + 2]))
        return cls(int(v[0]), int(v[1]), bool(v[2]), bool(v[3]), float(v[4]), float(v[5]),
                   float(v[6]), v3(7), v3(10), float(v[13]), float(v[14]), float(v[15]),
                   float(v[16]), float(v[17]), float(v[18]), bool(v[19]), int(v[20]),
                   int(v[21]), int(v[22]))


def lut_target_mm(value_mm100: int) -> float:
    """The REAL (mm) that carries a 0.01 mm integer to the PLC: value / 100. The PLC's
    REAL_TO_DINT(mm * 100.0) gives the integer back exactly for every |value| <= 1,000,000
    (float32 keeps k / 100 and its product with 100 within 0.12 of k)."""
    if isinstance(value_mm100, bool) or not isinstance(value_mm100, int):
        raise TypeError(f"LUT coordinates are integers in 0.01 mm, got {value_mm100!r}")
    if not -LUT_MAX_MM100 <= value_mm100 <= LUT_MAX_MM100:
        raise ValueError(f"LUT coordinate {value_mm100} (0.01 mm) is outside "
                         f"+/-{LUT_MAX_MM100} (10 m), the range of InverseKinematikFixed")
    return value_mm100 / 100.0


@dataclass(frozen=True)
class FiveAxisEcho:
    """The 5-axis echo block: the last 5-axis command's session, seq and result, and the
    joints of the last one that started with their ForwardKinematic5Axis."""

    session: int
    seq: int
    error_id: int
    joints_deg: tuple[float, float, float, float, float]  # base..elbow, wrist pitch, roll
    tip_mm: Vec3
    direction: Vec3  # unit tool direction
    tool_pitch_deg: float
    tool_roll_deg: float


@dataclass(frozen=True)
class WristSample:
    """The wrist joints' motion layer (channels 3 and 4), one read."""

    set_deg: tuple[float, float]  # group setpoints, pitch and roll
    out_deg: tuple[float, float]  # slew limiter outputs = the servos' joint angles
    pulses_us: tuple[float, float]  # 0 = off
    max_vel_deg: tuple[float, float]
    max_acc_deg: tuple[float, float]


@dataclass(frozen=True)
class GripperSample:
    """The gripper's channel (5), one read."""

    opening_pct: float  # the last SetGripper's opening
    out_deg: float  # its slew limiter's output = the servo's joint angle
    pulse_us: float  # 0 = off (limp)
    max_vel_deg: float
    max_acc_deg: float
    moving: bool  # the output is not yet at the target


@dataclass(frozen=True)
class Pending:
    """A command written to a mailbox and not yet answered."""

    mailbox: int
    seq: int
    code: int
    check: int
    address: int
    words: tuple[int, ...]
    sent_at: float  # time.monotonic() of the write


def next_seq(seq: int) -> int:
    """The sequence number after ``seq`` (2147483647 is followed by 1, as in the program)."""
    return 1 if seq >= MAX_SEQ or seq < 1 else seq + 1


def _encode(reg: Register, value: float) -> list[int]:
    t = reg.st_type.upper()
    if t not in ("REAL", "DINT", "UDINT"):
        raise TypeError(f"{reg.name}: no encoder for {reg.st_type}")
    return reg.encode(value if t == "REAL" else int(value))


def _decode(reg: Register, words: list[int]) -> float:
    if reg.st_type.upper() not in ("REAL", "DINT", "UDINT"):
        raise TypeError(f"{reg.name}: no decoder for {reg.st_type}")
    return reg.decode(words)


@dataclass(frozen=True)
class _Block:
    """Registers that are read or written together: contiguous registers of one table (holding
    registers on OpenPLC; under CODESYS what the client writes is in holding registers, what
    the program writes in input registers)."""

    regs: tuple[Register, ...]
    table: str
    address: int
    length: int

    @classmethod
    def of(cls, names: Iterable[str], cmap: dict[str, Register]) -> _Block:
        regs = tuple(cmap[n.upper()] for n in names)
        tables = {r.table for r in regs}
        if len(tables) != 1 or tables & {"coil", "discrete"}:
            raise ValueError(f"the block {regs[0].name}..{regs[-1].name} spans the tables "
                             f"{sorted(tables)}: a block is registers of one table")
        first = min(r.address for r in regs)
        return cls(regs, tables.pop(), first, max(r.address + r.count for r in regs) - first)

    def encode(self, values: Sequence[float]) -> list[int]:
        words = [0] * self.length
        for r, v in zip(self.regs, values, strict=True):
            words[r.address - self.address: r.address - self.address + r.count] = _encode(r, v)
        return words

    def decode(self, words: list[int]) -> list[float]:
        return [_decode(r, words[r.address - self.address: r.address - self.address + r.count])
                for r in self.regs]


def _batch_size() -> int:
    cmap = controller_map()
    n = 0
    while f"BATCHX{n + 1:02d}" in cmap:
        n += 1
    return n


_T = TypeVar("_T")


class ArmControllerClient:
    """Commands for the controller over an open :class:`PlcClient`.

    ``session`` identifies this client to the PLC (random when not given; any non-zero DINT).
    A mailbox is claimed at the first command (or :meth:`open`) and given back by
    :meth:`close` (or the context manager); the PLC frees it anyway after its lease.
    ``poll_interval_s`` is the sleep between two answer polls (0 = busy loop).
    ``retry_busy``: a command answered Busy (another client's InitPwm runs, or the batch
    buffer is held) is sent again until ``timeout_s``; then the Busy status is returned.
    ``flavor``: the PLC's register layout, "openplc" or "codesys" (:attr:`registers`).
    """

    def __init__(self, plc: PlcClient, timeout_s: float = 5.0,
                 poll_interval_s: float = 0.0005, session: int | None = None,
                 retry_busy: bool = True, flavor: str | Flavor = mm.OPENPLC) -> None:
        if session is not None and not (-2**31 <= session < 2**31 and session != 0):
            raise ValueError(f"session must be a non-zero 32-bit signed number, got {session}")
        self.plc = plc
        self.flavor = mm.flavor(flavor)
        # the controller's located variables by upper-case name, on this flavor's server
        self.registers = controller_map(self.flavor)
        cmap = self.registers
        self.timeout_s = timeout_s
        self.poll_interval_s = poll_interval_s
        self.retry_busy = retry_busy
        self.session = session if session is not None else random.SystemRandom().randrange(
            1, 2**31)
        self.mailbox: int | None = None
        self._seq = 0
        # A lower bound on the lease in seconds, measured by open(); until then (the claim
        # itself, where a Hello cannot do harm) 1000 scans of at least 1 ms.
        self._lease_s = 1.0

        def block(names: Iterable[str]) -> _Block:
            return _Block.of(names, cmap)

        self._commands = [block(f"Mbx{k:02d}{f}" for f in _COMMAND_FIELDS)
                          for k in range(1, MAILBOXES + 1)]
        self._answers = [block(f"Mbx{k:02d}{f}" for f in _ANSWER_FIELDS)
                         for k in range(1, MAILBOXES + 1)]
        self._all_answers = block(f"Mbx{k:02d}{f}" for k in range(1, MAILBOXES + 1)
                                  for f in _ANSWER_FIELDS)
        self._status = block(_STATUS_FIELDS)
        self._motion = block(_MOTION_FIELDS)
        self.last_ticket: MotionTicket | None = None  # the motion this client started last
        self._cal = block(f"{j}Cal{s}" for j in JOINTS for s in _CAL_SUFFIXES)
        self.batch_max = _batch_size()
        self._targets = block(f"Batch{a}{k:02d}" for k in range(1, self.batch_max + 1)
                              for a in "XYZ")
        self._results = block(f"{p}{k:02d}" for k in range(1, self.batch_max + 1)
                              for p in _RESULT_PREFIXES)
        self._lut = block(_LUT_FIELDS)
        self._five = block(_FIVE_FIELDS)
        self._wrist = block(_WRIST_FIELDS)
        self._wrist_cal = block(f"{j}Cal{s}" for j in WRIST_JOINTS for s in _CAL_SUFFIXES)
        self._gripper = block(_GRIPPER_FIELDS)
        self._gripper_cal = block(f"GripperCal{s}" for s in _CAL_SUFFIXES)
        self._imu = block(_IMU_FIELDS)
        self._follow = block(_FOLLOW_FIELDS)
        self._channel_regs = [cmap[f"CH{n:02d}OFF"] for n in range(16)]
        self._init_regs = [(cmap[f"INITREG{n}"], cmap[f"INITDATA{n}"]) for n in range(1, 6)]
        self._holds_batch = False
        self.polls = 0  # answer reads spent waiting for acknowledges
        self.answered = 0  # blocks of this client the PLC answered (Busy retries included)
        self.resends = 0  # commands written again (block overwritten, mailbox lost, reconnect)
        self.reconnects = 0

    def __enter__(self) -> ArmControllerClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- raw block access --------------------------------------------------------------------

    def _io(self, op: Callable[[], _T], deadline: float) -> _T:
        """One Modbus request; a broken connection is reopened until ``deadline``."""
        while True:
            try:
                return op()
            except ModbusIoError as exc:
                if time.monotonic() > deadline:
                    raise HandshakeTimeout(f"PLC at {self.plc.host}:{self.plc.port} does not "
                                           f"answer: {exc}") from exc
                time.sleep(0.01)
                self._reconnect()

    def _reconnect(self) -> None:
        self.reconnects += 1
        self.plc.close()
        try:
            self.plc.connect()
        except ModbusIoError:
            pass  # the next request fails again and _io() decides whether to go on

    def _read(self, b: _Block, length: int | None = None) -> list[int]:
        """The first ``length`` (default: all) registers of ``b``, in requests of at most
        124 registers (even: never splitting a 32-bit value)."""
        length = b.length if length is None else length
        words: list[int] = []
        while len(words) < length:
            n = min(_MAX_READ_REGS - 1, length - len(words))
            words += self.plc.read_table(b.table, b.address + len(words), n)
        return words

    def _read_block(self, b: _Block) -> list[float]:
        """One result block, decoded; a broken connection is reopened for ``timeout_s``."""
        return b.decode(self._io(lambda: self._read(b), time.monotonic() + self.timeout_s))

    def read_register(self, name: str) -> int | float:
        """One located variable of the controller by name, decoded (a BOOL as 0 or 1)."""
        reg = self.registers[name.upper()]
        words = self.plc.read_table(reg.table, reg.address, reg.count)
        return words[0] if reg.table in ("coil", "discrete") else reg.decode(words)

    def _write(self, address: int, words: list[int]) -> None:
        done = 0
        while done < len(words):
            n = min(_MAX_WRITE_REGS - 1, len(words) - done)
            self.plc.write_registers(address + done, words[done: done + n])
            done += n

    # -- status ------------------------------------------------------------------------------

    def answer(self, mailbox: int) -> Answer:
        """The answer block of ``mailbox`` (1..MAILBOXES)."""
        b = self._answers[mailbox - 1]
        v = b.decode(self._read(b))
        return Answer(int(v[0]), int(v[1]), int(v[2]), int(v[3]))

    def answers(self) -> list[Answer]:
        """All mailboxes' answer blocks, in mailbox order."""
        b = self._all_answers
        v = [int(x) for x in b.decode(self._read(b))]
        return [Answer(*v[i: i + 4]) for i in range(0, len(v), 4)]

    def status(self) -> Status:
        """The controller's status; ``error_id``/``ack_seq`` are this client's mailbox's."""
        f = dict(zip(_STATUS_FIELDS, self._status.decode(self._read(self._status)),
                     strict=True))
        a = self.answer(self.mailbox) if self.mailbox is not None else Answer(0, 0, 0, 0)
        return Status(
            mailbox=self.mailbox or 0, ack_seq=a.ack_seq, error_id=a.result,
            state=int(f["CtlState"]), busy_mailbox=int(f["BusyMailbox"]),
            scan_count=int(f["ScanCount"]), commands_answered=int(f["CommandsAnswered"]),
            commands_ignored=int(f["CommandsIgnored"]),
            joints_deg=(f["BaseDeg"], f["ShoulderDeg"], f["ElbowDeg"]),
            echo_mm=(f["EchoX"], f["EchoY"], f["EchoZ"]),
            pulses_us=(f["BasePulseUs"], f["ShoulderPulseUs"], f["ElbowPulseUs"]),
            prescale=int(f["PwmPrescale"]), pwm_ready=bool(f["PwmReady"]),
            init_frames=int(f["InitFrames"]), batch_owner=int(f["BatchOwner"]),
            batch_count=int(f["BatchCount"]), batch_failures=int(f["BatchFailures"]),
            driver_fault=bool(f["DriverFaultHeld"]), driver_faults=int(f["DriverFaults"]),
        )

    def scan_count(self) -> int:
        """The PLC's ScanCount (a reconnection is tried for ``timeout_s`` if the connection
        is broken or not served: also a way to make sure the PLC serves this connection)."""
        reg = self.registers["SCANCOUNT"]
        return int(reg.decode(self._io(
            lambda: self.plc.read_table(reg.table, reg.address, reg.count),
            time.monotonic() + self.timeout_s)))

    def wait_scans(self, scans: int, timeout_s: float = 5.0) -> None:
        """Return after the PLC has run ``scans`` more scans (raises HandshakeTimeout when it
        stops scanning): the way to wait for "nothing happened" in a test."""
        start = self.scan_count()
        deadline = time.monotonic() + timeout_s
        while (self.scan_count() - start) & 0xFFFFFFFF < scans:
            if time.monotonic() > deadline:
                raise HandshakeTimeout(f"the PLC ran fewer than {scans} scans in {timeout_s:g} s")
            time.sleep(0.002)

    def channel_words(self) -> list[int]:
        """The 16 LEDn_OFF words (one request: they are contiguous)."""
        first = self._channel_regs[0]
        return self.plc.read_table(first.table, first.address, 16)

    def init_frames(self) -> list[tuple[int, int]]:
        """(register, data) of the published PCA9685 init frames 1..5."""
        first = self._init_regs[0][0]
        words = self.plc.read_table(first.table, first.address, 10)
        return [(words[2 * i], words[2 * i + 1]) for i in range(5)]

    def calibration(self) -> tuple[Calibration, Calibration, Calibration]:
        """The three joints' calibration as the PLC uses it (the read-back block)."""
        v = self._cal.decode(self._read(self._cal))
        n = len(_CAL_SUFFIXES)
        cals = [Calibration(v[i], int(v[i + 1]), *v[i + 2: i + n]) for i in range(0, 3 * n, n)]
        return cals[0], cals[1], cals[2]

    # -- the mailbox handshake ---------------------------------------------------------------

    def block_words(self, mailbox: int, seq: int, code: int, *, ints: tuple[int, int] = (0, 0),
                    args: Sequence[float] = (), session: int | None = None,
                    check: int | None = None) -> tuple[int, list[int]]:
        """(first holding register, words) of a command block for ``mailbox``: what the client
        writes with one FC16 request. ``session``/``check`` default to this client's session
        and the correct check word (tests pass others to probe the PLC)."""
        if len(args) > 6:
            raise ValueError(f"a command takes at most 6 REAL arguments, got {len(args)}")
        s = self.session if session is None else session
        c = check_word(seq, s, code, *ints, args=args) if check is None else check
        values = (seq, s, code, *ints, *args, *([0.0] * (6 - len(args))), c)
        b = self._commands[mailbox - 1]
        words = b.encode(values)
        assert len(words) <= _MAX_WRITE_REGS
        return b.address, words

    def _send(self, mailbox: int, code: int, ints: tuple[int, int],
              args: Sequence[float]) -> Pending:
        self._seq = next_seq(self._seq)
        address, words = self.block_words(mailbox, self._seq, code, ints=ints, args=args)
        p = Pending(mailbox, self._seq, code, check_word(self._seq, self.session, code, *ints,
                                                         args=args),
                    address, tuple(words), time.monotonic())
        try:
            self.plc.write_registers(address, words)
        except ModbusIoError:
            # it may or may not have landed: wait() reads the block back and decides
            self._reconnect()
        return p

    def wait(self, p: Pending, *, judge_lease: bool = True) -> int:
        """Wait until the PLC answers ``p``; returns its result code. Raises
        :class:`MailboxLost` when another session took the mailbox before the command ran,
        :class:`HandshakeLost` when that cannot be told apart from a command that ran (with
        ``judge_lease=False``, for commands that change nothing, it waits on instead)."""
        deadline = p.sent_at + self.timeout_s
        last_look = p.sent_at
        longest_gap = 0.0
        next_block_check = p.sent_at + _BLOCK_RECHECK_S
        while True:
            self.polls += 1
            a = self._io(lambda: self.answer(p.mailbox), deadline)
            now = time.monotonic()
            longest_gap = max(longest_gap, now - last_look)
            last_look = now
            if a.ack_seq == p.seq and a.ack_check == p.check and a.owner in (0, self.session):
                # Owner 0: answered, and since then the mailbox was closed (Close) or its
                # lease ran out; the answer stays until another block is answered there.
                if a.owner == 0 and p.code != CMD_CLOSE and self.mailbox == p.mailbox:
                    self.mailbox = None
                self.answered += 1
                return a.result
            if a.owner != self.session and judge_lease and longest_gap > self._lease_s:
                # Not answered, and the mailbox is not ours (any more): a command answered,
                # its mailbox then freed by the lease and used by another client looks the
                # same as one never taken. Only a client that looked more often than the
                # lease lasts can tell them apart. (Owner still ours means no lease ran out.)
                raise HandshakeLost(
                    f"mailbox {p.mailbox}: {longest_gap:.1f} s without a look at the answer "
                    f"(the lease is about {self._lease_s:.1f} s) and the mailbox is no longer "
                    f"this client's; seq {p.seq} (code {p.code}) may or may not have run: "
                    "read the PLC's state before going on")
            if a.owner not in (0, self.session):
                raise MailboxLost(f"mailbox {p.mailbox} was taken by session {a.owner} before "
                                  f"the PLC took seq {p.seq}")
            if now > deadline:
                raise HandshakeTimeout(
                    f"mailbox {p.mailbox}: seq {p.seq} (code {p.code}) not answered in "
                    f"{self.timeout_s:g} s (Owner {a.owner}, AckSeq {a.ack_seq}, "
                    f"Result {a.result}); is the PLC program running?")
            if now >= next_block_check:
                next_block_check = now + _BLOCK_RECHECK_S
                words = self._io(lambda: self.plc.read_holding_registers(p.address,
                                                                        len(p.words)), deadline)
                if tuple(words) != p.words:
                    # overwritten before the PLC took it (a claiming client, or our own write
                    # lost with a broken connection): the PLC answers a block once, so
                    # writing it again cannot run it twice
                    self.resends += 1
                    self._io(lambda: self.plc.write_registers(p.address, list(p.words)),
                             deadline)
                    continue
            if self.poll_interval_s > 0.0:
                time.sleep(self.poll_interval_s)

    def open(self) -> int:
        """Claim a free mailbox (a Hello command); returns its number (1..MAILBOXES)."""
        if self.mailbox is not None:
            return self.mailbox
        deadline = time.monotonic() + self.timeout_s
        s0 = self._io(self.scan_count, deadline)
        t0_end = time.monotonic()
        while True:
            free = [k for k, a in enumerate(self._io(self.answers, deadline), start=1)
                    if a.owner == 0]
            random.shuffle(free)  # clients starting together rarely pick the same one
            for k in free:
                try:
                    # A slow answer is still an answer: giving up on it would leave the PLC
                    # holding a mailbox for this session that the client does not know about.
                    result = self.wait(self._send(k, CMD_HELLO, (0, 0), ()), judge_lease=False)
                except MailboxLost:
                    continue  # another client claimed it first: try the next one
                if result == ERR_OK:
                    self.mailbox = k
                    self._measure_lease(t0_end, s0, deadline)
                    return k
            if time.monotonic() > deadline:
                raise NoFreeMailbox(
                    f"all {MAILBOXES} mailboxes of the PLC at {self.plc.host}:{self.plc.port} "
                    f"are held by other clients; a mailbox is freed by Close or after "
                    f"{LEASE_SCANS} scans without a command from its holder")
            time.sleep(0.05)

    def _measure_lease(self, t0_end: float, s0: int, deadline: float) -> None:
        """A lower bound on the lease in seconds: LEASE_SCANS times the shortest scan period
        consistent with two ScanCount readings, halved for safety."""
        while True:
            t1 = time.monotonic()
            s1 = self._io(self.scan_count, deadline)
            if s1 - s0 >= 3 or time.monotonic() > deadline:
                break
            time.sleep(0.01)
        scans = max(1, (s1 - s0) & 0xFFFFFFFF) + 1
        period = max(t1 - t0_end, 0.0) / scans
        self._lease_s = 0.5 * LEASE_SCANS * period

    def close(self) -> None:
        """Give the mailbox back (Close) and the batch buffer with it. Never raises for a PLC
        that has gone away: the lease frees the mailbox then."""
        if self.mailbox is None:
            return
        try:
            self.wait(self._send(self.mailbox, CMD_CLOSE, (0, 0), ()))
        except (HandshakeError, MailboxLost, ModbusIoError):
            pass
        self.mailbox = None
        self._holds_batch = False

    def command(self, code: int, *, ints: tuple[int, int] = (0, 0),
                args: Sequence[float] = ()) -> Status:
        """Run one command and wait for its answer; returns the status read after it, with
        the command's result code as ``error_id``."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            mailbox = self.open()
            try:
                result = self.wait(self._send(mailbox, code, ints, args))
            except MailboxLost:
                # nothing ran (the lease check in wait() makes sure): claim another, resend
                self.resends += 1
                self.mailbox = None
                self._holds_batch = False
                if time.monotonic() > deadline:
                    raise HandshakeTimeout(f"code {code}: mailbox lost again and again") from None
                continue
            if result == ERR_BUSY and self.retry_busy and time.monotonic() < deadline:
                time.sleep(_BUSY_RETRY_S)
                continue
            return self._io(self.status, deadline)

    def submit(self, code: int, *, ints: tuple[int, int] = (0, 0),
               args: Sequence[float] = ()) -> Pending:
        """Write one command to this client's mailbox (claimed first if needed) and return
        without waiting; :meth:`wait` follows it up."""
        return self._send(self.open(), code, ints, args)

    def hello(self) -> Status:
        """Claim a mailbox or renew its lease."""
        return self.command(CMD_HELLO)

    def move_xyz(self, x: float, y: float, z: float, elbow_down: bool = False,
                 wait: bool = False) -> Status:
        """MoveXyz: starts a joint move to the IK of (x, y, z); ``wait`` waits until that
        motion has ended (the status then shows the servos there)."""
        return self._motion_command(CMD_MOVE_XYZ, (int(elbow_down), 0), (x, y, z), wait)

    def move_joints(self, base: float, shoulder: float, elbow: float,
                    wait: bool = False) -> Status:
        return self._motion_command(CMD_MOVE_JOINTS, (0, 0), (base, shoulder, elbow), wait)

    # -- motion (codes 11..19) ---------------------------------------------------------------

    def _motion_command(self, code: int, ints: tuple[int, int], args: Sequence[float],
                        wait: bool, timeout_s: float = 30.0) -> Status:
        st = self.command(code, ints=ints, args=args)
        if st.error_id == ERR_OK and self.mailbox is not None:
            ticket = MotionTicket(self.mailbox, self.session, self._seq)
            self.last_ticket = ticket
            if wait:
                self.wait_motion(ticket, timeout_s=timeout_s)
                st = self._io(self.status, time.monotonic() + self.timeout_s)
            return replace(st, ticket=ticket)
        return st

    def move_joints_profile(self, target: Vec3, profile: int, velocity: float,
                            acceleration: float, jerk: float = 0.0,
                            wait: bool = False) -> Status:
        """MoveJointsProfile: joint move with profile 0..4 (MotionJointMove: 0 constant speed
        per joint, 1 synchronised constant speed, 2 trapezoid, 3 quintic, 4 time-optimal
        jerk-limited), deg and s."""
        return self._motion_command(CMD_MOVE_JOINTS_PROFILE, (profile, 0),
                                    (*target, velocity, acceleration, jerk), wait)

    def move_linear(self, target: Vec3, velocity: float, acceleration: float = 500.0,
                    fineness: float = 1.0, method: int = 2, elbow_down: bool = False,
                    wait: bool = False) -> Status:
        """MoveLinear: straight line of the tool (MotionLinear), mm, mm/s, mm/s^2."""
        return self._motion_command(CMD_MOVE_LINEAR, (method, int(elbow_down)),
                                    (*target, velocity, acceleration, fineness), wait)

    def jog_start(self, stick: Vec3, max_speed: float, acceleration: float,
                  elbow_down: bool = False, jerk: float = 0.0) -> Status:
        """JogStart: jog along the stick (-1..+1 per axis); keep it alive with
        :meth:`jog_update` more often than every ``JOG_DEADMAN_SCANS`` scans. ``jerk``
        (mm/s^3): 0 = the acceleration-limited jog; > 0 (up to 1e7) its starts, stops and
        changes of direction are jerk-limited too."""
        return self._motion_command(CMD_JOG_START, (0, int(elbow_down)),
                                    (*stick, max_speed, acceleration, jerk), False)

    def jog_update(self, stick: Vec3) -> Status:
        return self.command(CMD_JOG_UPDATE, args=stick)

    def jog_stop(self) -> Status:
        return self.command(CMD_JOG_STOP)

    def stop(self, deceleration: float = 0.0, wait: bool = False) -> Status:
        """Stop: the group brakes to standstill (0 = every joint at its own limit)."""
        return self._motion_command(CMD_STOP, (0, 0), (deceleration,), wait)

    def set_motion_limits(self, joint: int, max_vel_deg: float, max_acc_deg: float) -> Status:
        """SetMotionLimits of joint 0 Base, 1 Shoulder, 2 Elbow (deg/s, deg/s^2)."""
        return self.command(CMD_SET_MOTION_LIMITS, ints=(joint, 0),
                            args=(max_vel_deg, max_acc_deg))

    def motion(self) -> MotionSample:
        """The motion registers, one FC3 request (they are contiguous)."""
        return MotionSample.decode(self._read_block(self._motion))

    def wait_motion(self, ticket: MotionTicket | Status | None = None,
                    timeout_s: float = 30.0) -> MotionOutcome:
        """Wait until the motion started by ``ticket`` (default: this client's last one) has
        ended, or another motion has taken its place. ``ticket`` may be the Status a motion
        command returned (:meth:`move_linear`, :meth:`move_xyz`, ...)."""
        if isinstance(ticket, Status):
            if ticket.ticket is None:
                # A status compared with the PLC's motion ticket never matches: waiting on it
                # would report any motion, the one it started included, as superseded.
                raise ValueError(
                    "wait_motion: this status started no motion (result code "
                    f"{ticket.error_id}; only an accepted motion command's status names one)")
            ticket = ticket.ticket
        elif ticket is not None and not isinstance(ticket, MotionTicket):
            raise TypeError("wait_motion takes a MotionTicket or the Status a motion command "
                            f"returned, not {type(ticket).__name__}")
        ticket = ticket or self.last_ticket
        if ticket is None:
            raise ValueError("wait_motion: this client has started no motion")
        deadline = time.monotonic() + timeout_s
        while True:
            m = self.motion()
            if m.ticket != ticket:
                return MotionOutcome("superseded", m.error_id, m.ticket, m)
            if not m.busy:
                state = ("done" if m.done else "error" if m.error else
                         "aborted" if m.aborted else "done")
                return MotionOutcome(state, m.error_id, None, m)
            if time.monotonic() > deadline:
                raise MotionTimeout(f"motion {ticket} still busy after {timeout_s:g} s "
                                    f"(progress {m.progress:.3f})")
            time.sleep(0.005)

    def init_pwm(self) -> Status:
        return self.command(CMD_INIT_PWM)

    def relax(self) -> Status:
        return self.command(CMD_RELAX)

    def set_calibration(self, joint: int, cal: Calibration) -> Status:
        """SetCalibration of joint 0 Base, 1 Shoulder, 2 Elbow; check ``error_id``."""
        c = astuple(cal)
        return self.command(CMD_SET_CALIBRATION, ints=(joint, int(c[1])),
                            args=(c[0], c[2], c[3], c[4], c[5]))

    # -- 5-axis arm (codes 30..39: InverseKinematik5Axis, wrist on channels 3 and 4) -------

    @staticmethod
    def _five_flags(flange_fixed: bool, elbow_down: bool) -> int:
        return (FIVE_FLAG_FLANGE_FIXED if flange_fixed else 0) | (
            FIVE_FLAG_ELBOW_DOWN if elbow_down else 0)

    def move_tool_angles(self, position: Vec3, pitch_deg: float, roll_deg: float, *,
                         flange_fixed: bool = False, elbow_down: bool = False,
                         wait: bool = False) -> Status:
        """MoveToolAngles: the tool tip (or, ``flange_fixed``, the flange point) to
        ``position`` (mm) with the tool pitched and rolled (deg), as one synchronised joint
        move of all five joints; ``error_id`` 0 = started (see :meth:`five_axis_echo`)."""
        return self._motion_command(CMD_MOVE_TOOL_ANGLES,
                                    (self._five_flags(flange_fixed, elbow_down), 0),
                                    (*position, pitch_deg, roll_deg), wait)

    def move_tool_vector(self, position: Vec3, direction: Vec3, roll_deg: float = 0.0, *,
                         flange_fixed: bool = False, elbow_down: bool = False,
                         wait: bool = False) -> Status:
        """MoveToolVector: as :meth:`move_tool_angles` with the tool direction (any length,
        in the arm plane) and the roll; the roll travels in 0.01 deg steps."""
        roll100 = round(roll_deg * 100.0)
        if not abs(roll100) <= FIVE_ROLL_MAX_100:
            raise ValueError(f"move_tool_vector: roll must lie within "
                             f"+/-{FIVE_ROLL_MAX_100 / 100.0:g} deg, got {roll_deg}")
        return self._motion_command(CMD_MOVE_TOOL_VECTOR,
                                    (self._five_flags(flange_fixed, elbow_down), roll100),
                                    (*position, *direction), wait)

    def five_axis_echo(self) -> FiveAxisEcho:
        """The 5-axis echo block (one read: a consistent snapshot)."""
        v = self._read_block(self._five)
        return FiveAxisEcho(int(v[0]), int(v[1]), int(v[2]), (v[3], v[4], v[5], v[6], v[7]),
                            (v[8], v[9], v[10]), (v[11], v[12], v[13]), v[14], v[15])

    def wrist(self) -> WristSample:
        """The wrist joints' setpoints, servo angles, pulses and limits (one read)."""
        v = self._read_block(self._wrist)
        return WristSample((v[0], v[1]), (v[2], v[3]), (v[4], v[5]), (v[6], v[7]), (v[8], v[9]))

    def wrist_calibration(self) -> tuple[Calibration, Calibration]:
        """The wrist pitch and roll servos' calibration (SetCalibration joints 3, 4)."""
        v = self._read_block(self._wrist_cal)
        n = len(_CAL_SUFFIXES)
        return (Calibration(v[0], int(v[1]), *v[2:n]),
                Calibration(v[n], int(v[n + 1]), *v[n + 2: 2 * n]))

    # -- wrist jog (code 32) and gripper (code 33) ------------------------------------------

    def jog_wrist_start(self, pitch_rate_deg: float, roll_rate_deg: float,
                        max_speed_deg: float = 0.0, acceleration_deg: float = 0.0, *,
                        flange_fixed: bool = False) -> Status:
        """JogWrist: turn the tool at these pitch/roll rates (deg/s); ``flange_fixed`` moves
        only the wrist, else the tool tip stays where it is. 0 speed/acceleration = the
        controller's defaults. Keep it alive with :meth:`jog_wrist_update` (or
        :meth:`jog_update` with (pitch, roll, 0)) more often than every
        ``JOG_DEADMAN_SCANS`` scans; :meth:`jog_stop` brakes it."""
        return self._motion_command(CMD_JOG_WRIST, (self._five_flags(flange_fixed, False), 0),
                                    (pitch_rate_deg, roll_rate_deg, max_speed_deg,
                                     acceleration_deg), False)

    def jog_wrist_update(self, pitch_rate_deg: float, roll_rate_deg: float) -> Status:
        """JogUpdate of a wrist jog: the new pitch and roll rates (deg/s)."""
        return self.command(CMD_JOG_UPDATE, args=(pitch_rate_deg, roll_rate_deg, 0.0))

    def set_gripper(self, opening_pct: float) -> Status:
        """SetGripper: open the gripper to ``opening_pct`` (0 closed .. 100 open, of the
        calibrated travel); ``error_id`` 8 BadParameter outside that range."""
        return self.command(CMD_SET_GRIPPER, args=(opening_pct,))

    def gripper(self) -> GripperSample:
        """The gripper channel's opening, servo angle, pulse, limits (one read)."""
        v = self._read_block(self._gripper)
        return GripperSample(v[0], v[1], v[2], v[3], v[4], bool(v[5]))

    def gripper_calibration(self) -> Calibration:
        """The gripper servo's calibration (SetCalibration joint ``JOINT_GRIPPER``)."""
        v = self._read_block(self._gripper_cal)
        return Calibration(v[0], int(v[1]), *v[2:])

    # -- SolveBatch --------------------------------------------------------------------------

    @contextmanager
    def batch_buffer(self) -> Iterator[None]:
        """Hold the batch buffer for the block (ReserveBatch ... ReleaseBatch)."""
        if self._holds_batch:
            yield
            return
        st = self.command(CMD_RESERVE_BATCH)
        if st.error_id != ERR_OK:
            raise CommandRejected(f"ReserveBatch (buffer held by mailbox {st.batch_owner})",
                                  st.error_id)
        self._holds_batch = True
        try:
            yield
        finally:
            if self._holds_batch and self.mailbox is not None:
                self.command(CMD_RELEASE_BATCH)
            self._holds_batch = False

    def submit_batch(self, points: Sequence[tuple[float, float, float]],
                     elbow_down: bool = False, code: int = CMD_SOLVE_BATCH) -> Pending:
        """Write up to ``batch_max`` targets, then the SolveBatch block (``code``:
        LutSolveBatch for the LUT) without waiting; the caller must hold the batch buffer
        (:meth:`batch_buffer`)."""
        n = len(points)
        if not 1 <= n <= self.batch_max:
            raise ValueError(f"a batch holds 1..{self.batch_max} points, got {n}")
        values = [c for p in points for c in p]
        words = self._targets.encode(values + [0.0] * (3 * self.batch_max - len(values)))
        # 3 REALs = 6 words per point; writing them again after a broken connection is harmless
        self._io(lambda: self._write(self._targets.address, words[: 6 * n]),
                 time.monotonic() + self.timeout_s)
        return self._send(self.open(), code, (int(elbow_down), n), ())

    def batch_results(self, n: int) -> list[BatchPoint]:
        """The first ``n`` SolveBatch results (read after the acknowledge)."""
        per = len(_RESULT_PREFIXES)
        words = self._io(lambda: self._read(self._results, 2 * per * n),
                         time.monotonic() + self.timeout_s)
        v = self._results.decode(words + [0] * (self._results.length - len(words)))
        return [BatchPoint((v[i], v[i + 1], v[i + 2]), (v[i + 3], v[i + 4], v[i + 5]),
                           int(v[i + 6])) for i in range(0, per * n, per)]

    def solve_batch(self, points: Sequence[tuple[float, float, float]],
                    elbow_down: bool = False, code: int = CMD_SOLVE_BATCH) -> list[BatchPoint]:
        """One SolveBatch (or ``code`` LutSolveBatch) of up to ``batch_max`` points: write,
        acknowledge, read back."""
        with self.batch_buffer():
            try:
                result = self.wait(self.submit_batch(points, elbow_down, code))
            except MailboxLost as exc:
                self.mailbox = None
                self._holds_batch = False  # went with the mailbox
                raise HandshakeError(f"SolveBatch: {exc}; the batch buffer went with it") \
                    from exc
            if result != ERR_OK:
                raise CommandRejected("SolveBatch", result)
            return self.batch_results(len(points))

    def batch_roundtrip(self, points: Sequence[tuple[float, float, float]],
                        elbow_down: bool = False) -> list[BatchPoint]:
        """Any number of points, in SolveBatch chunks of ``batch_max`` (one reservation)."""
        out: list[BatchPoint] = []
        with self.batch_buffer():
            for i in range(0, len(points), self.batch_max):
                out += self.solve_batch(points[i: i + self.batch_max], elbow_down)
        return out

    # -- LUT variant (codes 20..22: InverseKinematikFixed, integer units) ------------------

    def lut_result(self) -> LutResult:
        """The LUT result block as it is now (one read: a consistent snapshot)."""
        v = [int(x) for x in self._read_block(self._lut)]
        return LutResult(v[0], v[1], v[2], (v[3], v[4], v[5]), (v[6], v[7], v[8]),
                         (v[9], v[10], v[11]), v[12])

    def _lut_command(self, code: int, target_mm100: tuple[int, int, int],
                     elbow_down: bool) -> LutResult:
        args = tuple(lut_target_mm(v) for v in target_mm100)
        deadline = time.monotonic() + self.timeout_s
        while True:
            st = self.command(code, ints=(int(elbow_down), 0), args=args)
            if st.error_id in _NOT_RUN:
                # answered without running (Busy while InitPwm runs, or a PLC program
                # without the LUT commands): the result block is not this command's
                return LutResult(self.session, st.ack_seq, st.error_id, (0, 0, 0), (0, 0, 0),
                                 (0, 0, 0), 0)
            res = self._io(self.lut_result, deadline)
            if (res.session, res.seq) == (self.session, st.ack_seq):
                return res
            # another client's LUT command overwrote the shared block before the read: the
            # solve has no side effect beyond the block (a LutMoveXyz moves to the same
            # angles again), so run it again
            if time.monotonic() > deadline:
                raise HandshakeTimeout(
                    f"LUT code {code}: the result block kept being overwritten by other "
                    f"clients for {self.timeout_s:g} s (last result code {st.error_id})")

    def lut_solve(self, x_mm100: int, y_mm100: int, z_mm100: int,
                  elbow_down: bool = False) -> LutResult:
        """LutSolve: InverseKinematikFixed of an integer target (0.01 mm) in the PLC; the
        servos do not move. Check ``error_id`` (1 Unreachable, 2 Singular, ...)."""
        return self._lut_command(CMD_LUT_SOLVE, (x_mm100, y_mm100, z_mm100), elbow_down)

    def lut_move_xyz(self, x_mm100: int, y_mm100: int, z_mm100: int,
                     elbow_down: bool = False) -> LutResult:
        """LutMoveXyz: LutSolve, then the servos move as with MoveXyz (``status()`` shows
        the joints); ``error_id`` 101 JointLimit when a servo would clamp."""
        return self._lut_command(CMD_LUT_MOVE_XYZ, (x_mm100, y_mm100, z_mm100), elbow_down)

    def lut_solve_batch(self, points_mm100: Sequence[tuple[int, int, int]],
                        elbow_down: bool = False) -> list[LutBatchPoint]:
        """LutSolveBatch of up to ``batch_max`` integer targets (0.01 mm), any number of
        them in chunks of ``batch_max`` under one reservation of the batch buffer."""
        targets = [(lut_target_mm(x), lut_target_mm(y), lut_target_mm(z))
                   for x, y, z in points_mm100]
        out: list[LutBatchPoint] = []
        with self.batch_buffer():
            for i in range(0, len(targets), self.batch_max):
                for p in self.solve_batch(targets[i: i + self.batch_max], elbow_down,
                                          CMD_LUT_SOLVE_BATCH):
                    deg = tuple(round(a * 100.0) for a in p.joints_deg)
                    mm100 = tuple(round(c * 100.0) for c in p.echo_mm)
                    out.append(LutBatchPoint((deg[0], deg[1], deg[2]),
                                             (mm100[0], mm100[1], mm100[2]), p.error_id))
        return out

    # ----- IMU: commands 40..45 and the result block -----
    def imu_state(self) -> ImuState:
        """The IMU result block as it is now (one read: a consistent snapshot)."""
        return ImuState.decode(self._read_block(self._imu))

    def imu_select_filter(self, method: str, gain: float = 0.0) -> int:
        """ImuSelectFilter: ``method`` one of IMU_FILTERS' names, ``gain`` F or beta (0.0 =
        the filter's default); restarts the filter from the sensors. Returns the Result."""
        if method not in IMU_FILTERS:
            raise ValueError(f"unknown IMU filter {method!r}; choose one of "
                             f"{', '.join(IMU_FILTERS)}")
        return self.command(CMD_IMU_SELECT_FILTER, ints=(IMU_FILTERS[method], 0),
                            args=(gain,)).error_id

    def imu_set_period(self, period_s: float) -> int:
        """ImuSetPeriod: the time between two samples, s (0 < period <= 1)."""
        return self.command(CMD_IMU_SET_PERIOD, args=(period_s,)).error_id

    def imu_set_gyro_bias(self, bias_dps: Sequence[float]) -> int:
        """ImuSetGyroBias: deg/s subtracted from each gyro axis."""
        return self.command(CMD_IMU_SET_GYRO_BIAS, args=tuple(bias_dps)).error_id

    def imu_set_accel_scale(self, scale: Sequence[float]) -> int:
        """ImuSetAccelScale: factors (0.5..2) applied to each accelerometer axis."""
        return self.command(CMD_IMU_SET_ACCEL_SCALE, args=tuple(scale)).error_id

    def imu_set_mag_offset(self, offset_gauss: Sequence[float]) -> int:
        """ImuSetMagOffset: the hard-iron offset, gauss, subtracted from each axis."""
        return self.command(CMD_IMU_SET_MAG_OFFSET, args=tuple(offset_gauss)).error_id

    def imu_reset(self, quat: Sequence[float] | None = None) -> int:
        """ImuReset: restart the filter at ``quat`` (W, X, Y, Z), or from the sensors."""
        if quat is None:
            return self.command(CMD_IMU_RESET, ints=(0, 1)).error_id
        return self.command(CMD_IMU_RESET, ints=(0, 0), args=tuple(quat)).error_id

    def follow_imu(self, *, flange_fixed: bool = False, dead_band_deg: float = 0.0,
                   max_rate_dps: float = 0.0, heading_deg: float = 0.0,
                   mount_rpy_deg: Sequence[float] = (0.0, 0.0, 0.0),
                   max_jerk_dps3: int = 0) -> Status:
        """FollowImu start: the tool follows the fused orientation, holding the tool tip (or,
        ``flange_fixed``, the flange point) where it stands. ``heading_deg``: the arm's X axis
        from magnetic north, counter-clockwise about Z up. ``mount_rpy_deg``: the sensor's
        mounting (Z-Y-X roll, pitch, yaw). 0.0 dead band / rate = the defaults (2 deg,
        90 deg/s). ``max_jerk_dps3``: 0 = the turning speed is acceleration-limited only;
        1..1000000 deg/s^3 jerk-limits it too. A motion of this client: ``error_id`` 0 =
        following."""
        if len(mount_rpy_deg) != 3:
            raise ValueError(f"follow_imu: mount_rpy_deg needs roll, pitch, yaw, got "
                             f"{len(mount_rpy_deg)} values")
        flags = FOLLOW_FLAG_START | (FOLLOW_FLAG_FLANGE_FIXED if flange_fixed else 0)
        return self._motion_command(CMD_FOLLOW_IMU, (flags, max_jerk_dps3),
                                    (dead_band_deg, max_rate_dps, heading_deg,
                                     *mount_rpy_deg), False)

    def follow_imu_stop(self, wait: bool = False) -> Status:
        """FollowImu stop: the follow this client started brakes to rest (108 otherwise)."""
        st = self.command(CMD_FOLLOW_IMU, ints=(0, 0))
        if wait and st.error_id == ERR_OK and self.last_ticket is not None:
            self.wait_motion(self.last_ticket)
            return self._io(self.status, time.monotonic() + self.timeout_s)
        return st

    def follow_state(self) -> FollowState:
        """The FollowImu block (one read: a consistent snapshot)."""
        return FollowState.decode(self._read_block(self._follow))


@dataclass
class MotionRecording:
    """The samples of a :class:`MotionRecorder`, one per scan seen, in scan order."""

    samples: list[MotionSample]
    missed_scans: int  # scans between the first and the last sample that were not sampled
    reads: int  # FC3 requests made

    def consecutive(self) -> Iterator[tuple[MotionSample, MotionSample]]:
        """Pairs of samples of neighbouring scans (k, k + 1): per-scan steps are exact."""
        for a, b in zip(self.samples, self.samples[1:], strict=False):
            if (b.scan - a.scan) & 0xFFFFFFFF == 1:
                yield a, b

    def triples(self) -> Iterator[tuple[MotionSample, MotionSample, MotionSample]]:
        """Samples of three neighbouring scans (for the change of a per-scan step)."""
        s = self.samples
        for a, b, c in zip(s, s[1:], s[2:], strict=False):
            if (b.scan - a.scan) & 0xFFFFFFFF == 1 and (c.scan - b.scan) & 0xFFFFFFFF == 1:
                yield a, b, c


class MotionRecorder:
    """Samples the motion registers every scan on its own connection (one FC3 read per
    sample, tagged with the PLC's ScanCount), in a background thread between
    :meth:`start` and :meth:`stop`. Scans it could not sample are counted, never guessed."""

    def __init__(self, host: str, port: int, poll_interval_s: float = 0.001,
                 flavor: str | Flavor = mm.OPENPLC) -> None:
        self.host, self.port = host, port
        self.flavor = mm.flavor(flavor)
        self.poll_interval_s = poll_interval_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._samples: list[MotionSample] = []
        self._reads = 0
        self._error: BaseException | None = None

    def __enter__(self) -> MotionRecorder:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._thread is not None:
            self.stop()

    @property
    def recording(self) -> bool:
        return self._thread is not None

    def start(self, timeout_s: float = 30.0) -> None:
        """Start sampling; returns when the first sample is in. A motion started after this
        has a sample before its first scan (the tests bracket its start with it), so a
        recorder that has none after ``timeout_s`` raises HandshakeTimeout (it used to return
        after 5 s all the same, and a loaded machine then recorded a move without its start)."""
        if self._thread is not None:
            raise RuntimeError("MotionRecorder.start: already recording")
        self._stop.clear()
        self._samples = []
        self._reads = 0
        self._error = None
        ready = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(ready,), daemon=True,
                                        name="motion-recorder")
        self._thread.start()
        if not ready.wait(timeout_s):
            self.stop()  # raises what broke the connection, if anything did
            raise HandshakeTimeout(f"motion recorder at {self.host}:{self.port}: no sample "
                                   f"in {timeout_s:g} s")

    def _run(self, ready: threading.Event) -> None:
        try:
            with PlcClient(self.host, self.port) as plc:
                ctl = ArmControllerClient(plc, flavor=self.flavor)
                last = -1
                while not self._stop.is_set():
                    m = ctl.motion()
                    self._reads += 1
                    if m.scan != last:
                        self._samples.append(m)
                        last = m.scan
                    # start() returns once a sample is in: a connection is not served the
                    # moment it is accepted (OpenPLC's accept loop), and a motion started
                    # before the first read would lose its first scans
                    ready.set()
                    if self.poll_interval_s > 0.0:
                        time.sleep(self.poll_interval_s)
        except BaseException as exc:  # reported by stop(): a thread cannot raise to the test
            self._error = exc
            ready.set()

    def stop(self) -> MotionRecording:
        """End the recording; raises what broke the sampling connection, if anything."""
        if self._thread is None:
            raise RuntimeError("MotionRecorder.stop: not recording")
        self._stop.set()
        self._thread.join(10.0)
        self._thread = None
        if self._error is not None:
            raise HandshakeError(f"motion recorder at {self.host}:{self.port}: "
                                 f"{self._error}") from self._error
        samples = sorted(self._samples, key=lambda m: m.scan)
        missed = sum(max(0, ((b.scan - a.scan) & 0xFFFFFFFF) - 1)
                     for a, b in zip(samples, samples[1:], strict=False))
        return MotionRecording(samples, missed, self._reads)

    def record_until_idle(self, client: ArmControllerClient, ticket: MotionTicket | None = None,
                          timeout_s: float = 30.0) -> tuple[MotionOutcome, MotionRecording]:
        """While recording: wait for ``client``'s motion to end, then until this recorder
        holds a sample 5 scans after the end (so the standstill is in the record, however
        slowly a loaded machine lets it sample: waiting for 5 scans on ``client`` left the
        last sample before the end, under load against the real v3 runtime), and stop."""
        outcome = client.wait_motion(ticket, timeout_s=timeout_s)
        end = outcome.sample.scan
        deadline = time.monotonic() + timeout_s
        while not (self._samples  # the last sample 5 or more scans after the end (mod 2^32)
                   and 5 <= (self._samples[-1].scan - end) & 0xFFFFFFFF < 0x80000000):
            if self._thread is None or not self._thread.is_alive() \
                    or time.monotonic() > deadline:
                break  # stop() reports a broken recorder; a record without it is judged so
            time.sleep(0.005)
        return outcome, self.stop()
