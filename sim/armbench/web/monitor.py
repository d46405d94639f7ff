"""What the live view shows, read over Modbus like any client, plus the plant it drives.

A :class:`Monitor` thread polls the controller's registers at a fixed rate over its own Modbus
connection (status, calibration, the 16 mailboxes' command and answer blocks, init frames,
PWM channel words, the PSM handshake bits) and, less often, every register of the map for the
register table. It runs the plant the way ``armbench demo`` does, but in real time: the
channel words go into the PCA9685 model (initialised from the frames the PLC publishes, as
the PSM driver would be), its pulse widths into three MG996R models stepped by the real time
between polls, and the servo angles through the servos' mounting (the PLC's calibration read
back at start) to the achieved joint angles. Joint points for the drawing come from the numpy
reference kinematics for both the PLC's setpoints and the plant's angles.

PLC state and task statistics come from the :class:`SoftPlc` when it runs in this process (a
PLC over the network tells neither over Modbus: then the page shows the scan rate derived from
ScanCount). Every new mailbox answer with a non-zero result, a PLC fault and a PSM fault bit
become events on the page.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..controller_client import JOINTS, MAILBOXES, Calibration
from ..plant import arm
from ..plant.pca9685 import PCA9685, PCA9685Error
from ..plant.servo import MG996R
from ..registermap import Register, controller_constants, controller_map
from ..softplc import modbus_map as mm
from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient
from ..softplc.scan import SoftPlc

PCA9685_ADDRESS = 0x40
SERVO_CHANNELS = (0, 1, 2)
_MAX_READ = 122  # even, below FC03's 125: a 32-bit value is never split
_MERGE_GAP = 16  # read across gaps this small in one request rather than two
_CMD_FIELDS = ("Seq", "Session", "Code", "Int1", "Int2", "Arg1", "Arg2", "Arg3", "Arg4",
               "Arg5", "Arg6", "Check")
_ANS_FIELDS = ("Owner", "AckSeq", "Result", "AckCheck")
_CAL_FIELDS = ("ZeroDeg", "Direction", "MinPulseUs", "MaxPulseUs", "MinAngleDeg",
               "MaxAngleDeg")
_EVENTS_KEPT = 40


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


def _is_batch_area(name: str) -> bool:
    # the 32 batch targets and results: the register table shows them, the fast poll skips them
    stem = name.upper().rstrip("0123456789")
    return stem != name and (stem.startswith("BATCH") and stem[-1] in "XYZ"
                             or stem.startswith("RES"))


def _spans(regs: Iterable[Register]) -> list[tuple[int, int]]:
    """(address, count) requests covering the holding registers, merged across small gaps."""
    ranges = sorted((r.address, r.address + r.count) for r in regs if r.table == "holding")
    merged: list[list[int]] = []
    for lo, hi in ranges:
        if merged and lo - merged[-1][1] <= _MERGE_GAP:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    out = []
    for lo, hi in merged:
        a = lo
        while a < hi:
            n = min(_MAX_READ, hi - a)
            out.append((a, n))
            a += n
    return out


def decode(reg: Register, words: dict[int, int]) -> float | int:
    """A holding register's value from the words read (REAL, DINT, UDINT, WORD, INT...)."""
    w = [words[reg.address + i] for i in range(reg.count)]
    t = reg.st_type.upper()
    if t == "REAL":
        return mm.words_to_real(w)
    if t == "DINT":
        return mm.words_to_dint(w)
    if t == "UDINT":
        return mm.words_to_udint(w)
    if t == "INT":
        return mm.word_to_int(w[0])
    if t == "LREAL":
        return mm.words_to_lreal(w)
    if t == "LINT":
        return mm.words_to_lint(w)
    value = 0
    for x in w:  # WORD, DWORD, UINT, ...: unsigned, most significant word first
        value = (value << 16) | x
    return value


def _finite(x: float) -> float | None:
    # JSON has no NaN: a register a client scribbled over must not break the page
    return x if math.isfinite(x) else None


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


