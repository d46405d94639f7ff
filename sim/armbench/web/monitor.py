"""What the live view shows, read over Modbus like any client, plus the plant it drives.

A monitor thread polls the PLC at a fixed rate over its own Modbus connection; every poll
becomes one JSON snapshot for the page, and the table of the program's located variables is
refreshed from it. Two kinds:

- :class:`ProgramMonitor`, for any program: the located variables, nothing else assumed.
- :class:`Monitor`, for the arm controller: status, calibration, the 16 mailboxes' command
  and answer blocks, the motion layer, init frames, PWM channel words, the PSM handshake bits;
  every register of the map (less often) for the table. It runs the plant the way
  ``armbench demo`` does, but in real time: the channel words go into the PCA9685 model
  (initialised from the frames the PLC publishes, as the PSM driver would be), its pulse
  widths into three MG996R models stepped by the real time between polls, and the servo
  angles through the servos' mounting (the PLC's calibration read back at start) to the
  achieved joint angles. The arm drawn as the PLC's is its output stage (OutBaseDeg..: the
  angles the channels are sent, whatever motion produced them), with the motion group's
  setpoint (SetBaseDeg..) and, during a Cartesian motion, its Cartesian setpoint; joint points
  and tool points come from the numpy reference kinematics, not from the PLC.

PLC state and task statistics come from the :class:`SoftPlc` when it runs in this process (a
PLC over the network tells neither over Modbus: then the page shows the scan rate derived from
ScanCount, for the controller). Every new mailbox answer with a non-zero result, a PLC fault,
a motion that ends in an error, a PSM fault bit and a lost connection become events.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..controller_client import JOINTS, MAILBOXES, WRIST_JOINTS, Calibration
from ..follow_demo import TOOL_MM, arm_frames
from ..plant import arm
from ..plant.pca9685 import PCA9685, PCA9685Error
from ..plant.servo import MG996R
from ..registermap import controller_constants
from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient
from ..softplc.scan import SoftPlc
from .variables import Image, ProgramVariables, ReadPlan, controller_variables, decode

PCA9685_ADDRESS = 0x40
SERVO_CHANNELS = (0, 1, 2)
_CMD_FIELDS = ("Seq", "Session", "Code", "Int1", "Int2", "Arg1", "Arg2", "Arg3", "Arg4",
               "Arg5", "Arg6", "Check")
_ANS_FIELDS = ("Owner", "AckSeq", "Result", "AckCheck")
_CAL_FIELDS = ("ZeroDeg", "Direction", "MinPulseUs", "MaxPulseUs", "MinAngleDeg",
               "MaxAngleDeg")
_EVENTS_KEPT = 40
_CHANNEL_JOINTS = (*JOINTS, *WRIST_JOINTS, "Gripper")  # PCA9685 channels 0..5


def result_names() -> dict[int, str]:
    """Result code -> name from the controller's constants (Err.*, CtlErr.*)."""
    names: dict[int, str] = {}
    for key, value in controller_constants().items():
        for prefix in ("Err.", "CtlErr."):
            if key.startswith(prefix):
                names.setdefault(value, key[len(prefix):])
    return names


def command_names() -> dict[int, str]:
    """Command code -> name (CmdMoveXyz -> MoveXyz) from the controller's constants."""
    return {v: k[3:] for k, v in controller_constants().items() if k.startswith("Cmd")}


def motion_kinds() -> dict[int, str]:
    """MotionKind value -> name (KindLine -> Line) from the controller's constants."""
    return {v: k[4:] for k, v in controller_constants().items() if k.startswith("Kind")}


def _is_batch_area(name: str) -> bool:
    # the 32 batch targets and results: the register table shows them, the fast poll skips them
    stem = name.upper().rstrip("0123456789")
    return stem != name and (stem.startswith("BATCH") and stem[-1] in "XYZ"
                             or stem.startswith("RES"))


def _finite(x: float) -> float | None:
    # JSON has no NaN: a register a client scribbled over must not break the page
    return x if math.isfinite(x) else None


def _json_value(value: bool | float | int) -> bool | float | int | None:
    return _finite(value) if isinstance(value, float) else value


