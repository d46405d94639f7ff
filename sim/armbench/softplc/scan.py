"""The soft PLC's scan cycle: deterministic task scheduling with :meth:`SoftPlc.step`, fault
state, cycle statistics, and an optional real-time thread that calls ``step`` at absolute
deadlines.

All image access by the program happens under :attr:`SoftPlc.lock`; the Modbus server takes
the same lock per request, so a request never sees (or produces) a half-finished scan.
"""

from __future__ import annotations

import enum
import math
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from .fastpath import ScanLock, new_scan_lock
from .image import ProcessImage
from .program import CompiledProgram, PlcFault, TaskSpec

# Enough samples for a stable p99 (≥40 samples above it) while staying a few hundred KB for a
# whole configuration.
DEFAULT_RESERVOIR = 4096
# Finish the wait with a busy spin: time.sleep() overshoots its deadline (timer slack, wake-up
# from idle; ~120 µs median on the dev VM). Measured there on a 10 ms task, 12 s each: no spin
# p50 119 µs / p99 336 µs; 0.2 ms spin 38 / 280 µs; 0.5 ms spin 1.4 / 68 µs; 1 ms 0.7 / 8 µs.
# 0.5 ms costs ~4% of a core at 10 ms and delays a Modbus request arriving during the spin
# by at most that long (the spin holds the GIL).
DEFAULT_SPIN_NS = 500_000
# Upper bound on one sleep so stop requests are seen promptly even with long task intervals.
_MAX_SLEEP_NS = 50_000_000


def _set_fifo_priority(priority: int) -> bool:
    """Make the calling thread SCHED_FIFO (Linux: pid 0 means this thread, not the process)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):  # not Linux, or no CAP_SYS_NICE
        return False
    return True


class ScanIo(Protocol):
    """I/O a task exchanges with the image around each scan, under the scan lock (a CODESYS
    Modbus device: :class:`~armbench.softplc.codesys_device.CodesysDevice`)."""

    def read_inputs(self) -> None:
        """Before the task runs: inputs into the image."""
        ...

    def write_outputs(self) -> None:
        """After it ran without a fault: outputs out of the image."""
        ...


class PlcState(enum.Enum):
    STOPPED = "STOPPED"
    RUNNING = "RUNNING"
    FAULT = "FAULT"


@dataclass(frozen=True)
class FaultInfo:
    """Why the PLC is in FAULT."""

    message: str
    location: str
    task: str
    time_ns: int


def _percentile(sorted_samples: list[int], q: float) -> int:
    """Nearest-rank percentile (no interpolation: the value really occurred)."""
    if not sorted_samples:
        return 0
    rank = max(1, math.ceil(q * len(sorted_samples) / 100.0))
    return sorted_samples[min(rank, len(sorted_samples)) - 1]


@dataclass(frozen=True)
class Distribution:
    """Summary of one measured quantity, in nanoseconds. Percentiles cover the most recent
    samples (the reservoir); count/min/mean/max cover every sample since the last reset."""

    count: int
    min_ns: int
    mean_ns: float
    max_ns: int
    p50_ns: int
    p99_ns: int


@dataclass
class _Series:
    """Running min/mean/max plus a ring buffer of recent samples for percentiles."""

    reservoir: int
    count: int = 0
    total: int = 0
    min: int = 0
    max: int = 0
    recent: deque[int] = field(init=False)

    def __post_init__(self) -> None:
        self.recent = deque(maxlen=self.reservoir)

    def add(self, value: int) -> None:
        if self.count == 0:
            self.min = self.max = value
        elif value < self.min:
            self.min = value
        elif value > self.max:
            self.max = value
        self.count += 1
        self.total += value
        self.recent.append(value)

    def summary(self) -> Distribution:
        ordered = sorted(self.recent)
        return Distribution(
            count=self.count,
            min_ns=self.min,
            mean_ns=self.total / self.count if self.count else 0.0,
            max_ns=self.max,
            p50_ns=_percentile(ordered, 50.0),
            p99_ns=_percentile(ordered, 99.0),
        )


@dataclass(frozen=True)
class TaskStats:
    """Cycle statistics of one task. ``jitter`` is actual start − scheduled release;
    ``overruns`` counts releases skipped because the task was still late when they came."""

    name: str
    interval_ns: int
    scans: int
    overruns: int
    execution: Distribution
    jitter: Distribution


@dataclass
class _TaskRuntime:
    spec: TaskSpec
    order: int  # declaration order, breaks priority ties deterministically
    reservoir: int
    next_release_ns: int = 0
    overruns: int = 0
    execution: _Series = field(init=False)
    jitter: _Series = field(init=False)

    def __post_init__(self) -> None:
        self.execution = _Series(self.reservoir)
        self.jitter = _Series(self.reservoir)

    def stats(self) -> TaskStats:
        return TaskStats(
            name=self.spec.name,
            interval_ns=self.spec.interval_ns,
            scans=self.execution.count,
            overruns=self.overruns,
            execution=self.execution.summary(),
            jitter=self.jitter.summary(),
        )


class SoftPlc:
    """Runs a :class:`CompiledProgram`'s tasks.

    ``step(now_ns)`` is the whole scheduler: it runs, in priority order, every task whose
    release time has come. Releases are at ``origin + k * interval`` where the origin is the
    ``now_ns`` of the first step after entering RUNNING. A task found late by one interval or
    more runs once and the releases it missed are counted as overruns.

    ``clock_ns`` only measures execution time and in-step start offsets (pass a fake one for
    reproducible statistics); scheduling uses nothing but the ``now_ns`` values given.

    ``io``: copies inputs into the image before each task and outputs out of it after each
    task that did not fault, inside the task's hold of the scan lock.
    """

    def __init__(
        self,
        program: CompiledProgram,
        *,
        lock: ScanLock | None = None,
        clock_ns: Callable[[], int] = time.perf_counter_ns,
        reservoir: int = DEFAULT_RESERVOIR,
        io: ScanIo | None = None,
    ) -> None:
        specs = list(program.tasks)
        if not specs:
            raise ValueError("program has no tasks")
        names = [t.name for t in specs]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate task names in {names}")
        for spec in specs:
            if spec.interval_ns <= 0:
                raise ValueError(f"task {spec.name}: interval must be positive")
        self.program = program
        self.io = io
        # An ImageLock by default: the Modbus server's compiled request path takes it too.
        self.lock: ScanLock = lock if lock is not None else new_scan_lock()
        self._clock_ns = clock_ns
        self._reservoir = reservoir
        self._tasks = [_TaskRuntime(s, i, reservoir) for i, s in enumerate(specs)]
        self._state = PlcState.STOPPED
        self._fault: FaultInfo | None = None
        self._origin_ns: int | None = None
        # Guards state transitions and statistics (cheap, never held during a scan) so that
        # reading stats does not wait for a long scan.
        self._meta = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop_event = threading.Event()
        self._wake = threading.Event()
        self.rt_priority_applied = False

    # -- state -----------------------------------------------------------------------------

    @property
    def image(self) -> ProcessImage:
        return self.program.image

    @property
    def state(self) -> PlcState:
        return self._state

    @property
    def fault(self) -> FaultInfo | None:
        return self._fault

    def run(self) -> None:
        """Enter RUNNING; the next ``step`` becomes the schedule origin."""
        with self._meta:
            if self._state is PlcState.FAULT:
                raise RuntimeError(f"PLC is in FAULT ({self._fault}); call reset_fault() first")
            if self._state is PlcState.STOPPED:
                self._origin_ns = None
                self._state = PlcState.RUNNING
        self._wake.set()

    def halt(self) -> None:
        """Enter STOPPED (from RUNNING); scans stop, the image keeps its values."""
        with self._meta:
            if self._state is PlcState.RUNNING:
                self._state = PlcState.STOPPED
        self._wake.set()

    def reset_fault(self, *, resume: bool = False) -> None:
        """Clear a fault: the PLC goes to STOPPED, or straight back to RUNNING with
        ``resume=True`` (new schedule origin, statistics kept)."""
        with self._meta:
            if self._state is not PlcState.FAULT:
                return
            self._fault = None
            self._state = PlcState.STOPPED
        if resume:
            self.run()
        self._wake.set()

    # -- scheduling ------------------------------------------------------------------------

    def next_release_ns(self) -> int | None:
        """Earliest pending release, or None when not RUNNING (or before the first step)."""
        with self._meta:
            if self._state is not PlcState.RUNNING or self._origin_ns is None:
                return None
            return min(t.next_release_ns for t in self._tasks)

    def step(self, now_ns: int) -> list[str]:
        """Run every task released at or before ``now_ns``; return their names in run order.

        Does nothing unless RUNNING. Stops at the first :class:`PlcFault` (state FAULT).
        """
        with self._meta:
            if self._state is not PlcState.RUNNING:
                return []
            if self._origin_ns is None:
                self._origin_ns = now_ns
                for task in self._tasks:
                    task.next_release_ns = now_ns
            due = sorted(
                (t for t in self._tasks if t.next_release_ns <= now_ns),
                key=lambda t: (t.spec.priority, t.order),
            )
        ran: list[str] = []
        step_clock0 = self._clock_ns()
        for task in due:
            release = task.next_release_ns
            name = task.spec.name
            with self.lock:
                # Tasks after the first start later than now_ns by the time already spent in
                # this step; that is part of their real jitter.
                t0 = self._clock_ns()
                start_ns = now_ns + (t0 - step_clock0)
                if self.io is not None:
                    self.io.read_inputs()
                try:
                    self.program.run_task(name, start_ns)
                except PlcFault as exc:
                    with self._meta:
                        self._state = PlcState.FAULT
                        self._fault = FaultInfo(exc.message, exc.location, name, start_ns)
                    return ran
                if self.io is not None:
                    self.io.write_outputs()
                t1 = self._clock_ns()
            ran.append(name)
            interval = task.spec.interval_ns
            with self._meta:
                task.execution.add(t1 - t0)
                task.jitter.add(start_ns - release)
                # Releases that already passed while we were late are dropped, not queued.
                missed = (now_ns - release) // interval
                task.overruns += missed
                task.next_release_ns = release + (missed + 1) * interval
        return ran

    # -- introspection ---------------------------------------------------------------------

    def stats(self) -> dict[str, TaskStats]:
        with self._meta:
            return {t.spec.name: t.stats() for t in self._tasks}

    def reset_stats(self) -> None:
        with self._meta:
            for task in self._tasks:
                task.overruns = 0
                task.execution = _Series(self._reservoir)
                task.jitter = _Series(self._reservoir)

    def instance_vars(self, instance: str) -> dict[str, object]:
        """A consistent (between-scans) view of a program instance's variables."""
        with self.lock:
            return self.program.instance_vars(instance)

    # -- real time -------------------------------------------------------------------------

    def run_realtime(
        self,
        stop_event: threading.Event | None = None,
        duration_s: float | None = None,
        *,
        spin_ns: int = DEFAULT_SPIN_NS,
        rt_priority: int | None = None,
    ) -> None:
        """Call :meth:`step` at each release time, measured on ``time.monotonic_ns``, until
        ``stop_event`` is set or ``duration_s`` has passed. Blocks the calling thread; enters
        RUNNING if STOPPED. While not RUNNING (FAULT, halted) it idles until woken.

        ``rt_priority`` (1..99) asks Linux to run this thread SCHED_FIFO, which is what keeps
        wake-up latency low on a busy machine; without the privilege it is ignored and
        :attr:`rt_priority_applied` stays False.
        """
        if stop_event is None and duration_s is None:
            raise ValueError("give a stop_event or a duration_s, or it never returns")
        if rt_priority is not None:
            self.rt_priority_applied = _set_fifo_priority(rt_priority)
        stop = stop_event if stop_event is not None else threading.Event()
        end_ns = (
            time.monotonic_ns() + int(duration_s * 1e9) if duration_s is not None else None
        )
        if self._state is PlcState.STOPPED:
            self.run()
        while not stop.is_set():
            now = time.monotonic_ns()
            if end_ns is not None and now >= end_ns:
                return
            if self._state is not PlcState.RUNNING:
                self._wake.wait(0.02)
                self._wake.clear()
                continue
            deadline = self.next_release_ns()
            if deadline is None:  # fresh RUNNING: this step sets the origin
                self.step(now)
                continue
            if end_ns is not None and deadline > end_ns:
                deadline = end_ns
            if self._sleep_until(deadline, stop, spin_ns):
                self.step(time.monotonic_ns())

    def _sleep_until(self, deadline_ns: int, stop: threading.Event, spin_ns: int) -> bool:
        """Sleep to an absolute deadline; False if interrupted by ``stop`` or a state change
        (a step is then not due)."""
        while True:
            remaining = deadline_ns - time.monotonic_ns()
            if remaining <= spin_ns:
                break
            time.sleep(min(remaining - spin_ns, _MAX_SLEEP_NS) / 1e9)
            if stop.is_set() or self._state is not PlcState.RUNNING:
                return False
        # A pure spin: yielding the GIL here (sleep(0)) was measured to raise p50 jitter from
        # ~3 µs to ~50 µs for no real gain in Modbus throughput.
        while time.monotonic_ns() < deadline_ns:
            pass
        return True

    def start(self, *, spin_ns: int = DEFAULT_SPIN_NS, rt_priority: int | None = None) -> None:
        """Run the real-time loop in a background thread (enters RUNNING)."""
        if self._thread is not None:
            raise RuntimeError("real-time thread already started")
        self._stop_event.clear()
        self.run()
        thread = threading.Thread(
            target=self.run_realtime,
            args=(self._stop_event,),
            kwargs={"spin_ns": spin_ns, "rt_priority": rt_priority},
            name="softplc-scan",
            daemon=True,
        )
        self._thread = thread
        thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the real-time thread and wait for it; RUNNING becomes STOPPED, FAULT stays."""
        thread = self._thread
        self._stop_event.set()
        self._wake.set()
        if thread is not None:
            thread.join(timeout_s)
            if thread.is_alive():
                raise RuntimeError("scan thread did not stop (a scan is stuck?)")
            self._thread = None
        self.halt()

    @property
    def thread_running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self) -> SoftPlc:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