class Monitor:
    """Polls the PLC at ``rate_hz`` on its own thread; :meth:`snapshot` is the latest state
    (a dict ready for JSON), :meth:`subscribe` calls back with each new one as JSON text."""

    def __init__(self, host: str, port: int, *, rate_hz: float = 50.0,
                 registers_every_s: float = 0.5, local_plc: SoftPlc | None = None) -> None:
        if not (math.isfinite(rate_hz) and 1.0 <= rate_hz <= 1000.0):
            raise ValueError(f"the update rate must be 1..1000 Hz, got {rate_hz}")
        self.host, self.port = host, port
        self.period_s = 1.0 / rate_hz
        self.registers_every_s = registers_every_s
        self.local_plc = local_plc
        self._cmap = controller_map()
        self._fast = _spans(r for r in self._cmap.values() if not _is_batch_area(r.name))
        self._full = _spans(self._cmap.values())
        self._coils = [r for r in self._cmap.values() if r.table == "coil"]
        self._discrete = [r for r in self._cmap.values() if r.table == "discrete"]
        self._mbx_regs = [[(f, self._cmap[f"MBX{k:02d}{f}".upper()])
                           for f in (*_CMD_FIELDS, *_ANS_FIELDS)]
                          for k in range(1, MAILBOXES + 1)]
        self._results = result_names()
        self._commands = command_names()
        self._lock = threading.Lock()
        self._subscribers: list[Callable[[str], None]] = []
        self._events: deque[Event] = deque(maxlen=_EVENTS_KEPT)
        self._event_id = 0
        self._snapshot: dict[str, Any] = {"type": "state", "connected": False, "seq": 0}
        self._registers: list[dict[str, Any]] = []
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._plant: LivePlant | None = None
        self._last_answers: list[tuple[int, int, int]] | None = None
        self._init_seen = False
        self._faults_reported: set[str] = set()
        self._scan_hist: deque[tuple[float, int]] = deque(maxlen=200)
        self._poll_hist: deque[float] = deque(maxlen=200)
        self.polls = 0
        self.poll_errors = 0
        # sessions whose results are reported by their sender (the view's own commands)
        self.quiet_sessions: set[int] = set()

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

    def result_name(self, code: int) -> str:
        return self._results.get(code, f"code {code}")

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

    def _read(self, plc: PlcClient, spans: Sequence[tuple[int, int]]) -> dict[int, int]:
        words: dict[int, int] = {}
        for address, count in spans:
            for i, w in enumerate(plc.read_holding_registers(address, count)):
                words[address + i] = w
        return words

    def _val(self, name: str, words: dict[int, int]) -> Any:
        return decode(self._cmap[name.upper()], words)

    def _poll(self, plc: PlcClient, dt_s: float, full: bool) -> None:
        t_read = time.time()
        words = self._read(plc, self._full if full else self._fast)
        bits: dict[str, bool] = {}
        for regs, read in ((self._coils, plc.read_coils),
                           (self._discrete, plc.read_discrete_inputs)):
            if regs:
                first = min(r.address for r in regs)
                values = read(first, max(r.address for r in regs) - first + 1)
                bits.update({r.name: values[r.address - first] for r in regs})
        v = self._val
        scan_count = int(v("ScanCount", words))
        if scan_count == 0:
            return  # the program has not written its outputs yet: nothing to show or mount
        cals = [Calibration(*(v(f"{j}Cal{f}", words) for f in _CAL_FIELDS)) for j in JOINTS]
        cals = [Calibration(c.zero_offset_deg, int(c.direction), *map(float, (
            c.min_pulse_us, c.max_pulse_us, c.min_angle_deg, c.max_angle_deg))) for c in cals]
        if self._plant is None:
            # how the servos are mounted: the PLC's calibration at start (demo.py does the same)
            self._plant = LivePlant(cals)
        channels = [int(v(f"Ch{n:02d}Off", words)) for n in range(16)]
        frames = [(int(v(f"InitReg{n}", words)), int(v(f"InitData{n}", words)))
                  for n in range(1, 6)]
        pwm_ready = int(v("PwmReady", words)) == 1
        init_request = bits.get("PwmInitRequest", False)
        self._step_plant(channels, frames, pwm_ready, init_request, dt_s)
        mailboxes = self._mailboxes(words)
        self._events_from(mailboxes, bits)
        joints_plc = tuple(float(v(f"{j}Deg", words)) for j in JOINTS)
        joints_plant = self._plant.joints()
        self._scan_hist.append((time.monotonic(), scan_count))
        self._poll_hist.append(time.monotonic())
        self.polls += 1
        snap: dict[str, Any] = {
            "type": "state", "connected": True, "seq": self.polls, "t": t_read,
            "plc_address": f"{self.host}:{self.port}",
            "poll_hz": self._rate(self._poll_hist),
            "scan_count": scan_count, "scan_hz": self._scan_rate(),
            "controller": {
                "state": "Busy" if int(v("CtlState", words)) == 1 else "Ready",
                "busy_mailbox": int(v("BusyMailbox", words)),
                "commands_answered": int(v("CommandsAnswered", words)),
                "commands_ignored": int(v("CommandsIgnored", words)),
                "pwm_ready": pwm_ready, "prescale": int(v("PwmPrescale", words)),
                "init_frames": int(v("InitFrames", words)),
                "batch_owner": int(v("BatchOwner", words)),
                "batch_count": int(v("BatchCount", words)),
                "batch_failures": int(v("BatchFailures", words)),
                **{name: value for name, value in bits.items()},
            },
            "plc": self._plc_info(),
            "joints": {"plc": [_finite(a) for a in joints_plc],
                       "plant": [_finite(a) for a in joints_plant]},
            "points": {"plc": self._points(joints_plc), "plant": self._points(joints_plant)},
            "echo": [_finite(float(v(f"Echo{a}", words))) for a in "XYZ"],
            "channels": self._channels(channels, words),
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
        }
        with self._lock:
            snap["events"] = [e.__dict__ for e in self._events]
            self._snapshot = snap
            if full:
                self._registers = self._register_rows(words, bits)
        self._publish()

    def _publish(self) -> None:
        with self._lock:
            text = json.dumps(self._snapshot, allow_nan=False)
            subscribers = list(self._subscribers)
        for cb in subscribers:
            cb(text)

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

    def _mailboxes(self, words: dict[int, int]) -> list[dict[str, Any]]:
        out = []
        for k, regs in enumerate(self._mbx_regs, start=1):
            c = {f: decode(r, words) for f, r in regs}
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

    @staticmethod
    def _points(joints: Sequence[float]) -> list[list[float]] | None:
        if not all(math.isfinite(a) for a in joints):
            return None
        return [[float(c) for c in p] for p in arm.joint_points(joints[0], joints[1],
                                                                  joints[2])]

    def _channels(self, channels: list[int], words: dict[int, int]) -> list[dict[str, Any]]:
        assert self._plant is not None
        plc_pulses = [float(self._val(f"{j}PulseUs", words)) for j in JOINTS]
        out = []
        for ch, w in enumerate(channels):
            row: dict[str, Any] = {"channel": ch, "word": w, "full_off": bool(w & 0x1000),
                                   "count": w & 0xFFF,
                                   "joint": JOINTS[ch] if ch < len(JOINTS) else ""}
            if ch < len(JOINTS):
                row["plc_pulse_us"] = _finite(plc_pulses[ch])
                try:
                    row["plant_pulse_us"] = self._plant.pca.pulse_width_us(ch)
                except PCA9685Error:
                    row["plant_pulse_us"] = None
                row["servo_deg"] = self._plant.servos[ch].angle_deg
            out.append(row)
        return out

    def _register_rows(self, words: dict[int, int],
                       bits: dict[str, bool]) -> list[dict[str, Any]]:
        rows = []
        for r in self._cmap.values():
            if r.table == "holding":
                value: Any = decode(r, words)
                if isinstance(value, float):
                    value = _finite(value)
            else:
                value = bits.get(r.name)
            rows.append({"name": r.name, "location": r.location, "table": r.table,
                         "address": r.address, "type": r.st_type, "value": value,
                         "group": r.group, "description": r.description})
        return rows

    @staticmethod
    def _rate(times: deque[float]) -> float | None:
        recent = [t for t in times if t >= times[-1] - 1.0] if times else []
        if len(recent) < 2 or recent[-1] <= recent[0]:
            return None
        return (len(recent) - 1) / (recent[-1] - recent[0])

    def _scan_rate(self) -> float | None:
        h = self._scan_hist
        if len(h) < 2:
            return None
        t1, s1 = h[-1]
        t0, s0 = next(((t, s) for t, s in h if t >= t1 - 1.0), h[0])
        if t1 <= t0:
            return None
        return ((s1 - s0) & 0xFFFFFFFF) / (t1 - t0)
