"""The controller on an in-process soft PLC whose scans the caller makes, one at a time, with
no Modbus in between: a test writes whole mailbox command blocks (or single words) straight
into the process image, calls :meth:`SteppedController.step`, and reads the registers the
scan wrote. Blocks written to several mailboxes before one step land in the SAME scan, which
a client over Modbus can only hope for.

The check word of a block is computed here, independently of the client library, by a
formula the caller picks (:data:`CHECK_FORMULAS`): ``crc`` is the protocol's word (zlib's
CRC-32 of the eleven fields as 44 big-endian bytes); ``weighted`` (weights 1, 3, ..., 21) and
``sum`` (the five DINTs) are the earlier words, kept so that a defect can be shown on a
controller that still expects one of them (``ARMBENCH_CTL_CHECK=weighted`` or ``sum``).

Monitors (:class:`OutputMonitor`, :class:`StopMonitor`, :class:`AnswerMonitor`) run after
every scan and check the promises of the output stage, of Stop and of the mailbox answers;
each violation carries the scan number, the channel, the value against its limit and the
commands written for that scan, so a failing test says what happened where.
"""

from __future__ import annotations

import math
import os
import struct
import zlib
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np

# the answer record only: the harness computes check words and decodes registers itself
from armbench.controller_client import Answer
from armbench.registermap import SOURCES, Register, controller_map
from armbench.softplc.image import MD_OFFSET, ML_OFFSET
from armbench.softplc.loader import LoadedProgram, load_program
from armbench.softplc.scan import SoftPlc

TASK_NS: Final = 10_000_000
DT: Final = 0.01  # s, the controller's task interval
MAILBOXES: Final = 16
DRIVER_FAULT_BIT: Final = 1  # PwmDriverFault, %IX0.1: the image's discrete inputs, a byte a bit

# Command codes of the protocol (Controller.st header, COMMANDS).
MOVE_XYZ, MOVE_JOINTS, INIT_PWM, RELAX, SET_CALIBRATION = 1, 2, 3, 4, 5
SOLVE_BATCH, RESERVE_BATCH, RELEASE_BATCH, CLOSE, HELLO = 6, 7, 8, 9, 10
MOVE_JOINTS_PROFILE, MOVE_LINEAR, JOG_START, JOG_UPDATE, JOG_STOP = 11, 12, 13, 14, 15
STOP, SET_MOTION_LIMITS = 16, 17
LUT_SOLVE, LUT_MOVE_XYZ, LUT_SOLVE_BATCH = 20, 21, 22
MOVE_TOOL_ANGLES, MOVE_TOOL_VECTOR, JOG_WRIST, SET_GRIPPER = 30, 31, 32, 33
FOLLOW_IMU = 46
# Result codes.
OK, BAD_PARAMETER, JOINT_LIMIT, BUSY, BAD_CHECK = 0, 8, 101, 104, 106
# Commands that start a motion of the arm when answered 0 (FollowImu only with Int1 bit 0).
MOTION_STARTS: Final = frozenset({MOVE_XYZ, MOVE_JOINTS, MOVE_JOINTS_PROFILE, MOVE_LINEAR,
                                  JOG_START, LUT_MOVE_XYZ, MOVE_TOOL_ANGLES, MOVE_TOOL_VECTOR,
                                  JOG_WRIST})

CHANNELS: Final = ("Base", "Shoulder", "Elbow", "WristPitch", "WristRoll", "Gripper")
ARM_CHANNELS: Final = 5  # channels 0..4 are the motion group's; 5 is the gripper
FIELDS: Final = ("SEQ", "SESSION", "CODE", "INT1", "INT2",
                 "ARG1", "ARG2", "ARG3", "ARG4", "ARG5", "ARG6", "CHECK")

_CANONICAL_NAN: Final = 0x7FC00000
_U32: Final = 0xFFFFFFFF


@dataclass(frozen=True)
class Bits:
    """A REAL argument given as its raw IEEE-754 single-precision bit pattern (any NaN
    payload, -0.0, ...), written to the image as is."""

    pattern: int


