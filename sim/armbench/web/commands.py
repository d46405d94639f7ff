"""The controller commands the live view can send: one table, one entry per command.

Each :class:`CommandSpec` names the command's constant in ``Controller.st`` (its code comes
from the program, so the page cannot drift from the ST), its form fields and which mailbox
slot each field fills (Int1, Int2, Arg1..Arg6). A command whose constant the loaded
controller does not declare is left off the page, so an entry can be added before the
controller has it. Values from the page are checked here (numbers, finite, integers in range,
one of the listed choices) before anything is written to the PLC: bad input is a
:class:`BadInput` with a message for the page, never a command.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

from ..controller_client import (
    JOINTS,
    WRIST_JOINTS,
    ArmControllerClient,
    BatchPoint,
    CommandRejected,
    Status,
)
from ..registermap import controller_constants

FieldKind = Literal["real", "int", "choice", "points"]
SLOTS = ("Int1", "Int2", "Arg1", "Arg2", "Arg3", "Arg4", "Arg5", "Arg6")
DINT_MIN, DINT_MAX = -(2**31), 2**31 - 1
# A REAL argument beyond this cannot be a length, angle or pulse width the controller can use;
# the float32 encoder would overflow to inf near 3.4e38 anyway.
REAL_LIMIT = 1.0e9
# The page's command tabs, in this order.
GROUPS = ("Move", "Jog", "5-axis", "Setup", "Batch")


class BadInput(ValueError):
    """A value from the page that cannot become a command; the message says which and why."""


@dataclass(frozen=True)
class Field:
    """One form field of a command."""

    key: str  # the form's name for it (JSON key)
    label: str
    slot: str  # "Int1", "Int2", "Arg1".."Arg6", or "points" (the batch targets)
    kind: FieldKind = "real"
    default: float | str = 0.0
    unit: str = ""
    choices: tuple[tuple[int, str], ...] = ()  # (value, label) for kind "choice"
    low: float | None = None  # inclusive bounds for "int"
    high: float | None = None

    def __post_init__(self) -> None:
        if self.slot not in (*SLOTS, "points"):
            raise ValueError(f"field {self.key}: unknown slot {self.slot!r}")
        if self.kind == "choice" and not self.choices:
            raise ValueError(f"field {self.key}: a choice needs choices")


@dataclass(frozen=True)
class CommandSpec:
    """One command of the controller as the page offers it."""

    constant: str  # the CONSTANT of Controller.st holding its code, e.g. "CmdMoveXyz"
    label: str
    help: str
    fields: tuple[Field, ...] = ()
    batch: bool = False  # SolveBatch: reserve the buffer, write targets, solve, read, release
    group: str = "Move"  # the page's tab (one of GROUPS); "" = above the tabs, always shown

    def __post_init__(self) -> None:
        if self.group not in ("", *GROUPS):
            raise ValueError(f"{self.constant}: group {self.group!r} is not one of {GROUPS}")
        slots = [f.slot for f in self.fields]
        if len(set(slots)) != len(slots):
            raise ValueError(f"{self.constant}: two fields fill the same slot")


@dataclass(frozen=True)
class Prepared:
    """A checked command: the code and the mailbox block's arguments."""

    spec: CommandSpec
    code: int
    ints: tuple[int, int]
    args: tuple[float, ...]
    points: tuple[tuple[float, float, float], ...] = ()


_ELBOW = (0, "elbow up"), (1, "elbow down")
_PROFILES = ((0, "constant speed per joint"), (1, "synchronised constant speed"),
             (2, "trapezoid"), (3, "quintic (jerk-limited)"),
             (4, "time-optimal jerk-limited"))
_FOLLOW_MODES = ((1, "start, tip fixed"), (3, "start, flange fixed"), (0, "stop"))
_TOOL_MODES = ((0, "elbow up, tip fixed"), (1, "elbow down, tip fixed"),
               (2, "elbow up, flange fixed"), (3, "elbow down, flange fixed"))
_WRIST_JOG_MODES = ((0, "tip fixed"), (2, "flange fixed (only the wrist moves)"))
# SetCalibration / SetMotionLimits Int1: the arm, the wrist, the gripper (channels 0..5)
_ALL_JOINTS = tuple(enumerate((*JOINTS, *WRIST_JOINTS, "Gripper")))
_LINE_METHODS = ((0, "Bresenham (document 001)"), (1, "Bresenham + start compensation"),
                 (2, "time-scaled path"))

