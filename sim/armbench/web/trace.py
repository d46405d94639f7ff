"""The trace: chosen variables sampled as fast as the PLC answers, each sample timestamped.

Like CODESYS Trace or TwinCAT Scope, but over Modbus, so it works with any PLC the view
reaches: a thread with its own connection reads the chosen variables back to back (one
request per contiguous stretch, usually one), at most one round every ``min_period_s``, and
keeps the newest ``keep`` samples in a ring. Each sample's time is the midpoint of its
request and answer (wall clock, seconds since the epoch): the PLC's values of one scan, read
between the two. A PLC scans at its own pace and Modbus cannot ask it for a scan's values,
so samples faster than the scan repeat values, and a scan shorter than the round trip is
missed: the page shows the sample rate reached next to the scan rate.

One trace per view, shared by its pages (one PLC, one configuration, as on a real device);
choosing other variables starts a new one (``config`` counts them). Nobody fetching samples
for ``idle_s`` pauses the sampling, so a forgotten page does not keep a real PLC busy; the
next fetch resumes it (the time axis shows the gap).
"""

from __future__ import annotations

import csv
import io
import math
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from ..registermap import Register
from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient
from .variables import ProgramVariables, ReadPlan, decode

MAX_VARIABLES = 16
SAMPLES_PER_ANSWER = 5000


class BadTrace(ValueError):
    """A trace configuration the view cannot sample; the message says why."""


@dataclass(frozen=True)
class _Config:
    number: int
    registers: tuple[Register, ...]
    plan: ReadPlan