Arg = float | Bits


def real_bits(value: Arg) -> int:
    """The bit pattern a REAL argument is stored with. A float beyond the float32 range
    becomes the infinity of its sign, as a client's float32 conversion does."""
    if isinstance(value, Bits):
        return value.pattern & _U32
    if math.isfinite(value) and abs(value) > 3.4028234663852886e38:
        value = math.copysign(math.inf, value)
    return int(struct.unpack("<I", struct.pack("<f", value))[0])


def bits_real(pattern: int) -> float:
    return float(struct.unpack("<f", struct.pack("<I", pattern & _U32))[0])


def _check_pattern(pattern: int) -> int:
    """A REAL's pattern as the check word counts it: every NaN as the canonical quiet NaN,
    -0.0 as +0.0."""
    pattern &= _U32
    if (pattern & 0x7F800000) == 0x7F800000 and (pattern & 0x007FFFFF) != 0:
        return _CANONICAL_NAN
    if pattern == 0x80000000:
        return 0
    return pattern


def check_crc(ints: Sequence[int], args: Sequence[int]) -> int:
    """The protocol's check word: zlib's CRC-32 of v1..v11 = Seq, Session, Code, Int1, Int2
    (two's complement) and the six REAL patterns (NaN canonical, -0.0 as 0), each as four
    bytes, most significant first."""
    values = [v & _U32 for v in ints] + [_check_pattern(a) for a in args]
    assert len(values) == 11
    return zlib.crc32(struct.pack(">11I", *values))


def check_weighted(ints: Sequence[int], args: Sequence[int]) -> int:
    """The earlier check word (fooled by a word-level torn write): v1..v11 = Seq, Session,
    Code, Int1, Int2 (two's complement) and the six REAL patterns (NaN canonical, -0.0 as
    0); sum of (2k - 1) * v_k mod 2^32."""
    values = [v & _U32 for v in ints] + [_check_pattern(a) for a in args]
    assert len(values) == 11
    return sum((2 * k + 1) * v for k, v in enumerate(values)) & _U32


def check_sum(ints: Sequence[int], args: Sequence[int]) -> int:
    """The old check word: Seq + Session + Code + Int1 + Int2 mod 2^32 (arguments not
    covered)."""
    del args
    return sum(v & _U32 for v in ints) & _U32


CheckFormula = Callable[[Sequence[int], Sequence[int]], int]
CHECK_FORMULAS: Final[dict[str, CheckFormula]] = {"crc": check_crc, "weighted": check_weighted,
                                                   "sum": check_sum}


def check_formula_from_env() -> CheckFormula:
    """The formula named by ARMBENCH_CTL_CHECK (default: the protocol's, crc)."""
    name = os.environ.get("ARMBENCH_CTL_CHECK", "crc")
    if name not in CHECK_FORMULAS:
        raise ValueError(f"ARMBENCH_CTL_CHECK={name!r}: one of {sorted(CHECK_FORMULAS)}")
    return CHECK_FORMULAS[name]


@dataclass(frozen=True)
class Block:
    """One command block as written into a mailbox."""

    mailbox: int
    session: int
    seq: int
    code: int
    int1: int
    int2: int
    args: tuple[int, ...]  # six REAL bit patterns
    check: int
    scan: int  # the scan that first sees it (SteppedController.scan + 1 when written)

    def describe(self) -> str:
        args = ", ".join(f"{bits_real(a):.6g}" for a in self.args)
        return (f"mbx{self.mailbox:02d} session {self.session} seq {self.seq} code {self.code} "
                f"int1 {self.int1} int2 {self.int2} args ({args}) check {self.check:#010x}")


@dataclass(frozen=True)
class Answered:
    """A block the controller answered in a scan."""

    block: Block
    result: int
    scan: int


ScanObserver = Callable[["SteppedController"], None]


def load_controller() -> LoadedProgram:
    """Compile (cached) and load the library + controller once; :meth:`SteppedController.
    reset` brings it back to power-up."""
    return load_program(list(SOURCES))