@dataclass
class LivePlant:
    """PCA9685 + three MG996R models stepped in real time; ``calibration`` is how each
    servo is mounted (joint angle at servo centre, direction)."""

    calibration: Sequence[Calibration]
    pca: PCA9685 = field(default_factory=lambda: PCA9685(address=PCA9685_ADDRESS))
    servos: list[MG996R] = field(default_factory=lambda: [MG996R() for _ in SERVO_CHANNELS])
    initialised: bool = False

    def apply_init_frames(self, frames: Sequence[tuple[int, int]]) -> None:
        for i, (register, data) in enumerate(frames, start=1):
            self.pca.write(PCA9685_ADDRESS, register, bytes((data & 0xFF,)))
            # frame 4 wakes the oscillator: the controller waits >= 1 ms before frame 5
            self.pca.advance(0.001 if i == 4 else 0.0001)
        self.initialised = True

    def step(self, words: Sequence[int], dt_s: float) -> None:
        self.pca.load_off_counts(list(words))
        for ch, servo in zip(SERVO_CHANNELS, self.servos, strict=True):
            pulse = self.pca.pulse_width_us(ch)
            servo.step(dt_s, pulse if pulse > 0.0 else None)

    def joints(self) -> tuple[float, float, float]:
        a = [c.servo_to_joint(s.angle_deg)
             for s, c in zip(self.servos, self.calibration, strict=True)]
        return a[0], a[1], a[2]


@dataclass
class Event:
    id: int
    t: float
    kind: str  # "fault" | "info"
    text: str