# The table. A new controller command is one entry here.
COMMANDS: tuple[CommandSpec, ...] = (
    CommandSpec("CmdMoveXyz", "Move to X/Y/Z", "IK of the point; servos, FK echo and PWM follow.",
                (Field("x", "X", "Arg1", default=150.0, unit="mm"),
                 Field("y", "Y", "Arg2", default=0.0, unit="mm"),
                 Field("z", "Z", "Arg3", default=120.0, unit="mm"),
                 Field("elbow", "Elbow", "Int1", "choice", 0, choices=_ELBOW)),
                group="Move"),
    CommandSpec("CmdMoveJoints", "Move joints", "Base/Shoulder/Elbow angles directly.",
                (Field("base", "Base", "Arg1", default=0.0, unit="deg"),
                 Field("shoulder", "Shoulder", "Arg2", default=70.0, unit="deg"),
                 Field("elbow", "Elbow", "Arg3", default=65.0, unit="deg")),
                group="Move"),
    CommandSpec("CmdInitPwm", "Init PWM", "PCA9685 initialisation for 50 Hz (several scans).",
                group="Setup"),
    CommandSpec("CmdRelax", "Relax", "All channels fully off: the servos go limp.",
                group="Setup"),
    CommandSpec("CmdSetCalibration", "Set calibration",
                "A joint's servo calibration (checked by the PLC; applies from the next move).",
                (Field("joint", "Joint", "Int1", "choice", 0, choices=_ALL_JOINTS),
                 Field("direction", "Direction", "Int2", "choice", 1,
                       choices=((1, "+1"), (-1, "-1"))),
                 Field("zero", "Zero offset", "Arg1", default=0.0, unit="deg"),
                 Field("min_pulse", "Min pulse", "Arg2", default=1000.0, unit="us"),
                 Field("max_pulse", "Max pulse", "Arg3", default=2000.0, unit="us"),
                 Field("min_angle", "Min angle", "Arg4", default=-60.0, unit="deg"),
                 Field("max_angle", "Max angle", "Arg5", default=60.0, unit="deg")),
                group="Setup"),
    CommandSpec("CmdSolveBatch", "Solve batch",
                "IK + FK echo of up to 32 points in one scan (one 'x y z' per line); the servos "
                "do not move.",
                (Field("points", "Points (x y z per line, mm)", "points", "points",
                       "150 0 120\n160 20 110\n400 0 0"),
                 Field("elbow", "Elbow", "Int1", "choice", 0, choices=_ELBOW)),
                batch=True,
                group="Batch"),
    CommandSpec("CmdMoveJointsProfile", "Joint move (profile)",
                "A joint move with a chosen profile through the motion layer; the servos "
                "follow scan by scan.",
                (Field("base", "Base", "Arg1", default=0.0, unit="deg"),
                 Field("shoulder", "Shoulder", "Arg2", default=70.0, unit="deg"),
                 Field("elbow", "Elbow", "Arg3", default=65.0, unit="deg"),
                 Field("profile", "Profile", "Int1", "choice", 2,
                       choices=_PROFILES),
                 Field("speed", "Speed", "Arg4", default=60.0, unit="deg/s"),
                 Field("accel", "Acceleration", "Arg5", default=300.0, unit="deg/s^2"),
                 Field("jerk", "Jerk", "Arg6", default=3000.0, unit="deg/s^3")),
                group="Move"),
    CommandSpec("CmdMoveLinear", "Straight line",
                "A Cartesian straight line to X/Y/Z (document 001's Bresenham, with or without "
                "its start compensation, or the time-scaled path).",
                (Field("x", "X", "Arg1", default=150.0, unit="mm"),
                 Field("y", "Y", "Arg2", default=40.0, unit="mm"),
                 Field("z", "Z", "Arg3", default=120.0, unit="mm"),
                 Field("speed", "Speed", "Arg4", default=40.0, unit="mm/s"),
                 Field("accel", "Acceleration", "Arg5", default=200.0, unit="mm/s^2"),
                 Field("fineness", "Fineness", "Arg6", default=2.0, unit="steps/mm"),
                 Field("method", "Method", "Int1", "choice", 2, choices=_LINE_METHODS),
                 Field("elbow", "Elbow", "Int2", "choice", 0, choices=_ELBOW)),
                group="Move"),
    CommandSpec("CmdJogStart", "Jog",
                "Cartesian jog along the stick vector (-1..+1 per axis). Dead-man: it brakes "
                "by itself 0.5 s after the last Jog/Jog update.",
                (Field("sx", "Stick X", "Arg1", default=0.5),
                 Field("sy", "Stick Y", "Arg2", default=0.0),
                 Field("sz", "Stick Z", "Arg3", default=0.0),
                 Field("speed", "Max speed", "Arg4", default=30.0, unit="mm/s"),
                 Field("accel", "Acceleration", "Arg5", default=200.0, unit="mm/s^2"),
                 Field("jerk", "Jerk (0 = none)", "Arg6", default=0.0, unit="mm/s^3"),
                 Field("elbow", "Elbow", "Int2", "choice", 0, choices=_ELBOW)),
                group="Jog"),
    CommandSpec("CmdJogUpdate", "Jog update", "New stick values for the running jog.",
                (Field("sx", "Stick X", "Arg1", default=0.5),
                 Field("sy", "Stick Y", "Arg2", default=0.0),
                 Field("sz", "Stick Z", "Arg3", default=0.0)),
                group="Jog"),
    CommandSpec("CmdJogStop", "Jog stop", "The jog brakes to a stop.",
                group="Jog"),
    CommandSpec("CmdStop", "Stop", "Any motion brakes to standstill within the limits.",
                (Field("decel", "Deceleration (0 = limits)", "Arg1", default=0.0,
                       unit="deg/s^2"),),
                group=""),
    CommandSpec("CmdSetMotionLimits", "Motion limits",
                "A joint's speed and acceleration limits (motion blocks and output stage).",
                (Field("joint", "Joint", "Int1", "choice", 0, choices=_ALL_JOINTS),
                 Field("speed", "Speed limit", "Arg1", default=150.0, unit="deg/s"),
                 Field("accel", "Acceleration limit", "Arg2", default=1000.0,
                       unit="deg/s^2")),
                group="Setup"),
    CommandSpec("CmdMoveToolAngles", "Tool pose (pitch/roll)",
                "5-axis arm: tool position plus pitch and roll (document 000), tip-fixed or "
                "flange-fixed; a synchronised joint move of all five joints.",
                (Field("x", "X", "Arg1", default=170.0, unit="mm"),
                 Field("y", "Y", "Arg2", default=0.0, unit="mm"),
                 Field("z", "Z", "Arg3", default=80.0, unit="mm"),
                 Field("pitch", "Pitch", "Arg4", default=-30.0, unit="deg"),
                 Field("roll", "Roll", "Arg5", default=0.0, unit="deg"),
                 Field("mode", "Elbow / mode", "Int1", "choice", 0, choices=_TOOL_MODES)),
                group="5-axis"),
    CommandSpec("CmdMoveToolVector", "Tool pose (direction)",
                "5-axis arm: tool position plus a tool direction in the arm plane (document "
                "004) and the roll in 0.01 deg.",
                (Field("x", "X", "Arg1", default=170.0, unit="mm"),
                 Field("y", "Y", "Arg2", default=0.0, unit="mm"),
                 Field("z", "Z", "Arg3", default=80.0, unit="mm"),
                 Field("dx", "Direction X", "Arg4", default=1.0),
                 Field("dy", "Direction Y", "Arg5", default=0.0),
                 Field("dz", "Direction Z", "Arg6", default=-0.5),
                 Field("roll", "Roll", "Int2", "int", 0, unit="0.01 deg", low=-36000,
                       high=36000),
                 Field("mode", "Elbow / mode", "Int1", "choice", 0, choices=_TOOL_MODES)),
                group="5-axis"),
    CommandSpec("CmdJogWrist", "Wrist jog (pitch/roll)",
                "5-axis arm: turn the tool at these rates (document 000's operator); tip fixed "
                "(the arm moves round the tip) or flange fixed (only the wrist). Jog update "
                "(Arg1/Arg2 = rates) keeps it alive, Jog stop brakes; dead-man 0.5 s.",
                (Field("pitch", "Pitch rate", "Arg1", default=10.0, unit="deg/s"),
                 Field("roll", "Roll rate", "Arg2", default=0.0, unit="deg/s"),
                 Field("speed", "Max speed (0 = 30)", "Arg3", default=0.0, unit="deg/s"),
                 Field("accel", "Acceleration (0 = 150)", "Arg4", default=0.0,
                       unit="deg/s^2"),
                 Field("mode", "Mode", "Int1", "choice", 0, choices=_WRIST_JOG_MODES)),
                group="5-axis"),
    CommandSpec("CmdSetGripper", "Gripper",
                "Open the gripper (channel 5) to a percentage of its calibrated travel: "
                "0 closed, 100 open. No arm motion starts or ends.",
                (Field("opening", "Opening", "Arg1", default=50.0, unit="%"),),
                group="5-axis"),
    CommandSpec("CmdFollowImu", "Follow the IMU",
                "5-axis arm: the tool follows the fused IMU orientation (pitch and roll; the "
                "tip or flange held where it stands), or stops following. Brakes by itself "
                "0.5 s after the last IMU sample.",
                (Field("mode", "Start / mode", "Int1", "choice", 1, choices=_FOLLOW_MODES),
                 Field("deadband", "Dead band (0 = 2)", "Arg1", default=0.0, unit="deg"),
                 Field("rate", "Max rate (0 = 90)", "Arg2", default=0.0, unit="deg/s"),
                 Field("heading", "Arm X from magnetic north", "Arg3", default=0.0,
                       unit="deg"),
                 Field("mroll", "Mount roll", "Arg4", default=0.0, unit="deg"),
                 Field("mpitch", "Mount pitch", "Arg5", default=0.0, unit="deg"),
                 Field("myaw", "Mount yaw", "Arg6", default=0.0, unit="deg"),
                 Field("jerk", "Jerk limit (0 = none)", "Int2", "int", 0, unit="deg/s^3",
                       low=0, high=1000000)),
                group="5-axis"),
    CommandSpec("CmdLutMoveXyz", "Move to X/Y/Z (LUT IK)",
                "The integer lookup-table IK (0.01 mm in, 0.01 deg out), then the move.",
                (Field("x", "X", "Arg1", default=150.0, unit="mm"),
                 Field("y", "Y", "Arg2", default=0.0, unit="mm"),
                 Field("z", "Z", "Arg3", default=120.0, unit="mm"),
                 Field("elbow", "Elbow", "Int1", "choice", 0, choices=_ELBOW)),
                group="Move"),
)