@dataclass
class SteppedController:
    """The controller program, scanned by the caller. Scan numbers count from 1 (the first
    step); ``scan`` is the number of scans made so far."""

    program: LoadedProgram
    check_formula: CheckFormula = check_crc
    plc: SoftPlc = field(init=False)
    now_ns: int = 0
    scan: int = 0
    regs: dict[str, Register] = field(default_factory=controller_map)
    observers: list[ScanObserver] = field(default_factory=list)
    # what was written for the coming scan (whole blocks, and single words as text)
    pending: list[Block] = field(default_factory=list)
    pending_words: list[str] = field(default_factory=list)
    # of the scan just made: what had been written for it, and what it answered
    last_written: list[Block] = field(default_factory=list)
    last_words: list[str] = field(default_factory=list)
    answered: list[Answered] = field(default_factory=list)
    # every whole block ever written, per mailbox: (session, seq, check)
    written: dict[int, set[tuple[int, int, int]]] = field(default_factory=dict)
    _awaiting: dict[int, Block] = field(default_factory=dict)
    # the last few scans that had commands: (scan, text), for failure messages
    history: deque[tuple[int, str]] = field(default_factory=lambda: deque(maxlen=3))
    _md_u: memoryview = field(init=False)
    _md_i: memoryview = field(init=False)
    _md_f: memoryview = field(init=False)
    _pulse_idx: tuple[int, ...] = field(init=False)
    _slots: dict[str, tuple[int, str]] = field(init=False)

    def __post_init__(self) -> None:
        # name -> (%MD index, ST type), parsed once: the monitors read dozens per scan
        self._slots = {name: (r.index, r.st_type.upper()) for name, r in self.regs.items()
                       if r.location.startswith("%MD")}
        self._pulse_idx = tuple(self.index(f"{c}PULSEUS") for c in CHANNELS)
        raw = self.program.image.raw[MD_OFFSET:ML_OFFSET]
        self._md_u = raw.cast("I")
        self._md_i = raw.cast("i")
        self._md_f = raw.cast("f")
        self.reset()

    # -- power-up ----------------------------------------------------------------------------
    def reset(self) -> None:
        """Power-up: a zeroed image, the program's variables at their initial values, a new
        scheduler, no scans made."""
        self.program.image.clear()
        self.program.module.config_init()
        self.plc = SoftPlc(self.program)
        self.plc.run()
        self.now_ns = 0
        self.scan = 0
        self.observers.clear()
        self.pending, self.pending_words = [], []
        self.last_written, self.last_words, self.answered = [], [], []
        self.written = {}
        self._awaiting = {}
        self.history.clear()

    # -- registers -----------------------------------------------------------------------------
    def index(self, name: str) -> int:
        return self._slots[name.upper()][0]

    def read(self, name: str) -> float | int:
        """A %MD register decoded by its ST type (REAL, DINT, UDINT)."""
        try:
            idx, kind = self._slots[name.upper()]
        except KeyError:
            raise KeyError(f"{name} is not a %MD register of the controller") from None
        if kind == "REAL":
            return float(self._md_f[idx])
        if kind == "DINT":
            return int(self._md_i[idx])
        return int(self._md_u[idx])

    def pulses(self) -> tuple[float, ...]:
        return tuple(float(self._md_f[i]) for i in self._pulse_idx)

    def answer(self, mailbox: int) -> Answer:
        p = f"MBX{mailbox:02d}"
        return Answer(int(self.read(p + "OWNER")), int(self.read(p + "ACKSEQ")),
                      int(self.read(p + "RESULT")), int(self.read(p + "ACKCHECK")))

    def md_float32(self) -> np.ndarray:
        """The %MD area as float32, a copy (for vectorised checks)."""
        return np.frombuffer(self._md_f.tobytes(), dtype=np.float32)

    # -- writing -------------------------------------------------------------------------------
    def block(self, mailbox: int, session: int, seq: int, code: int, int1: int = 0,
              int2: int = 0, args: Iterable[Arg] = (), check: int | None = None) -> Block:
        """A block (not written) with its check word by this controller's formula unless
        given."""
        patterns = [real_bits(a) for a in args]
        if len(patterns) > 6:
            raise ValueError("at most six REAL arguments")
        patterns += [0] * (6 - len(patterns))
        ints = (seq, session, code, int1, int2)
        word = self.check_formula(ints, patterns) if check is None else check & _U32
        return Block(mailbox, session, seq, code, int1, int2, tuple(patterns), word,
                     self.scan + 1)

    def write_block(self, mailbox: int, session: int, seq: int, code: int, int1: int = 0,
                    int2: int = 0, args: Iterable[Arg] = (), check: int | None = None) -> Block:
        """Write a whole command block (one function-16 request) into a mailbox."""
        blk = self.block(mailbox, session, seq, code, int1, int2, args, check)
        self.put(blk)
        return blk

    def put(self, blk: Block) -> None:
        base = self.index(f"MBX{blk.mailbox:02d}SEQ")
        words = [blk.seq, blk.session, blk.code, blk.int1, blk.int2, *blk.args, blk.check]
        for i, w in enumerate(words):
            self._md_u[base + i] = w & _U32
        self.pending.append(blk)
        self.written.setdefault(blk.mailbox, set()).add((blk.session, blk.seq, blk.check))
        self._awaiting[blk.mailbox] = blk

    def write_word(self, mailbox: int, name: str, value: int | Arg) -> None:
        """Write ONE field of a mailbox block (a function-6 style partial write): name is one
        of FIELDS; REAL fields take a float or Bits, the others an int."""
        name = name.upper()
        idx = self.index(f"MBX{mailbox:02d}{name}")
        if name.startswith("ARG"):
            assert not isinstance(value, int)
            pattern = real_bits(value)
        else:
            assert isinstance(value, int)
            pattern = value & _U32
        self._md_u[idx] = pattern
        self.pending_words.append(f"mbx{mailbox:02d}.{name} := {value}")

    def write_raw(self, name: str, pattern: int) -> None:
        """Write any %MD register's 32 bits (a client writing a located output)."""
        self._md_u[self.index(name)] = pattern & _U32

    # -- scanning ------------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Make n scans; after each, collect the answers and run the observers."""
        for _ in range(n):
            ran = self.plc.step(self.now_ns)
            if not ran:
                raise RuntimeError(f"scan {self.scan + 1} did not run: PLC {self.plc.state}, "
                                   f"fault {self.plc.fault}")
            self.now_ns += TASK_NS
            self.scan += 1
            self.last_written, self.pending = self.pending, []
            self.last_words, self.pending_words = self.pending_words, []
            self._collect_answers()
            if self.last_written or self.last_words or self.answered:
                self.history.append((self.scan, self._describe_scan()))
            for obs in list(self.observers):
                obs(self)

    def _collect_answers(self) -> None:
        self.answered = []
        for mbx in sorted(self._awaiting):
            blk = self._awaiting[mbx]
            a = self.answer(mbx)
            if (a.owner, a.ack_seq, a.ack_check) == (blk.session, blk.seq, blk.check):
                self.answered.append(Answered(blk, a.result, self.scan))
                del self._awaiting[mbx]

    def result_of(self, blk: Block) -> int | None:
        """The result of blk when the last scan answered it, else None."""
        for a in self.answered:
            if a.block is blk:
                return a.result
        return None

    def _describe_scan(self) -> str:
        lines = [b.describe() for b in self.last_written] + self.last_words
        answers = [f"answered mbx{a.block.mailbox:02d} seq {a.block.seq}: {a.result}"
                   for a in self.answered]
        return "; ".join(lines + answers)

    def scan_commands(self) -> str:
        """The commands of the last few scans that had any, newest first (what was written,
        what was answered), for failure messages."""
        if not self.history:
            return "no commands"
        return " | ".join(f"[scan {k}] {text}" for k, text in reversed(self.history))


