"""pytest plugin `armbench`: fixtures for Modbus regression tests of the arm controller.

Installed with the package (entry point `pytest11`), so any test suite in this environment
can use them:

- ``plc_address`` (module scope): ``(host, port)`` of the PLC under test. By default a soft
  PLC running ``plc_project/Controller.st`` with its Modbus server on a free loopback port
  (one per test module; under pytest-xdist every worker process starts its own, so workers
  never share one). With ``--plc-address HOST:PORT[,HOST:PORT...]`` (or ``--plc-host`` /
  ``--plc-port`` for one) real PLCs (OpenPLC running ``plc_project/openplc/arm_controller.st``):
  xdist worker N gets the N-th address. More workers than addresses is a usage error unless
  ``--plc-share`` lets the workers take the addresses in turn. The controller's 16 mailboxes
  keep the workers' commands apart, but the arm is one: a suite that moves it, calibrates it
  or counts its answers (tests/modbus: the motion, calibration, gripper and soak tests) needs
  the PLC to itself, and fails when another worker moves the same arm. Share a PLC only
  between suites that read, solve or answer without moving it.
- ``plc``: an :class:`~armbench.controller_client.ArmControllerClient` connected to it.
- ``motion_recorder``: a factory of :class:`~armbench.controller_client.MotionRecorder`s on
  their own connections to it (one FC3 read of the motion registers per scan, tagged with
  the PLC's ScanCount), stopped at the end of the test; a suite asserts on the whole path.
- ``record_points``: ``record_points(n, total=...)`` tells the session that the running test
  checked ``n`` points of a sweep of ``total``. The controlling process (the one pytest-xdist
  workers report to) adds them up into one progress bar (``--sweep-progress``) and prints
  ``armbench sweep: N points in T s = R points/s on W workers`` at the end, T being the time
  from the first sweep test's start to the last one's end (PLC start-up not included).

A real PLC that does not answer Modbus ends the session with one line naming host:port and
the reason (pytest exit code 4).
"""

from __future__ import annotations

import socket
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest

from .. import argtypes
from ..controller_client import ArmControllerClient, MotionRecorder
from ..softplc.modbus_client import ModbusError, PlcClient

PROBE_TIMEOUT_S = 3.0


POINTS_KEY = "armbench_points"  # user_properties entry: (points, total, start, stop)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("armbench", "arm controller under test")
    group.addoption("--plc-host", default=None,
                    help="run the Modbus tests against a real PLC at this host")
    group.addoption("--plc-port", type=argtypes.port, default=None,
                    help="its Modbus TCP port (502)")
    group.addoption("--plc-address", type=argtypes.plc_addresses, default=None,
                    metavar="HOST:PORT[,HOST:PORT...]",
                    help="real PLCs, one per pytest-xdist worker (worker N takes the N-th)")
    group.addoption("--plc-share", action="store_true",
                    help="let more xdist workers than --plc-address entries share the PLCs")
    group.addoption("--sweep-progress", choices=("auto", "bar", "off"), default="auto",
                    help="progress bar of the points tests report with record_points "
                         "(auto: when stderr is a terminal)")


def plc_addresses(config: pytest.Config) -> tuple[tuple[str, int], ...]:
    """The real PLCs named on the command line (empty: soft PLCs)."""
    listed: tuple[tuple[str, int], ...] | None = config.getoption("--plc-address")
    host: str | None = config.getoption("--plc-host")
    port: int | None = config.getoption("--plc-port")
    if listed is not None and (host is not None or port is not None):
        raise pytest.UsageError("give either --plc-address or --plc-host/--plc-port, not both")
    if listed is not None:
        return listed
    if host is None:
        if port is not None:
            raise pytest.UsageError("--plc-port needs --plc-host (or use --plc-address)")
        return ()
    return ((host, 502 if port is None else port),)


def _worker(config: pytest.Config) -> tuple[int, int]:
    """(index, count) of this pytest-xdist worker; (0, 1) without xdist."""
    info: dict[str, Any] | None = getattr(config, "workerinput", None)
    if info is None:
        return 0, 1
    return int(str(info["workerid"]).removeprefix("gw")), int(info["workercount"])


def _xdist_workers(config: pytest.Config) -> int:
    """Workers the controlling process will start (0 without xdist)."""
    n = getattr(config.option, "numprocesses", None)
    return n if isinstance(n, int) else 0


def pytest_configure(config: pytest.Config) -> None:
    addresses = plc_addresses(config)
    if hasattr(config, "workerinput"):
        return
    workers = _xdist_workers(config)
    if addresses and workers > len(addresses) and not config.getoption("--plc-share"):
        raise pytest.UsageError(
            f"{workers} pytest-xdist workers but {len(addresses)} PLC address(es): give one "
            f"--plc-address entry per worker (or -n {len(addresses)}), or add --plc-share to "
            f"let workers share a PLC (its 16 mailboxes keep their commands apart, but a test "
            f"that moves, calibrates or counts the one arm, as most of tests/modbus does, then "
            f"fails when another worker moves it)")
    config.pluginmanager.register(_SweepReporter(config, max(workers, 1)), "armbench-sweep")