def _number(spec: CommandSpec, f: Field, raw: object) -> float:
    what = f"{spec.label}: {f.label}"
    if isinstance(raw, bool) or raw is None:
        raise BadInput(f"{what} must be a number, got {raw!r}")
    if isinstance(raw, int | float):
        value = float(raw)
    elif isinstance(raw, str):
        text = raw.strip()
        if not text:
            raise BadInput(f"{what} is empty: enter a number")
        try:
            value = float(text)
        except ValueError:
            raise BadInput(f"{what} must be a number, got {raw!r}") from None
    else:
        raise BadInput(f"{what} must be a number, got {type(raw).__name__}")
    if not math.isfinite(value):
        raise BadInput(f"{what} must be a finite number, got {raw!r}")
    return value


def _integer(spec: CommandSpec, f: Field, raw: object) -> int:
    value = _number(spec, f, raw)
    if value != int(value):
        raise BadInput(f"{spec.label}: {f.label} must be a whole number, got {raw!r}")
    low = DINT_MIN if f.low is None else f.low
    high = DINT_MAX if f.high is None else f.high
    if not low <= value <= high:
        raise BadInput(f"{spec.label}: {f.label} must be {low:g}..{high:g}, got {raw!r}")
    return int(value)


def parse_points(spec: CommandSpec, f: Field, raw: object,
                 limit: int) -> tuple[tuple[float, float, float], ...]:
    """'x y z' per line (commas or blanks between the numbers); blank lines are skipped."""
    if not isinstance(raw, str):
        raise BadInput(f"{spec.label}: {f.label} must be text, one 'x y z' per line")
    points = []
    for n, line in enumerate(raw.splitlines(), start=1):
        parts = line.replace(",", " ").split()
        if not parts:
            continue
        if len(parts) != 3:
            raise BadInput(f"{spec.label}: line {n} needs 3 numbers (x y z), got {line!r}")
        try:
            xyz = tuple(float(p) for p in parts)
        except ValueError:
            raise BadInput(f"{spec.label}: line {n} must be 3 numbers, got {line!r}") from None
        if not all(math.isfinite(v) and abs(v) <= REAL_LIMIT for v in xyz):
            raise BadInput(f"{spec.label}: line {n} must be 3 finite numbers of at most "
                           f"{REAL_LIMIT:g}, got {line!r}")
        points.append((xyz[0], xyz[1], xyz[2]))
    if not 1 <= len(points) <= limit:
        raise BadInput(f"{spec.label}: give 1..{limit} points, got {len(points)}")
    return tuple(points)