@dataclass
class Client:
    """One client in one mailbox: numbers its blocks and reads their answers."""

    ctl: SteppedController
    mailbox: int
    session: int
    seq: int = 0
    last: Block | None = None

    def next_seq(self) -> int:
        self.seq = 1 if self.seq >= 2147483647 else self.seq + 1
        return self.seq

    def send(self, code: int, int1: int = 0, int2: int = 0, args: Iterable[Arg] = (),
             check: int | None = None) -> Block:
        """Write the next block (the scan has not run)."""
        self.last = self.ctl.write_block(self.mailbox, self.session, self.next_seq(), code,
                                         int1, int2, args, check)
        return self.last

    def result(self) -> int | None:
        """The answer to the last block if the mailbox shows it, else None."""
        if self.last is None:
            return None
        a = self.ctl.answer(self.mailbox)
        if (a.owner, a.ack_seq, a.ack_check) == (self.session, self.last.seq, self.last.check):
            return a.result
        return None

    def command(self, code: int, int1: int = 0, int2: int = 0, args: Iterable[Arg] = (),
                scans: int = 1) -> int:
        """Send, make the scans, return the result; AssertionError when unanswered."""
        blk = self.send(code, int1, int2, args)
        self.ctl.step(scans)
        r = self.result()
        assert r is not None, (f"scan {self.ctl.scan}: no answer to {blk.describe()}: "
                               f"{self.ctl.answer(self.mailbox)}")
        return r