class Poller:
    """Polls the PLC at ``rate_hz`` on its own thread; :meth:`snapshot` is the latest state
    (a dict ready for JSON), :meth:`subscribe` calls back with each new one as JSON text, and
    :meth:`registers` is the table of the program's located variables with their values."""

    mode = "program"

    def __init__(self, host: str, port: int, program: ProgramVariables, *,
                 rate_hz: float = 50.0, registers_every_s: float = 0.5,
                 local_plc: SoftPlc | None = None) -> None:
        if not (math.isfinite(rate_hz) and 1.0 <= rate_hz <= 1000.0):
            raise ValueError(f"the update rate must be 1..1000 Hz, got {rate_hz}")
        self.host, self.port = host, port
        self.program = program
        self.rate_hz = rate_hz
        self.period_s = 1.0 / rate_hz
        self.registers_every_s = registers_every_s
        self.local_plc = local_plc
        self._full = ReadPlan(program.registers)
        self._lock = threading.Lock()
        self._subscribers: list[Callable[[str], None]] = []
        self._events: deque[Event] = deque(maxlen=_EVENTS_KEPT)
        self._event_id = 0
        self._snapshot: dict[str, Any] = {"type": "state", "mode": self.mode,
                                          "connected": False, "seq": 0}
        self._registers: list[dict[str, Any]] = []
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._faults_reported: set[str] = set()
        self._poll_hist: deque[float] = deque(maxlen=200)
        self.polls = 0
        self.poll_errors = 0

    # -- public ---------------------------------------------------------------------------

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="armbench-web-monitor",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None

    def subscribe(self, callback: Callable[[str], None]) -> Callable[[], None]:
        """Call ``callback(json_text)`` after every poll; returns the unsubscribe function."""
        with self._lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)
        return unsubscribe

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._snapshot)

    def registers(self) -> list[dict[str, Any]]:
        with self._lock:
            return list(self._registers)

    def event(self, kind: str, text: str) -> None:
        """Add an event for the page (the command path reports its results here)."""
        with self._lock:
            self._event_id += 1
            self._events.append(Event(self._event_id, time.time(), kind, text))

    # -- the poll loop --------------------------------------------------------------------

    def _run(self) -> None:
        plc = PlcClient(self.host, self.port, timeout_s=1.0)
        connected = False
        last_full = -math.inf
        last_t = time.monotonic()
        next_t = last_t
        while not self._stop.is_set():
            now = time.monotonic()
            try:
                if not connected:
                    plc.connect()
                    connected = True
                full = now - last_full >= self.registers_every_s
                self._poll(plc, now - last_t, full)
                if full:
                    last_full = now
            except (ModbusIoError, ModbusError, OSError) as exc:
                self.poll_errors += 1
                if connected:
                    self.event("fault", f"Modbus connection to {self.host}:{self.port} lost: "
                               f"{exc}")
                connected = False
                plc.close()
                with self._lock:
                    self._snapshot = {**self._snapshot, "connected": False,
                                      "error": f"no answer from {self.host}:{self.port}: {exc}"}
                self._publish()
                self._stop.wait(0.5)
            last_t = now
            next_t = max(next_t + self.period_s, time.monotonic())
            self._stop.wait(max(0.0, next_t - time.monotonic()))
        plc.close()

    def _poll(self, plc: PlcClient, dt_s: float, full: bool) -> None:
        raise NotImplementedError

    def _common(self, t_read: float) -> dict[str, Any]:
        """The part of every snapshot that does not depend on the program."""
        self._poll_hist.append(time.monotonic())
        self.polls += 1
        self._plc_fault_event()
        return {"type": "state", "mode": self.mode, "connected": True, "seq": self.polls,
                "t": t_read, "plc_address": f"{self.host}:{self.port}",
                "program": self.program.name, "poll_hz": self._rate(self._poll_hist),
                "plc": self._plc_info()}

    def _commit(self, snap: dict[str, Any], image: Image | None) -> None:
        with self._lock:
            snap["events"] = [e.__dict__ for e in self._events]
            self._snapshot = snap
            if image is not None:
                self._registers = self._register_rows(image)
        self._publish()

    def _publish(self) -> None:
        with self._lock:
            text = json.dumps(self._snapshot, allow_nan=False)
            subscribers = list(self._subscribers)
        for cb in subscribers:
            cb(text)

    def _plc_fault_event(self) -> None:
        if self.local_plc is not None and self.local_plc.fault is not None:
            f = self.local_plc.fault
            key = f"plc:{f}"
            if key not in self._faults_reported:
                self._faults_reported.add(key)
                self.event("fault", f"PLC fault at {f.location}: {f.message}")

    def _plc_info(self) -> dict[str, Any]:
        if self.local_plc is None:
            return {"state": None, "fault": None, "tasks": [],
                    "note": "a PLC over the network reports no state over Modbus"}
        p = self.local_plc
        f = p.fault
        return {
            "state": p.state.name,
            "fault": None if f is None else f"{f.location}: {f.message}",
            "tasks": [{"name": s.name, "interval_ms": s.interval_ns / 1e6, "scans": s.scans,
                       "overruns": s.overruns,
                       "exec_mean_us": s.execution.mean_ns / 1e3,
                       "exec_max_us": s.execution.max_ns / 1e3,
                       "jitter_p50_us": s.jitter.p50_ns / 1e3,
                       "jitter_p99_us": s.jitter.p99_ns / 1e3,
                       "jitter_max_us": s.jitter.max_ns / 1e3}
                      for s in p.stats().values()],
        }

    def _register_rows(self, image: Image) -> list[dict[str, Any]]:
        return [{"name": r.name, "location": r.location, "table": r.table,
                 "address": r.address, "type": r.st_type,
                 "value": _json_value(decode(r, image)),
                 "group": r.group, "description": r.description}
                for r in self.program.registers]

    @staticmethod
    def _rate(times: deque[float]) -> float | None:
        recent = [t for t in times if t >= times[-1] - 1.0] if times else []
        if len(recent) < 2 or recent[-1] <= recent[0]:
            return None
        return (len(recent) - 1) / (recent[-1] - recent[0])


class ProgramMonitor(Poller):
    """Any program: every poll reads all of its located variables (the page's table)."""

    mode = "program"

    def _poll(self, plc: PlcClient, dt_s: float, full: bool) -> None:
        t_read = time.time()
        image = self._full.read(plc)
        snap = self._common(t_read)
        snap["unreachable"] = [u.__dict__ for u in self.program.unreachable]
        self._commit(snap, image)