def _number(value: bool | float | int) -> float | int | None:
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class Trace:
    """Samples the chosen variables on its own thread; see the module docstring."""

    def __init__(self, host: str, port: int, program: ProgramVariables, *,
                 min_period_s: float = 0.001, keep: int = 100_000,
                 idle_s: float = 60.0) -> None:
        if not (math.isfinite(min_period_s) and 0.0 <= min_period_s <= 10.0):
            raise ValueError(f"the trace period must be 0..10000 ms, got {min_period_s * 1e3}")
        self.host, self.port = host, port
        self.program = program
        self.min_period_s = min_period_s
        self.idle_s = idle_s
        self.keep = keep
        # (seq, time, values...), seq contiguous: a list trimmed in chunks, so that a page's
        # "since" is an index, not a scan of the ring
        self._samples: list[tuple[Any, ...]] = []
        self._seq = 0
        self._config = _Config(0, (), ReadPlan(()))
        self._cond = threading.Condition()
        self._stop = False
        self._thread: threading.Thread | None = None
        self._last_fetch = time.monotonic()
        self._times: deque[float] = deque(maxlen=2000)
        self._read_s: deque[float] = deque(maxlen=200)
        self.error: str | None = None

    # -- configuration --------------------------------------------------------------------

    def configure(self, names: object) -> dict[str, Any]:
        """Trace these variables from now on (an empty list stops sampling)."""
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise BadTrace("the trace takes a list of variable names, e.g. "
                           "{\"variables\": [\"Scans\", \"Wave\"]}")
        if len(names) > MAX_VARIABLES:
            raise BadTrace(f"a trace takes at most {MAX_VARIABLES} variables, got "
                           f"{len(names)}")
        regs: list[Register] = []
        for name in names:
            try:
                reg = self.program.find(name)
            except KeyError:
                hint = next((u for u in self.program.unreachable
                             if u.name.upper() == name.upper()), None)
                raise BadTrace(f"{name} is not a located variable of {self.program.name}"
                               + (f": {hint.reason}" if hint else "")) from None
            if reg not in regs:
                regs.append(reg)
        with self._cond:
            self._config = _Config(self._config.number + 1, tuple(regs), ReadPlan(regs))
            self._samples.clear()
            self._times.clear()
            self._read_s.clear()
            self._last_fetch = time.monotonic()
            self._cond.notify_all()
        return self.describe()

    def describe(self) -> dict[str, Any]:
        c = self._config
        return {"config": c.number, "requests": len(c.plan.requests),
                "min_period_ms": self.min_period_s * 1e3,
                "variables": [{"name": r.name, "type": r.st_type, "location": r.location}
                              for r in c.registers]}

    # -- reading --------------------------------------------------------------------------

    def samples(self, since: int = 0, config: int | None = None) -> dict[str, Any]:
        """Samples after sequence number ``since`` (at most :data:`SAMPLES_PER_ANSWER`):
        rows of [seq, time s, value...]; ``lost`` counts those already dropped from the ring;
        ``idle`` says the sampling was paused for want of fetches (this one resumes it). A
        ``config`` other than the current one starts from the beginning."""
        with self._cond:
            idle = self._idle()  # was: this fetch resumes it
            self._last_fetch = time.monotonic()
            self._cond.notify_all()
            c = self._config
            if config is not None and config != c.number:
                since = 0
            first = self._samples[0][0] if self._samples else self._seq + 1
            start = max(0, since - first + 1)
            rows = self._samples[start:start + SAMPLES_PER_ANSWER]
            lost = max(0, first - since - 1) if since and self._samples else 0
            more = start + len(rows) < len(self._samples)
            return {**self.describe(), "samples": rows, "lost": lost, "more": more,
                    "rate_hz": self._rate(), "read_ms": self._read_ms(),
                    "error": self.error, "idle": idle}

    def csv(self) -> str:
        """The ring as CSV: time since the first sample (s), wall-clock time, one column per
        variable (BOOL as 0/1)."""
        with self._cond:
            c = self._config
            rows = list(self._samples)
        out = io.StringIO()
        w = csv.writer(out, lineterminator="\n")
        w.writerow(["time_s", "unix_time_s", *(r.name for r in c.registers)])
        t0 = rows[0][1] if rows else 0.0
        for row in rows:
            w.writerow([f"{row[1] - t0:.6f}", f"{row[1]:.6f}",
                        *("nan" if v is None else v for v in row[2:])])
        return out.getvalue()

    # -- the sampling thread --------------------------------------------------------------

    def start(self) -> None:
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="armbench-web-trace",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None

    def _idle(self) -> bool:
        return time.monotonic() - self._last_fetch > self.idle_s

    def _run(self) -> None:
        plc = PlcClient(self.host, self.port, timeout_s=1.0)
        connected = False
        next_t = time.monotonic()
        try:
            while True:
                with self._cond:
                    while not self._stop and (not self._config.registers or self._idle()):
                        self._cond.wait(0.5)
                    if self._stop:
                        return
                    c = self._config
                try:
                    if not connected:
                        plc.connect()
                        connected = True
                    t0 = time.time()
                    image = c.plan.read(plc)
                    t1 = time.time()
                except (ModbusIoError, ModbusError, OSError) as exc:
                    self.error = f"no answer from {self.host}:{self.port}: {exc}"
                    connected = False
                    plc.close()
                    with self._cond:
                        self._cond.wait(0.5)
                    continue
                self.error = None
                values = tuple(_number(decode(r, image)) for r in c.registers)
                with self._cond:
                    if c is self._config:  # not reconfigured while reading
                        self._seq += 1
                        self._samples.append((self._seq, (t0 + t1) / 2.0, *values))
                        if len(self._samples) > self.keep + self.keep // 4:
                            del self._samples[:len(self._samples) - self.keep]
                        self._times.append(time.monotonic())
                        self._read_s.append(t1 - t0)
                next_t = max(next_t + self.min_period_s, time.monotonic())
                delay = next_t - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
        finally:
            plc.close()

    def _rate(self) -> float | None:
        recent = [t for t in self._times if t >= self._times[-1] - 1.0] if self._times else []
        if len(recent) < 2 or recent[-1] <= recent[0]:
            return None
        return (len(recent) - 1) / (recent[-1] - recent[0])

    def _read_ms(self) -> float | None:
        if not self._read_s:
            return None
        return 1e3 * sum(self._read_s) / len(self._read_s)


def parse_since(raw: str | None, what: str) -> int:
    """A non-negative integer from a query parameter; BadTrace otherwise."""
    if raw is None or raw == "":
        return 0
    try:
        value = int(raw)
    except ValueError:
        raise BadTrace(f"{what} must be a whole number, got {raw!r}") from None
    if value < 0:
        raise BadTrace(f"{what} must be >= 0, got {value}")
    return value