# ------------------------------------------------------------------------------------------
# Monitors
# ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Violation:
    scan: int
    channel: str
    kind: str
    value: float
    limit: float
    commands: str
    outside: bool = False  # a range violation: value lies beyond the limit (an end)

    @property
    def ratio(self) -> float:
        if self.outside or self.limit == 0.0 or not math.isfinite(self.value):
            return math.inf
        return abs(self.value) / self.limit

    def __str__(self) -> str:
        if self.outside or self.limit == 0.0:
            figure = f"{self.value:.6g} (limit {self.limit:.6g})"
        else:
            figure = f"{self.value:.6g} vs limit {self.limit:.6g} ({self.ratio:.3g}x)"
        return f"scan {self.scan}, {self.channel}: {self.kind} {figure}; commands: {self.commands}"


def _tol(limit: float, magnitude: float = 0.0) -> float:
    """1e-3 us absolute plus 1e-5 relative: what float32 arithmetic near 2000 us needs."""
    return 1e-3 + 1e-5 * max(abs(limit), abs(magnitude))


def _finite_output_indices(regs: dict[str, Register]) -> tuple[np.ndarray, list[str]]:
    """%MD indices of every located REAL the program writes (not the mailbox blocks, not the
    batch targets, which clients write)."""
    names = [name for name, r in regs.items()
             if r.st_type.upper() == "REAL" and r.location.startswith("%MD")
             and not name.startswith("MBX")
             and not (name[:6] in ("BATCHX", "BATCHY", "BATCHZ") and name[6:].isdigit())]
    return np.array([regs[n].index for n in names], dtype=np.intp), names


@dataclass
class ChannelFigures:
    worst_step_ratio: float = 0.0
    worst_change_ratio: float = 0.0


@dataclass
class OutputMonitor:
    """Promise A, every scan: per channel the step |P_k - P_(k-1)| <= Vus*dt, the step change
    <= Aus*dt^2 (steps of off or just powered scans count as 0), a re-powered channel starts
    from its last emitted pulse (at power-up: the servo centre), P is 0 or inside the
    calibration's pulse range, and no REAL output register is NaN/Inf. In a scan that read
    PwmDriverFault (%IX0.1) TRUE a powered pulse does not move at all (the stage freezes:
    the one place where the step may change by more than Aus*dt^2, to 0)."""

    violations: list[Violation] = field(default_factory=list)
    figures: list[ChannelFigures] = field(
        default_factory=lambda: [ChannelFigures() for _ in CHANNELS])
    scans: int = 0
    prev: list[float] | None = None
    steps: list[float] = field(default_factory=lambda: [0.0] * len(CHANNELS))
    held: list[float | None] = field(default_factory=lambda: [None] * len(CHANNELS))
    max_violations: int = 200
    _finite_idx: np.ndarray | None = None
    _finite_names: list[str] = field(default_factory=list)

    def limits(self, ctl: SteppedController, c: int) -> tuple[float, float, float, float]:
        """(step limit us, step change limit us, min pulse, max pulse) of channel c now."""
        name = CHANNELS[c].upper()
        lo, hi = ctl.read(f"{name}CALMINPULSEUS"), ctl.read(f"{name}CALMAXPULSEUS")
        a0, a1 = ctl.read(f"{name}CALMINANGLEDEG"), ctl.read(f"{name}CALMAXANGLEDEG")
        g = (hi - lo) / (a1 - a0) if a1 != a0 else math.nan
        vel, acc = ctl.read(f"LIM{name}VEL"), ctl.read(f"LIM{name}ACC")
        return vel * g * DT, acc * g * DT * DT, float(lo), float(hi)

    def travel(self, ctl: SteppedController, c: int) -> tuple[float, float]:
        """The joint-angle range of channel c's calibration, deg (ordered)."""
        name = CHANNELS[c].upper()
        zero, sign = ctl.read(f"{name}CALZERODEG"), ctl.read(f"{name}CALDIRECTION")
        a0, a1 = ctl.read(f"{name}CALMINANGLEDEG"), ctl.read(f"{name}CALMAXANGLEDEG")
        ends = (zero + sign * a0, zero + sign * a1)
        return float(min(ends)), float(max(ends))

    def centre(self, ctl: SteppedController, c: int) -> float:
        name = CHANNELS[c].upper()
        lo, hi = ctl.read(f"{name}CALMINPULSEUS"), ctl.read(f"{name}CALMAXPULSEUS")
        a0, a1 = ctl.read(f"{name}CALMINANGLEDEG"), ctl.read(f"{name}CALMAXANGLEDEG")
        return float(lo + (0.0 - a0) * (hi - lo) / (a1 - a0))

    def _add(self, v: Violation) -> None:
        if len(self.violations) < self.max_violations:
            self.violations.append(v)

    def __call__(self, ctl: SteppedController) -> None:
        self.scans += 1
        pulses = list(ctl.pulses())
        if self.prev is None:
            self.prev = [0.0] * len(CHANNELS)
            self.held = [self.centre(ctl, c) for c in range(len(CHANNELS))]
        cmds: str | None = None
        frozen = bool(ctl.program.image.ix[DRIVER_FAULT_BIT])

        def commands() -> str:
            nonlocal cmds
            if cmds is None:
                cmds = ctl.scan_commands()
            return cmds

        for c, p in enumerate(pulses):
            vstep, achange, lo, hi = self.limits(ctl, c)
            name = CHANNELS[c]
            prev = self.prev[c]
            if not math.isfinite(p):
                self._add(Violation(ctl.scan, name, "pulse not finite:", p, hi, commands(),
                                    outside=True))
                self.steps[c] = 0.0
                continue
            if p != 0.0 and not (lo - _tol(hi) <= p <= hi + _tol(hi)):
                self._add(Violation(ctl.scan, name, f"pulse outside [{lo:g}, {hi:g}] us:",
                                    p, hi if p > hi else lo, commands(), outside=True))
            if p == 0.0:
                step = 0.0
                if prev != 0.0:
                    self.held[c] = prev
            elif prev == 0.0:
                # powered again: it starts at rest from the pulse it held, so its first step
                # is measured from there (and the next step change from that step)
                ref = self.held[c]
                step = 0.0 if ref is None else p - ref
                fig = self.figures[c]
                if achange > 0.0:
                    fig.worst_change_ratio = max(fig.worst_change_ratio, abs(step) / achange)
                if abs(step) > achange + _tol(achange, p):
                    self._add(Violation(ctl.scan, name,
                                        f"powered at {p:.6g} us, last pulse {ref:.6g} us: "
                                        "jump", step, achange, commands()))
            else:
                step = p - prev
                change = step - self.steps[c]
                fig = self.figures[c]
                if vstep > 0.0:
                    fig.worst_step_ratio = max(fig.worst_step_ratio, abs(step) / vstep)
                if achange > 0.0:
                    fig.worst_change_ratio = max(fig.worst_change_ratio, abs(change) / achange)
                if abs(step) > vstep + _tol(vstep, p):
                    self._add(Violation(ctl.scan, name, f"step {prev:.6g} -> {p:.6g} us",
                                        step, vstep, commands()))
                if frozen and step != 0.0:
                    self._add(Violation(ctl.scan, name, f"moved under PwmDriverFault {prev:.6g}"
                                        f" -> {p:.6g} us", step, 0.0, commands()))
                elif abs(change) > achange + _tol(achange, p) and not frozen:
                    self._add(Violation(ctl.scan, name,
                                        f"step change {self.steps[c]:.6g} -> {step:.6g} us",
                                        change, achange, commands()))
            self.steps[c] = step
        self.prev = pulses
        for c, name in enumerate(CHANNELS):
            lo_deg, hi_deg = self.travel(ctl, c)
            out = float(ctl.read(f"OUT{name.upper()}DEG"))
            slack = 1e-3 + 1e-5 * max(abs(lo_deg), abs(hi_deg))
            if not (lo_deg - slack <= out <= hi_deg + slack):
                self._add(Violation(ctl.scan, name,
                                    f"joint angle outside its travel [{lo_deg:g}, {hi_deg:g}] "
                                    "deg:", out, hi_deg if out > hi_deg else lo_deg, commands(),
                                    outside=True))
        if self._finite_idx is None:
            self._finite_idx, self._finite_names = _finite_output_indices(ctl.regs)
        values = ctl.md_float32()[self._finite_idx]
        bad = np.flatnonzero(~np.isfinite(values))
        for i in bad[:5]:
            self._add(Violation(ctl.scan, self._finite_names[int(i)], "register not finite:",
                                float(values[i]), 0.0, commands(), outside=True))

    def report(self) -> str:
        lines = [f"scans checked {self.scans}"]
        for c, f in enumerate(self.figures):
            lines.append(f"  {CHANNELS[c]:<10} worst |step|/limit {f.worst_step_ratio:.4f}  "
                         f"worst |step change|/limit {f.worst_change_ratio:.4f}")
        return "\n".join(lines)

    def failure(self, limit: int = 5) -> str:
        """The first violations and the worst one, for an assertion message."""
        if not self.violations:
            return "no violation"
        worst = max(self.violations, key=lambda v: v.ratio)
        head = "\n".join(str(v) for v in self.violations[:limit])
        return f"{len(self.violations)} violation(s); first:\n{head}\nworst:\n{worst}"


