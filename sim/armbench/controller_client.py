"""Client side of ``plc_project/Controller.st``: the request/acknowledge handshake over Modbus,
with every address taken from the register map derived from the program
(:mod:`armbench.registermap`), so the client cannot drift from the ST.

A command is one FC16 write of the command block (``CmdSeq`` last-but-not-least: the PLC acts
only when ``CmdSeq`` changes), then polls of ``AckSeq`` with a short sleep between them (a busy
loop of Modbus reads steals the CPU, and in-process the GIL, from the PLC's scan thread).
``SolveBatch`` targets are written before the command block, so a client that dies half-way
leaves the PLC untouched; its results are read back after the acknowledge.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import astuple, dataclass

from .registermap import Register, controller_constants, controller_map
from .softplc import modbus_map as mm
from .softplc.modbus_client import PlcClient

# Command codes, result codes and states come from Controller.st's constants (one source).
_K = controller_constants()
CMD_MOVE_XYZ = _K["CmdMoveXyz"]
CMD_MOVE_JOINTS = _K["CmdMoveJoints"]
CMD_INIT_PWM = _K["CmdInitPwm"]
CMD_RELAX = _K["CmdRelax"]
CMD_SET_CALIBRATION = _K["CmdSetCalibration"]
CMD_SOLVE_BATCH = _K["CmdSolveBatch"]

ERR_OK = _K["Err.NoError"]
ERR_UNREACHABLE = _K["Err.Unreachable"]
ERR_SINGULAR = _K["Err.Singular"]
ERR_NOT_FINITE = _K["Err.NotFinite"]
ERR_BAD_CALIBRATION = _K["Err.BadCalibration"]
ERR_UNKNOWN_COMMAND = _K["CtlErr.UnknownCommand"]
ERR_JOINT_LIMIT = _K["CtlErr.JointLimit"]
ERR_BAD_JOINT = _K["CtlErr.BadJoint"]
ERR_BAD_COUNT = _K["CtlErr.BadCount"]

STATE_READY = _K["StateReady"]
STATE_BUSY = _K["StateBusy"]

JOINTS = ("Base", "Shoulder", "Elbow")  # CmdJoint 0, 1, 2 = PCA9685 channels 0, 1, 2

# FC16 carries at most 123 registers and FC03 returns at most 125 (Modbus spec §6.12/§6.3).
_MAX_WRITE_REGS = 123
_MAX_READ_REGS = 125

# Command block fields, in register order (all %MD, so one FC16 request covers them).
_COMMAND_FIELDS = ("CmdSeq", "CmdCode", "CmdX", "CmdY", "CmdZ", "CmdBaseDeg",
                   "CmdShoulderDeg", "CmdElbowDeg", "CmdElbowDown", "CmdCount", "CmdJoint",
                   "CmdCalZeroDeg", "CmdCalDirection", "CmdCalMinPulseUs", "CmdCalMaxPulseUs",
                   "CmdCalMinAngleDeg", "CmdCalMaxAngleDeg")
_STATUS_FIELDS = ("AckSeq", "CtlState", "ErrorId", "ScanCount", "BaseDeg", "ShoulderDeg",
                  "ElbowDeg", "EchoX", "EchoY", "EchoZ", "BasePulseUs", "ShoulderPulseUs",
                  "ElbowPulseUs", "PwmPrescale", "PwmReady", "InitFrames", "BatchCount",
                  "BatchFailures")
_CAL_SUFFIXES = ("ZeroDeg", "Direction", "MinPulseUs", "MaxPulseUs", "MinAngleDeg",
                 "MaxAngleDeg")
_RESULT_PREFIXES = ("ResBase", "ResShoulder", "ResElbow", "ResX", "ResY", "ResZ", "ResErrorId")


class HandshakeTimeout(Exception):
    """The PLC did not acknowledge a command in time."""


class CommandRejected(Exception):
    """A command the caller needed came back with a non-zero ErrorId."""

    def __init__(self, what: str, error_id: int) -> None:
        super().__init__(f"{what}: ErrorId {error_id}")
        self.error_id = error_id


@dataclass(frozen=True)
class Status:
    ack_seq: int
    state: int
    error_id: int
    scan_count: int
    joints_deg: tuple[float, float, float]
    echo_mm: tuple[float, float, float]
    pulses_us: tuple[float, float, float]
    prescale: int
    pwm_ready: bool
    init_frames: int
    batch_count: int
    batch_failures: int


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


def _encode(reg: Register, value: float) -> list[int]:
    t = reg.st_type.upper()
    if t == "REAL":
        return list(mm.real_to_words(value))
    if t == "DINT":
        return list(mm.dint_to_words(int(value)))
    if t == "UDINT":
        return list(mm.udint_to_words(int(value)))
    raise TypeError(f"{reg.name}: no encoder for {reg.st_type}")


def _decode(reg: Register, words: list[int]) -> float:
    t = reg.st_type.upper()
    if t == "REAL":
        return mm.words_to_real(words)
    if t == "DINT":
        return mm.words_to_dint(words)
    if t == "UDINT":
        return mm.words_to_udint(words)
    raise TypeError(f"{reg.name}: no decoder for {reg.st_type}")


@dataclass(frozen=True)
class _Block:
    """Registers that are read or written together: contiguous holding registers."""

    regs: tuple[Register, ...]
    address: int
    length: int

    @classmethod
    def of(cls, names: Iterable[str]) -> _Block:
        cmap = controller_map()
        regs = tuple(cmap[n.upper()] for n in names)
        if any(r.table != "holding" for r in regs):
            raise ValueError("command, status and batch blocks must be holding registers")
        first = min(r.address for r in regs)
        return cls(regs, first, max(r.address + r.count for r in regs) - first)

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


class ArmControllerClient:
    """Commands for the controller over an open :class:`PlcClient`.

    ``poll_interval_s`` is the sleep between two AckSeq polls (0 = busy loop).
    """

    def __init__(self, plc: PlcClient, timeout_s: float = 5.0,
                 poll_interval_s: float = 0.0005) -> None:
        self.plc = plc
        self.timeout_s = timeout_s
        self.poll_interval_s = poll_interval_s
        self._cmd = _Block.of(_COMMAND_FIELDS)
        self._status = _Block.of(_STATUS_FIELDS)
        self._ack = _Block.of(("AckSeq",))
        self._cal = _Block.of(f"{j}Cal{s}" for j in JOINTS for s in _CAL_SUFFIXES)
        self.batch_max = _batch_size()
        self._targets = _Block.of(f"Batch{a}{k:02d}" for k in range(1, self.batch_max + 1)
                                  for a in "XYZ")
        self._results = _Block.of(f"{p}{k:02d}" for k in range(1, self.batch_max + 1)
                                  for p in _RESULT_PREFIXES)
        cmap = controller_map()
        self._channel_regs = [cmap[f"CH{n:02d}OFF"] for n in range(16)]
        self._init_regs = [(cmap[f"INITREG{n}"], cmap[f"INITDATA{n}"]) for n in range(1, 6)]
        self.polls = 0  # AckSeq reads spent waiting for acknowledges

    # -- raw block access --------------------------------------------------------------------

    def _read(self, address: int, length: int) -> list[int]:
        words: list[int] = []
        while len(words) < length:
            n = min(_MAX_READ_REGS - 1, length - len(words))  # even: never split a 32-bit value
            words += self.plc.read_holding_registers(address + len(words), n)
        return words

    def _write(self, address: int, words: list[int]) -> None:
        done = 0
        while done < len(words):
            n = min(_MAX_WRITE_REGS - 1, len(words) - done)
            self.plc.write_registers(address + done, words[done: done + n])
            done += n

    # -- status ------------------------------------------------------------------------------

    def status(self) -> Status:
        f = dict(zip(_STATUS_FIELDS, self._status.decode(
            self._read(self._status.address, self._status.length)), strict=True))
        return Status(
            ack_seq=int(f["AckSeq"]), state=int(f["CtlState"]), error_id=int(f["ErrorId"]),
            scan_count=int(f["ScanCount"]),
            joints_deg=(f["BaseDeg"], f["ShoulderDeg"], f["ElbowDeg"]),
            echo_mm=(f["EchoX"], f["EchoY"], f["EchoZ"]),
            pulses_us=(f["BasePulseUs"], f["ShoulderPulseUs"], f["ElbowPulseUs"]),
            prescale=int(f["PwmPrescale"]), pwm_ready=bool(f["PwmReady"]),
            init_frames=int(f["InitFrames"]), batch_count=int(f["BatchCount"]),
            batch_failures=int(f["BatchFailures"]),
        )

    def ack_seq(self) -> int:
        return int(self._ack.decode(self.plc.read_holding_registers(self._ack.address, 2))[0])

    def channel_words(self) -> list[int]:
        """The 16 LEDn_OFF words (one request: they are contiguous)."""
        first = self._channel_regs[0].address
        return self.plc.read_holding_registers(first, 16)

    def init_frames(self) -> list[tuple[int, int]]:
        """(register, data) of the published PCA9685 init frames 1..5."""
        first = self._init_regs[0][0].address
        words = self.plc.read_holding_registers(first, 10)
        return [(words[2 * i], words[2 * i + 1]) for i in range(5)]

    def calibration(self) -> tuple[Calibration, Calibration, Calibration]:
        """The three joints' calibration as the PLC uses it (the read-back block)."""
        v = self._cal.decode(self._read(self._cal.address, self._cal.length))
        n = len(_CAL_SUFFIXES)
        cals = [Calibration(v[i], int(v[i + 1]), *v[i + 2: i + n]) for i in range(0, 3 * n, n)]
        return cals[0], cals[1], cals[2]

    # -- the handshake -----------------------------------------------------------------------

    def submit(self, code: int, *, xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
               joints: tuple[float, float, float] = (0.0, 0.0, 0.0), elbow_down: bool = False,
               count: int = 0, joint: int = 0, cal: Calibration | None = None) -> int:
        """Write the command block with one FC16 request; returns its CmdSeq (not waited)."""
        ack = self.ack_seq()
        seq = ack + 1 if ack < 2**31 - 1 else 1
        address, words = self.command_words(seq, code, xyz=xyz, joints=joints,
                                            elbow_down=elbow_down, count=count, joint=joint,
                                            cal=cal)
        self.plc.write_registers(address, words)
        return seq

    def command_words(self, seq: int, code: int, *,
                      xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
                      joints: tuple[float, float, float] = (0.0, 0.0, 0.0),
                      elbow_down: bool = False, count: int = 0, joint: int = 0,
                      cal: Calibration | None = None) -> tuple[int, list[int]]:
        """(first holding register, words) of a command block: what :meth:`submit` writes."""
        c = cal if cal is not None else Calibration()
        values = (seq, code, *xyz, *joints, int(elbow_down), count, joint, *astuple(c))
        words = self._cmd.encode(values)
        assert len(words) <= _MAX_WRITE_REGS
        return self._cmd.address, words

    def wait_ack(self, seq: int) -> Status:
        """Poll AckSeq (small reads, ``poll_interval_s`` apart) until it equals ``seq``; returns
        the full status read after it."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            self.polls += 1
            if self.ack_seq() == seq:
                return self.status()
            if time.monotonic() > deadline:
                st = self.status()
                raise HandshakeTimeout(f"seq {seq} not acknowledged "
                                       f"(AckSeq {st.ack_seq}, state {st.state})")
            if self.poll_interval_s > 0.0:
                time.sleep(self.poll_interval_s)

    def command(self, code: int, *, xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
                joints: tuple[float, float, float] = (0.0, 0.0, 0.0),
                elbow_down: bool = False, count: int = 0, joint: int = 0,
                cal: Calibration | None = None) -> Status:
        """Issue one command and wait for its acknowledge; returns the status after it."""
        seq = self.submit(code, xyz=xyz, joints=joints, elbow_down=elbow_down, count=count,
                          joint=joint, cal=cal)
        return self.wait_ack(seq)

    def move_xyz(self, x: float, y: float, z: float, elbow_down: bool = False) -> Status:
        return self.command(CMD_MOVE_XYZ, xyz=(x, y, z), elbow_down=elbow_down)

    def move_joints(self, base: float, shoulder: float, elbow: float) -> Status:
        return self.command(CMD_MOVE_JOINTS, joints=(base, shoulder, elbow))

    def init_pwm(self) -> Status:
        return self.command(CMD_INIT_PWM)

    def set_calibration(self, joint: int, cal: Calibration) -> Status:
        """SetCalibration of joint 0 Base, 1 Shoulder, 2 Elbow; check ``error_id``."""
        return self.command(CMD_SET_CALIBRATION, joint=joint, cal=cal)

    # -- SolveBatch --------------------------------------------------------------------------

    def submit_batch(self, points: Sequence[tuple[float, float, float]],
                     elbow_down: bool = False) -> int:
        """Write up to ``batch_max`` targets, then the command block; returns the CmdSeq."""
        n = len(points)
        if not 1 <= n <= self.batch_max:
            raise ValueError(f"a batch holds 1..{self.batch_max} points, got {n}")
        values = [c for p in points for c in p]
        words = self._targets.encode(values + [0.0] * (3 * self.batch_max - len(values)))
        self._write(self._targets.address, words[: 6 * n])  # 3 REALs = 6 words per point
        return self.submit(CMD_SOLVE_BATCH, count=n, elbow_down=elbow_down)

    def batch_results(self, n: int) -> list[BatchPoint]:
        """The first ``n`` SolveBatch results (read after the acknowledge)."""
        per = len(_RESULT_PREFIXES)
        words = self._read(self._results.address, 2 * per * n)
        v = self._results.decode(words + [0] * (self._results.length - len(words)))
        return [BatchPoint((v[i], v[i + 1], v[i + 2]), (v[i + 3], v[i + 4], v[i + 5]),
                           int(v[i + 6])) for i in range(0, per * n, per)]

    def solve_batch(self, points: Sequence[tuple[float, float, float]],
                    elbow_down: bool = False) -> list[BatchPoint]:
        """One SolveBatch of up to ``batch_max`` points: write, acknowledge, read back."""
        st = self.wait_ack(self.submit_batch(points, elbow_down))
        if st.error_id != ERR_OK:
            raise CommandRejected("SolveBatch", st.error_id)
        return self.batch_results(len(points))

    def batch_roundtrip(self, points: Sequence[tuple[float, float, float]],
                        elbow_down: bool = False) -> list[BatchPoint]:
        """Any number of points, in SolveBatch chunks of ``batch_max``."""
        out: list[BatchPoint] = []
        for i in range(0, len(points), self.batch_max):
            out += self.solve_batch(points[i: i + self.batch_max], elbow_down)
        return out