def probe(host: str, port: int, timeout_s: float = PROBE_TIMEOUT_S) -> str | None:
    """None when a Modbus TCP server answers at host:port, else the reason it does not."""
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:  # refused, unreachable, unknown host, timeout
        return exc.strerror or str(exc) or type(exc).__name__
    start = time.monotonic()
    try:
        with PlcClient(host, port, timeout_s=timeout_s) as client:
            client.read_holding_registers(0, 1)
    except ModbusError:
        return None  # an exception response is still a Modbus server answering
    # pymodbus raises several exception types for a silent or garbled peer (not importable
    # here: modbus_client is the one module that touches pymodbus); time tells them apart
    except Exception as exc:
        if time.monotonic() - start >= 0.9 * timeout_s:
            return f"connected, but no Modbus TCP answer within {timeout_s:g} s"
        return f"connected, but the reply is not Modbus TCP ({type(exc).__name__}: {exc})"
    return None


@pytest.fixture(scope="session")
def _real_plc(request: pytest.FixtureRequest) -> tuple[str, int] | None:
    """This worker's real PLC, checked once: one clear line and the end of the session when
    it does not answer, instead of every test failing with the same connection error."""
    addresses = plc_addresses(request.config)
    if not addresses:
        return None
    index, _count = _worker(request.config)
    # pytest_configure refused more workers than addresses without --plc-share; a worker
    # xdist started later to replace a crashed one can still number past the list
    if index >= len(addresses) and not request.config.getoption("--plc-share"):
        pytest.exit(f"armbench: pytest-xdist worker gw{index} has no PLC address of its own "
                    f"({len(addresses)} given with --plc-address); add --plc-share to let "
                    f"workers share", returncode=pytest.ExitCode.USAGE_ERROR)
    host, port = addresses[index % len(addresses)]
    option = "--plc-address" if request.config.getoption("--plc-address") else \
        "--plc-host/--plc-port"
    reason = probe(host, port)
    if reason is not None:
        pytest.exit(f"armbench: the PLC at {host}:{port} ({option}) does not "
                    f"answer: {reason}", returncode=pytest.ExitCode.USAGE_ERROR)
    return host, port


@pytest.fixture(scope="module")
def plc_address(_real_plc: tuple[str, int] | None) -> Iterator[tuple[str, int]]:
    if _real_plc is not None:
        yield _real_plc
        return
    from ..demo import serve_controller

    with serve_controller() as running:
        yield running.host, running.port


@pytest.fixture
def plc(plc_address: tuple[str, int]) -> Iterator[ArmControllerClient]:
    host, port = plc_address
    with PlcClient(host, port) as client, ArmControllerClient(client) as ctl:
        # One request before the test starts: a PLC that takes new connections one at a time
        # (OpenPLC's accept loop) has then taken this one before the test opens another.
        ctl.scan_count()
        yield ctl


@pytest.fixture
def motion_recorder(plc_address: tuple[str, int]) -> Iterator[Callable[[], MotionRecorder]]:
    made: list[MotionRecorder] = []

    def make() -> MotionRecorder:
        rec = MotionRecorder(*plc_address)
        made.append(rec)
        return rec

    yield make
    for rec in made:
        if rec.recording:
            rec.stop()


@pytest.fixture
def record_points(request: pytest.FixtureRequest) -> Iterator[Callable[..., None]]:
    """``record_points(n, total=0)``: this test checked ``n`` more points of a sweep of
    ``total`` (reported to the session's progress bar and points/s summary)."""
    counted = 0
    start = time.time()  # wall clock: the workers' figures are compared across processes

    def record(n: int, total: int = 0) -> None:
        nonlocal counted
        if n < 0:
            raise ValueError(f"a test cannot check {n} points")
        counted += n
        props = [p for p in request.node.user_properties if p[0] != POINTS_KEY]
        props.append((POINTS_KEY, (counted, total, start, time.time())))
        request.node.user_properties[:] = props

    yield record


@dataclass(eq=False)  # pluggy keeps plugins in sets: identity hash
class _SweepReporter:
    """Adds up the points tests report (from every xdist worker, as their reports arrive in
    the controlling process) into one progress bar and a points/s summary."""

    config: pytest.Config
    workers: int
    points: int = 0
    total: int = 0
    first_start: float | None = None
    last_stop: float = 0.0
    bar: Any = field(default=None, repr=False)

    def _want_bar(self) -> bool:
        mode = self.config.getoption("--sweep-progress")
        return mode == "bar" or (mode == "auto" and sys.stderr.isatty())

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when != "call":
            return
        for key, value in report.user_properties:
            if key != POINTS_KEY:
                continue
            entry: Any = value
            n, total, start, stop = entry
            self.points += int(n)
            self.total = max(self.total, int(total))
            self.first_start = start if self.first_start is None else min(self.first_start,
                                                                          start)
            self.last_stop = max(self.last_stop, stop)
            self._show(int(n))

    def _show(self, n: int) -> None:
        if not self._want_bar():
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total or None, unit="pt", desc="FK∘IK sweep",
                            file=sys.stderr, dynamic_ncols=True, leave=True)
        if self.total and self.bar.total != self.total:
            self.bar.total = self.total
        self.bar.update(n)

    @pytest.hookimpl(tryfirst=True)
    def pytest_report_teststatus(self, report: pytest.TestReport,
                                 config: pytest.Config) -> tuple[str, str, str] | None:
        # With the bar drawn, a sweep test's pass shows there, not as a dot in its line.
        if (self.bar is not None and report.when == "call" and report.passed
                and any(k == POINTS_KEY for k, _ in report.user_properties)):
            return "passed", "", "PASSED"
        return None

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if self.bar is not None:
            self.bar.close()
        if self.first_start is None:
            return
        span = max(self.last_stop - self.first_start, 1e-9)
        terminalreporter.write_line(
            f"armbench sweep: {self.points} points in {span:.2f} s = "
            f"{self.points / span:.0f} points/s on {self.workers} worker(s)")