@dataclass
class _Braking:
    scan: int  # scan the Stop was answered in
    bounds: tuple[int, ...]  # per arm channel, scans
    last_moving: list[int]


# Stop always brakes: a refused deceleration is answered BadParameter and brakes all the same
STOP_ANSWERS = (OK, BAD_PARAMETER)


@dataclass
class StopMonitor:
    """Promise B: after a Stop (answered 0, or 8 for a refused deceleration that brakes all
    the same) and no later accepted motion start in a later scan
    or a later mailbox of the same scan) every arm channel's step is 0 from scan
    Stop + ceil(Vel / (min(Acc, 100) * dt)) + 5 on. Uses the OutputMonitor's steps."""

    output: OutputMonitor
    violations: list[Violation] = field(default_factory=list)
    braking: _Braking | None = None
    stops: int = 0
    worst: list[tuple[int, int]] = field(default_factory=lambda: [(0, 1)] * ARM_CHANNELS)

    def _finish(self) -> None:
        b = self.braking
        if b is None:
            return
        for c in range(ARM_CHANNELS):
            took = b.last_moving[c] - b.scan + 1 if b.last_moving[c] >= b.scan else 0
            w_took, w_bound = self.worst[c]
            if took / b.bounds[c] > w_took / w_bound:
                self.worst[c] = (took, b.bounds[c])
        self.braking = None

    def __call__(self, ctl: SteppedController) -> None:
        for a in sorted(ctl.answered, key=lambda a: a.block.mailbox):
            code = a.block.code
            starts = (code in MOTION_STARTS
                      or (code == FOLLOW_IMU and (a.block.int1 & 1) == 1))
            if a.result == OK and starts:
                self._finish()
            elif (a.result in STOP_ANSWERS and code == STOP and self.braking is None):
                self.stops += 1
                bounds = []
                for c in range(ARM_CHANNELS):
                    name = CHANNELS[c].upper()
                    vel = float(ctl.read(f"LIM{name}VEL"))
                    acc = float(ctl.read(f"LIM{name}ACC"))
                    bounds.append(math.ceil(vel / (min(acc, 100.0) * DT)) + 5
                                  if math.isfinite(vel) and acc > 0.0 else 10**9)
                self.braking = _Braking(ctl.scan, tuple(bounds), [ctl.scan - 1] * ARM_CHANNELS)
        b = self.braking
        if b is None:
            return
        for c in range(ARM_CHANNELS):
            step = self.output.steps[c]
            if step != 0.0:
                b.last_moving[c] = ctl.scan
                if ctl.scan - b.scan >= b.bounds[c] and len(self.violations) < 200:
                    self.violations.append(Violation(
                        ctl.scan, CHANNELS[c],
                        f"still moving {ctl.scan - b.scan} scans after the Stop of scan "
                        f"{b.scan} (bound {b.bounds[c]} scans): step", step, 0.0,
                        ctl.scan_commands()))

    def report(self) -> str:
        self_worst = list(self.worst)
        if self.braking is not None:  # a braking still open counts with what it took so far
            b = self.braking
            for c in range(ARM_CHANNELS):
                took = b.last_moving[c] - b.scan + 1 if b.last_moving[c] >= b.scan else 0
                if took / b.bounds[c] > self_worst[c][0] / self_worst[c][1]:
                    self_worst[c] = (took, b.bounds[c])
        parts = [f"{CHANNELS[c]} {t}/{bd}" for c, (t, bd) in enumerate(self_worst)]
        return f"accepted Stops {self.stops}; worst Stop-to-rest scans vs bound: " + \
            ", ".join(parts)


