"""The front ends of many files at once: this process and a forked child share the work.

A file's front end (parse, nesting guard, lexical rules, lowering: units.front_end) is Python
work that depends on that file alone, and it is most of a cold check of a large program. On a
machine with a second CPU, a child forked from this process takes the files from the end of
the list while this process takes them from the start, until they meet; the child's results
come back pickled through a pipe (their bytes are what the unit cache stores, so they are
written there as they are). A file both happen to start is computed twice, never missed.

Forking is only done where it is safe and pays: on Linux, with a second usable CPU, with at
least MIN_SPLIT_BYTES of source, and only while this process runs one thread: a forked copy
of a multi-threaded process may block forever on a lock another thread held (Python 3.12
warns of it), and the count is the kernel's, so it includes threads that C libraries started.
Whatever goes wrong in the child (an exception, a crash, a result that cannot be read back)
only means that this process computes those files itself.
"""

from __future__ import annotations

import os
import pickle
import signal
import struct
import sys
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, TypeVar

from .build import usable_cpus

T = TypeVar("T")
# Source bytes below which the fork, the pickling and the reading back cost more than the
# child saves (st/ is 690 KB; a small program never forks).
MIN_SPLIT_BYTES = 100_000
_STARTED, _RESULT = 0, 1
_HEADER = struct.Struct("<BiQ")  # kind, file index, payload length
# A child that says nothing for this long is taken as stuck: this process computes what it
# has not sent (a file can take longer than this only by being far larger than st/'s largest).
STALL_S = 10.0


@dataclass
class Computed(Generic[T]):
    """One file's result, and its pickled bytes when it was computed by the child."""

    value: T
    pickled: bytes | None = None


def can_split(sizes: Sequence[int]) -> bool:
    """Whether a fork would share this work: see the module's description."""
    return (len(sizes) >= 2 and sum(sizes) >= MIN_SPLIT_BYTES and sys.platform == "linux"
            and hasattr(os, "fork") and usable_cpus() >= 2 and _threads() == 1)


def _threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return 2  # unknown: never fork


def compute_all(jobs: Sequence[tuple[Path, bytes]], work: Callable[[Path, bytes], T],
                kind: type[T]) -> list[Computed[T]]:
    """``work`` of every (path, bytes) job, in order; shared with a forked child when
    can_split says so (``kind``: what a result read back from the child must be)."""
    if not can_split([len(data) for _, data in jobs]):
        return [Computed(work(path, data)) for path, data in jobs]
    read_fd, write_fd = os.pipe()
    try:
        pid = os.fork()
    except OSError:
        os.close(read_fd)
        os.close(write_fd)
        return [Computed(work(path, data)) for path, data in jobs]
    if pid == 0:  # the child: never returns
        os.close(read_fd)
        _child(jobs, work, write_fd)
    os.close(write_fd)
    return _parent(jobs, work, kind, pid, read_fd)


def _child(jobs: Sequence[tuple[Path, bytes]], work: Callable[[Path, bytes], T],
           fd: int) -> None:
    """From the last job down, say which job starts, then send its result; exit without
    running anything of the parent's (no atexit hooks, no flushing of its buffers)."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        for i in range(len(jobs) - 1, -1, -1):
            _send(fd, _STARTED, i, b"")
            blob = pickle.dumps(work(*jobs[i]), protocol=pickle.HIGHEST_PROTOCOL)
            _send(fd, _RESULT, i, blob)
    except BaseException:  # noqa: BLE001 - the parent computes what is missing
        pass
    finally:
        os._exit(0)


def _send(fd: int, what: int, index: int, payload: bytes) -> None:
    for part in (_HEADER.pack(what, index, len(payload)), payload):
        data = memoryview(part)
        while data:
            data = data[os.write(fd, data):]


@dataclass
class _Inbox:
    """What the child has said so far, filled by a reader thread."""

    lowest_started: int
    results: dict[int, bytes] = field(default_factory=dict)
    ended: bool = False
    said: int = 0  # messages so far
    changed: threading.Condition = field(default_factory=threading.Condition)


def _read(fd: int, inbox: _Inbox) -> None:
    with os.fdopen(fd, "rb") as pipe:
        while True:
            header = pipe.read(_HEADER.size)
            if len(header) < _HEADER.size:
                break
            what, index, size = _HEADER.unpack(header)
            payload = pipe.read(size) if size else b""
            if len(payload) < size:
                break
            with inbox.changed:
                if what == _STARTED:
                    inbox.lowest_started = min(inbox.lowest_started, index)
                else:
                    inbox.results[index] = payload
                inbox.said += 1
                inbox.changed.notify_all()
    with inbox.changed:
        inbox.ended = True
        inbox.changed.notify_all()


def _parent(jobs: Sequence[tuple[Path, bytes]], work: Callable[[Path, bytes], T],
            kind: type[T], pid: int, fd: int) -> list[Computed[T]]:
    n = len(jobs)
    inbox = _Inbox(lowest_started=n)
    reader = threading.Thread(target=_read, args=(fd, inbox), daemon=True,
                              name="armbench-front-split")
    reader.start()
    out: list[Computed[T] | None] = [None] * n
    try:
        mine = 0
        while mine < n and mine < inbox.lowest_started:  # the child's start ends this
            out[mine] = Computed(work(*jobs[mine]))
            mine += 1
        with inbox.changed:  # the rest were started by the child: wait for them
            heard = -1
            while not inbox.ended and any(i not in inbox.results for i in range(mine, n)):
                if inbox.said == heard:
                    break  # nothing new for STALL_S
                heard = inbox.said
                inbox.changed.wait(STALL_S)
            results = dict(inbox.results)
    finally:
        _end(pid)
    for i in range(mine, n):
        blob = results.get(i)
        value = _load(blob, kind) if blob is not None else None
        out[i] = Computed(work(*jobs[i])) if value is None else Computed(value, blob)
    reader.join()
    return [c for c in out if c is not None]


def _load(blob: bytes, kind: type[T]) -> T | None:
    try:
        value = pickle.loads(blob)
    except Exception:  # noqa: BLE001 - computed here instead
        return None
    return value if isinstance(value, kind) else None


def _end(pid: int) -> None:
    """Stop the child (it may still be working on a file this process did) and reap it."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass
