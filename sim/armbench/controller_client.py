"""Client side of ``plc_project/Controller.st``: the request/acknowledge handshake over Modbus,
with every address taken from the register map derived from the program
(:mod:`armbench.registermap`), so the client cannot drift from the ST.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from .registermap import Register, controller_map
from .softplc import modbus_map as mm
from .softplc.modbus_client import PlcClient

CMD_MOVE_XYZ = 1
CMD_MOVE_JOINTS = 2
CMD_INIT_PWM = 3
CMD_RELAX = 4

ERR_OK = 0
ERR_UNREACHABLE = 1
ERR_SINGULAR = 2
ERR_NOT_FINITE = 3
ERR_UNKNOWN_COMMAND = 100
ERR_JOINT_LIMIT = 101

STATE_READY = 0
STATE_BUSY = 1

# Command block fields, in register order (all %MD, so one FC16 request covers them).
_COMMAND_FIELDS = ("CmdSeq", "CmdCode", "CmdX", "CmdY", "CmdZ", "CmdBaseDeg",
                   "CmdShoulderDeg", "CmdElbowDeg", "CmdElbowDown")
_STATUS_FIELDS = ("AckSeq", "CtlState", "ErrorId", "ScanCount", "BaseDeg", "ShoulderDeg",
                  "ElbowDeg", "EchoX", "EchoY", "EchoZ", "BasePulseUs", "ShoulderPulseUs",
                  "ElbowPulseUs", "PwmPrescale", "PwmReady", "InitFrames")


class HandshakeTimeout(Exception):
    """The PLC did not acknowledge a command in time."""


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


def _encode(reg: Register, value: float) -> tuple[int, int]:
    t = reg.st_type.upper()
    if t == "REAL":
        return mm.real_to_words(value)
    if t == "DINT":
        return mm.dint_to_words(int(value))
    if t == "UDINT":
        return mm.udint_to_words(int(value))
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


def _span(names: tuple[str, ...]) -> tuple[list[Register], int, int]:
    cmap = controller_map()
    regs = [cmap[n.upper()] for n in names]
    first = regs[0].address
    end = max(r.address + r.count for r in regs)
    if any(r.table != "holding" for r in regs):
        raise ValueError("command and status blocks must be holding registers")
    return regs, first, end - first


class ArmControllerClient:
    """Commands for the controller over an open :class:`PlcClient`."""

    def __init__(self, plc: PlcClient, timeout_s: float = 5.0) -> None:
        self.plc = plc
        self.timeout_s = timeout_s
        self._cmd_regs, self._cmd_addr, self._cmd_len = _span(_COMMAND_FIELDS)
        self._st_regs, self._st_addr, self._st_len = _span(_STATUS_FIELDS)
        cmap = controller_map()
        self._channel_regs = [cmap[f"CH{n:02d}OFF"] for n in range(16)]
        self._init_regs = [(cmap[f"INITREG{n}"], cmap[f"INITDATA{n}"]) for n in range(1, 6)]
        self.polls = 0  # status reads spent waiting for acknowledges

    def _read_fields(self, regs: list[Register], addr: int, length: int) -> dict[str, float]:
        words = self.plc.read_holding_registers(addr, length)
        return {r.name: _decode(r, words[r.address - addr: r.address - addr + r.count])
                for r in regs}

    def status(self) -> Status:
        f = self._read_fields(self._st_regs, self._st_addr, self._st_len)
        return Status(
            ack_seq=int(f["AckSeq"]), state=int(f["CtlState"]), error_id=int(f["ErrorId"]),
            scan_count=int(f["ScanCount"]),
            joints_deg=(f["BaseDeg"], f["ShoulderDeg"], f["ElbowDeg"]),
            echo_mm=(f["EchoX"], f["EchoY"], f["EchoZ"]),
            pulses_us=(f["BasePulseUs"], f["ShoulderPulseUs"], f["ElbowPulseUs"]),
            prescale=int(f["PwmPrescale"]), pwm_ready=bool(f["PwmReady"]),
            init_frames=int(f["InitFrames"]),
        )

    def channel_words(self) -> list[int]:
        """The 16 LEDn_OFF words (one request: they are contiguous)."""
        first = self._channel_regs[0].address
        return self.plc.read_holding_registers(first, 16)

    def init_frames(self) -> list[tuple[int, int]]:
        """(register, data) of the published PCA9685 init frames 1..5."""
        first = self._init_regs[0][0].address
        words = self.plc.read_holding_registers(first, 10)
        return [(words[2 * i], words[2 * i + 1]) for i in range(5)]

    def command(self, code: int, *, xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
                joints: tuple[float, float, float] = (0.0, 0.0, 0.0),
                elbow_down: bool = False) -> Status:
        """Issue one command with one FC16 write and wait for its acknowledge; returns the
        status read that saw it."""
        ack = self.status().ack_seq
        seq = ack + 1 if ack < 2**31 - 1 else 1
        values = dict(zip(_COMMAND_FIELDS, (seq, code, *xyz, *joints, int(elbow_down)),
                          strict=True))
        words = [0] * self._cmd_len
        for r in self._cmd_regs:
            w = _encode(r, values[r.name])
            words[r.address - self._cmd_addr: r.address - self._cmd_addr + r.count] = w
        self.plc.write_registers(self._cmd_addr, words)
        deadline = time.monotonic() + self.timeout_s
        while True:
            st = self.status()
            self.polls += 1
            if st.ack_seq == seq:
                return st
            if time.monotonic() > deadline:
                raise HandshakeTimeout(f"command {code} seq {seq} not acknowledged "
                                       f"(AckSeq {st.ack_seq}, state {st.state})")

    def move_xyz(self, x: float, y: float, z: float, elbow_down: bool = False) -> Status:
        return self.command(CMD_MOVE_XYZ, xyz=(x, y, z), elbow_down=elbow_down)

    def move_joints(self, base: float, shoulder: float, elbow: float) -> Status:
        return self.command(CMD_MOVE_JOINTS, joints=(base, shoulder, elbow))

    def init_pwm(self) -> Status:
        return self.command(CMD_INIT_PWM)