@dataclass
class AnswerMonitor:
    """No answer to the wrong client: whenever a mailbox's answer changes and names an owner,
    (Owner, AckSeq, AckCheck) is a block that owner wrote into that mailbox (a 106 BadCheck
    answer carries the Check as read, which a half-written block may have torn: its
    (Owner, AckSeq) must be the owner's)."""

    violations: list[str] = field(default_factory=list)
    prev: dict[int, Answer] = field(default_factory=dict)
    answers: int = 0

    def __call__(self, ctl: SteppedController) -> None:
        for mbx in range(1, MAILBOXES + 1):
            a = ctl.answer(mbx)
            if self.prev.get(mbx) == a:
                continue
            self.prev[mbx] = a
            if a.owner == 0:
                continue
            self.answers += 1
            written = ctl.written.get(mbx, set())
            if a.result == BAD_CHECK:
                # a block read half-written is refused with the Check the PLC read: the
                # owner's (Session, Seq) is all it must name
                ok = any((s, q) == (a.owner, a.ack_seq) for s, q, _ in written)
            else:
                ok = (a.owner, a.ack_seq, a.ack_check) in written
            if not ok and len(self.violations) < 200:
                self.violations.append(
                    f"scan {ctl.scan}, mbx{mbx:02d}: answer owner {a.owner} ack seq "
                    f"{a.ack_seq} ack check {a.ack_check:#010x} result {a.result} is no block "
                    f"that session wrote there; commands: {ctl.scan_commands()}")