@dataclass
class CommandTable:
    """The commands the loaded controller declares, with their codes."""

    specs: tuple[CommandSpec, ...] = COMMANDS
    constants: Mapping[str, int] = field(default_factory=controller_constants)
    batch_max: int = 32

    def available(self) -> list[CommandSpec]:
        return [s for s in self.specs if s.constant in self.constants]

    def find(self, constant: str) -> CommandSpec:
        for s in self.available():
            if s.constant == constant:
                return s
        raise BadInput(f"unknown command {constant!r}; the controller offers "
                       + ", ".join(s.constant for s in self.available()))

    def describe(self) -> list[dict[str, object]]:
        """The table as JSON for the page (it builds its forms from it)."""
        return [{"name": s.constant, "code": self.constants[s.constant], "label": s.label,
                 "help": s.help, "batch": s.batch, "group": s.group,
                 "fields": [{"key": f.key, "label": f.label, "slot": f.slot, "kind": f.kind,
                             "default": f.default, "unit": f.unit,
                             "choices": [list(c) for c in f.choices]} for f in s.fields]}
                for s in self.available()]

    def prepare(self, constant: object, values: object) -> Prepared:
        """Check the page's values; raises :class:`BadInput` with the reason."""
        if not isinstance(constant, str):
            raise BadInput(f"command name must be text, got {constant!r}")
        spec = self.find(constant)
        if not isinstance(values, Mapping):
            raise BadInput(f"{spec.label}: the fields must be an object of name: value")
        unknown = sorted(set(values) - {f.key for f in spec.fields})
        if unknown:
            raise BadInput(f"{spec.label}: unknown field(s) {', '.join(map(str, unknown))}")
        slots: dict[str, float] = {}
        points: tuple[tuple[float, float, float], ...] = ()
        for f in spec.fields:
            raw = values.get(f.key, f.default)
            if f.kind == "points":
                points = parse_points(spec, f, raw, self.batch_max)
            elif f.kind == "choice":
                choice = _integer(spec, f, raw)
                if choice not in [c[0] for c in f.choices]:
                    raise BadInput(f"{spec.label}: {f.label} must be one of "
                                   + ", ".join(f"{v} ({t})" for v, t in f.choices)
                                   + f", got {raw!r}")
                slots[f.slot] = choice
            elif f.kind == "int":
                slots[f.slot] = _integer(spec, f, raw)
            else:
                value = _number(spec, f, raw)
                if abs(value) > REAL_LIMIT:
                    raise BadInput(f"{spec.label}: {f.label} must be within "
                                   f"+-{REAL_LIMIT:g}, got {raw!r}")
                slots[f.slot] = value
        ints = (int(slots.get("Int1", 0)), int(slots.get("Int2", 0)))
        n_args = max((i for i in range(1, 7) if f"Arg{i}" in slots), default=0)
        args = tuple(slots.get(f"Arg{i}", 0.0) for i in range(1, n_args + 1))
        return Prepared(spec, self.constants[spec.constant], ints, args, points)


@dataclass(frozen=True)
class Outcome:
    """What a command gave: its result code, the status after it, batch results if any."""

    result: int
    status: Status | None
    batch: Sequence[BatchPoint] = ()


def run(client: ArmControllerClient, p: Prepared) -> Outcome:
    """Send a prepared command through the mailbox handshake and wait for its answer."""
    if p.spec.batch:
        try:
            points = client.solve_batch(list(p.points), elbow_down=bool(p.ints[0]))
        except CommandRejected as exc:
            return Outcome(exc.error_id, None)
        return Outcome(0, None, points)
    st = client.command(p.code, ints=p.ints, args=p.args)
    return Outcome(st.error_id, st)