class Monitor(Poller):
    """The arm controller: the arm, the plant, mailboxes, motion and faults."""

    mode = "controller"

    def __init__(self, host: str, port: int, program: ProgramVariables | None = None, *,
                 rate_hz: float = 50.0, registers_every_s: float = 0.5,
                 local_plc: SoftPlc | None = None) -> None:
        program = program or controller_variables()
        super().__init__(host, port, program, rate_hz=rate_hz,
                         registers_every_s=registers_every_s, local_plc=local_plc)
        self._cmap = {r.name.upper(): r for r in program.registers}
        self._fast = ReadPlan(r for r in program.registers if not _is_batch_area(r.name))
        self._mbx_regs = [[(f, self._cmap[f"MBX{k:02d}{f}".upper()])
                           for f in (*_CMD_FIELDS, *_ANS_FIELDS)]
                          for k in range(1, MAILBOXES + 1)]
        self._results = result_names()
        self._commands = command_names()
        self._kinds = motion_kinds()
        self._plant: LivePlant | None = None
        self._last_answers: list[tuple[int, int, int]] | None = None
        self._last_motion: tuple[int, int, int, int] | None = None
        self._init_seen = False
        self._scan_hist: deque[tuple[float, int]] = deque(maxlen=200)
        self._last_command: dict[str, Any] | None = None
        # why the PLC does not look like the arm controller (None: it does; the commander
        # sends nothing then)
        self.waiting: str | None = "no poll yet"
        # sessions whose results are reported by their sender (the view's own commands)
        self.quiet_sessions: set[int] = set()

    def result_name(self, code: int) -> str:
        return self._results.get(code, f"code {code}")

    def command_done(self, answer: dict[str, Any]) -> None:
        """The page's last command and its answer: the header banner shows it to every page."""
        with self._lock:
            self._last_command = {"t": time.time(), "ok": answer.get("ok", False),
                                  "result": answer.get("result"),
                                  "result_name": answer.get("result_name"),
                                  "message": answer.get("message", "")}

    def _val(self, name: str, image: Image) -> Any:
        return decode(self._cmap[name.upper()], image)

    def _poll(self, plc: PlcClient, dt_s: float, full: bool) -> None:
        t_read = time.time()
        image = (self._full if full else self._fast).read(plc)

        def v(name: str) -> Any:
            return self._val(name, image)

        scan_count = int(v("ScanCount"))
        wrong = self._not_the_controller(scan_count, v)
        with self._lock:
            self.waiting = wrong
        if wrong is not None:
            # Not (yet) the controller's outputs: say so rather than wait without a word, and
            # drive no plant from another program's numbers.
            snap = self._common(t_read)
            snap["waiting"] = wrong
            snap["last_command"] = self._last_command
            self._commit(snap, image if full else None)
            return
        cals = [Calibration(*(v(f"{j}Cal{f}") for f in _CAL_FIELDS)) for j in JOINTS]
        cals = [Calibration(c.zero_offset_deg, int(c.direction), *map(float, (
            c.min_pulse_us, c.max_pulse_us, c.min_angle_deg, c.max_angle_deg))) for c in cals]
        if self._plant is None:
            # how the servos are mounted: the PLC's calibration at start (demo.py does the same)
            self._plant = LivePlant(cals)
        channels = [int(v(f"Ch{n:02d}Off")) for n in range(16)]
        frames = [(int(v(f"InitReg{n}")), int(v(f"InitData{n}"))) for n in range(1, 6)]
        pwm_ready = int(v("PwmReady")) == 1
        bits = {r.name: bool(decode(r, image)) for r in self.program.registers
                if r.table in ("coil", "discrete")}
        init_request = bits.get("PwmInitRequest", False)
        self._step_plant(channels, frames, pwm_ready, init_request, dt_s)
        mailboxes = self._mailboxes(image)
        self._events_from(mailboxes, bits)
        motion = self._motion(v)
        # What the servos are sent, for every kind of motion: the output stage's angles.
        out = tuple(float(v(f"Out{j}Deg")) for j in JOINTS)
        setpoint = tuple(float(v(f"Set{j}Deg")) for j in JOINTS)
        target = tuple(float(v(f"{j}Deg")) for j in JOINTS)
        wrist_out = tuple(float(v(f"Out{j}Deg")) for j in WRIST_JOINTS)
        wrist_set = tuple(float(v(f"Set{j}Deg")) for j in WRIST_JOINTS)
        joints_plant = self._plant.joints()
        self._scan_hist.append((time.monotonic(), scan_count))
        cart_valid = int(v("CartValid")) == 1
        faults = self._faults(motion, bits)
        snap = self._common(t_read)
        snap.update({
            "scan_count": scan_count, "scan_hz": self._scan_rate(),
            "controller": {
                "state": "Busy" if int(v("CtlState")) == 1 else "Ready",
                "busy_mailbox": int(v("BusyMailbox")),
                "commands_answered": int(v("CommandsAnswered")),
                "commands_ignored": int(v("CommandsIgnored")),
                "pwm_ready": pwm_ready, "prescale": int(v("PwmPrescale")),
                "init_frames": int(v("InitFrames")),
                "batch_owner": int(v("BatchOwner")),
                "batch_count": int(v("BatchCount")),
                "batch_failures": int(v("BatchFailures")),
                **{name: value for name, value in bits.items()},
            },
            "motion": motion,
            "faults": faults,
            "last_command": self._last_command,
            "joints": {"plc": [_finite(a) for a in out],
                       "setpoint": [_finite(a) for a in setpoint],
                       "target": [_finite(a) for a in target],
                       "plant": [_finite(a) for a in joints_plant]},
            "wrist": {"output": [_finite(a) for a in wrist_out],
                      "setpoint": [_finite(a) for a in wrist_set],
                      "pulse_us": [_finite(float(v(f"{j}PulseUs"))) for j in WRIST_JOINTS],
                      "gripper_deg": _finite(float(v("OutGripperDeg"))),
                      "gripper_pct": _finite(float(v("GripperOpeningPct"))),
                      "gripper_pulse_us": _finite(float(v("GripperPulseUs")))},
            "points": {"plc": self._points(out), "setpoint": self._points(setpoint),
                       "plant": self._points(joints_plant),
                       "tool": self._tool_points((*out, *wrist_out))},
            "tool": {"output": self._tool(out), "setpoint": self._tool(setpoint),
                     "plant": self._tool(joints_plant),
                     "cartesian": [_finite(float(v(f"Cart{a}"))) for a in "XYZ"]
                     if cart_valid else None,
                     "echo": [_finite(float(v(f"Echo{a}"))) for a in "XYZ"]},
            "channels": self._channels(channels, image),
            "calibration": [{"joint": j, "zero_deg": _finite(c.zero_offset_deg),
                             "direction": c.direction, "min_pulse_us": _finite(c.min_pulse_us),
                             "max_pulse_us": _finite(c.max_pulse_us),
                             "min_angle_deg": _finite(c.min_angle_deg),
                             "max_angle_deg": _finite(c.max_angle_deg)}
                            for j, c in zip(JOINTS, cals, strict=True)],
            "plant": {"pca_running": self._plant.pca.running,
                      "pca_initialised": self._plant.initialised,
                      "update_rate_hz": _finite(self._plant.pca.update_rate_hz),
                      "moving": [s.moving for s in self._plant.servos],
                      "servo_deg": [s.angle_deg for s in self._plant.servos]},
            "mailboxes": mailboxes,
        })
        self._commit(snap, image if full else None)

    def _not_the_controller(self, scan_count: int, v: Callable[[str], Any]) -> str | None:
        """Why the PLC's registers are not (yet) the arm controller's, or None. Modbus names
        no program: the controller always publishes its servo calibration (direction +1 or
        -1, 0 < min pulse < max pulse), which another program's memory hardly repeats."""
        where = f"the PLC at {self.host}:{self.port}"
        if scan_count == 0:
            return (f"ScanCount (%MD0) of {where} is 0: it has not started the arm "
                    "controller's scans, or runs another program (attach with --program "
                    "FILE.st to see that program's variables)")
        for j in JOINTS:
            direction = int(v(f"{j}CalDirection"))
            lo, hi = float(v(f"{j}CalMinPulseUs")), float(v(f"{j}CalMaxPulseUs"))
            reg = self._cmap[f"{j}CalDirection".upper()]
            if direction not in (1, -1) or not 0.0 < lo < hi < 1e4:
                return (f"{where} does not look like the arm controller: {reg.name} "
                        f"({reg.location}) is {direction} and the pulse range {lo:g}..{hi:g} "
                        "us, where the controller publishes +1 or -1 and a range within "
                        "0..10000 us; it runs another program: attach with --program "
                        "FILE.st to see that program's variables")
        return None

    def _motion(self, v: Callable[[str], Any]) -> dict[str, Any]:
        kind = int(v("MotionKind"))
        error_id = int(v("MotionErrorId"))
        starts, error = int(v("MotionStarts")), int(v("MotionError")) == 1
        kind_name = self._kinds.get(kind, "none" if kind == 0 else f"kind {kind}")
        m: dict[str, Any] = {"kind": kind, "kind_name": kind_name,
             "busy": int(v("MotionBusy")) == 1, "done": int(v("MotionDone")) == 1,
             "error": error, "aborted": int(v("MotionAborted")) == 1,
             "error_id": error_id, "error_name": self.result_name(error_id),
             "progress": _finite(float(v("MotionProgress"))),
             "mailbox": int(v("MotionMailbox")), "session": int(v("MotionSession")),
             "seq": int(v("MotionSeq")), "starts": starts,
             "at_limit": int(v("MotionAtLimit")) == 1,
             "slew_limited": int(v("SlewLimited")) == 1,
             "slew_error_id": int(v("SlewErrorId"))}
        key = (starts, kind, int(error), error_id)
        if self._last_motion is not None and key != self._last_motion and error:
            self.event("fault", f"motion {m['kind_name']} (mailbox {m['mailbox']}, seq "
                       f"{m['seq']}) ended in an error: {error_id} {m['error_name']}")
        self._last_motion = key
        return m

    def _faults(self, motion: dict[str, Any], bits: dict[str, bool]) -> list[str]:
        """What is wrong now (the header banner): PLC fault, driver fault, motion error."""
        out = []
        if self.local_plc is not None and self.local_plc.fault is not None:
            f = self.local_plc.fault
            out.append(f"PLC fault at {f.location}: {f.message}")
        if bits.get("PwmDriverFault"):
            out.append("PSM driver reports an I2C fault (PwmDriverFault)")
        if motion["error"]:
            out.append(f"motion {motion['kind_name']} ended in an error: "
                       f"{motion['error_id']} {motion['error_name']}")
        if motion["slew_error_id"]:
            out.append(f"output stage error {motion['slew_error_id']} "
                       f"{self.result_name(motion['slew_error_id'])}")
        return out

    def _step_plant(self, channels: list[int], frames: list[tuple[int, int]],
                    pwm_ready: bool, init_request: bool, dt_s: float) -> None:
        assert self._plant is not None
        # The PSM re-initialises on PwmInitRequest; the frames are complete once PwmReady.
        self._init_seen = self._init_seen or init_request
        try:
            if pwm_ready and not init_request and (self._init_seen
                                                   or not self._plant.initialised):
                self._plant.apply_init_frames(frames)
                self._init_seen = False
            self._plant.step(channels, min(dt_s, 0.5))
        except (PCA9685Error, ValueError) as exc:
            key = f"plant:{exc}"
            if key not in self._faults_reported:
                self._faults_reported.add(key)
                self.event("fault", f"plant: {exc}")

    def _mailboxes(self, image: Image) -> list[dict[str, Any]]:
        out = []
        for k, regs in enumerate(self._mbx_regs, start=1):
            c = {f: decode(r, image) for f, r in regs}
            a = {f: int(c[f]) for f in _ANS_FIELDS}
            code = int(c["Code"])
            session, seq = int(c["Session"]), int(c["Seq"])
            out.append({
                "mailbox": k, "seq": seq, "session": session, "code": code,
                "command": self._commands.get(code, "") if session else "",
                "int1": int(c["Int1"]), "int2": int(c["Int2"]),
                "args": [_finite(float(c[f"Arg{i}"])) for i in range(1, 7)],
                "check": int(c["Check"]),
                "owner": a["Owner"], "ack_seq": a["AckSeq"], "result": a["Result"],
                "result_name": self.result_name(a["Result"]), "ack_check": a["AckCheck"],
                # a block the PLC has not answered yet (it answers within one scan)
                "pending": session != 0 and a["Owner"] == session and seq != a["AckSeq"],
            })
        return out

    def _events_from(self, mailboxes: list[dict[str, Any]], bits: dict[str, bool]) -> None:
        answers = [(m["ack_seq"], m["ack_check"], m["result"]) for m in mailboxes]
        if self._last_answers is not None:
            for m, old, new in zip(mailboxes, self._last_answers, answers, strict=True):
                if new != old and new[2] != 0 and m["session"] not in self.quiet_sessions:
                    who = m["owner"] or "closed"
                    cmd = m["command"] if m["seq"] == m["ack_seq"] else ""
                    self.event("fault", f"mailbox {m['mailbox']} (session {who}): seq "
                               f"{m['ack_seq']} {cmd} rejected: result {new[2]} "
                               f"{self.result_name(new[2])}".replace("  ", " "))
        self._last_answers = answers
        if bits.get("PwmDriverFault") and "psm" not in self._faults_reported:
            self._faults_reported.add("psm")
            self.event("fault", "PSM driver reports an I2C fault (PwmDriverFault)")
        elif not bits.get("PwmDriverFault"):
            self._faults_reported.discard("psm")

    @staticmethod
    def _points(joints: Sequence[float]) -> list[list[float]] | None:
        if not all(math.isfinite(a) for a in joints):
            return None
        return [[float(c) for c in p] for p in arm.joint_points(joints[0], joints[1],
                                                                  joints[2])]

    @staticmethod
    def _tool(joints: Sequence[float]) -> list[float] | None:
        """The reference FK's tool point of three joint angles (the 3-axis arm's tool)."""
        if not all(math.isfinite(a) for a in joints):
            return None
        return [float(c) for c in arm.forward(joints[0], joints[1], joints[2])]

    @staticmethod
    def _tool_points(joints: Sequence[float]) -> list[list[float]] | None:
        """Flange and tool tip of the 5-axis arm (reference closed form, the controller's
        60 mm tool): the wrist's pitch and roll made visible."""
        if not all(math.isfinite(a) for a in joints):
            return None
        x, _, tip = arm_frames(np.array([joints], dtype=np.float64))
        flange = tip[0] - TOOL_MM * x[0]
        return [[float(c) for c in flange], [float(c) for c in tip[0]]]

    def _channels(self, channels: list[int], image: Image) -> list[dict[str, Any]]:
        assert self._plant is not None
        plc_pulses = [float(self._val(f"{j}PulseUs", image)) for j in JOINTS]
        out = []
        for ch, w in enumerate(channels):
            row: dict[str, Any] = {"channel": ch, "word": w, "full_off": bool(w & 0x1000),
                                   "count": w & 0xFFF,
                                   "joint": _CHANNEL_JOINTS[ch] if ch < len(_CHANNEL_JOINTS)
                                   else ""}
            if ch < len(JOINTS):
                row["plc_pulse_us"] = _finite(plc_pulses[ch])
                try:
                    row["plant_pulse_us"] = self._plant.pca.pulse_width_us(ch)
                except PCA9685Error:
                    row["plant_pulse_us"] = None
                row["servo_deg"] = self._plant.servos[ch].angle_deg
            out.append(row)
        return out

    def _scan_rate(self) -> float | None:
        h = self._scan_hist
        if len(h) < 2:
            return None
        t1, s1 = h[-1]
        t0, s0 = next(((t, s) for t, s in h if t >= t1 - 1.0), h[0])
        if t1 <= t0:
            return None
        return ((s1 - s0) & 0xFFFFFFFF) / (t1 - t0)
