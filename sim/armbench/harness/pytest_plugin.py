"""pytest plugin `armbench`: fixtures for Modbus tests of your own ST program and of the arm
controller, on a soft PLC or on a real PLC by address.

Installed with the package (entry point ``pytest11``), so any test suite in this environment
can use them. Importing the plugin costs next to nothing: the compiler, the soft PLC and
pymodbus are loaded by the first fixture that needs them.

Your own program (``--plc-program FILE.st [FILE.st ...]``, or ``plc_program`` in the ini file):

- ``plc_program`` (session): the program, checked once: its located variables by name, typed
  from their declarations and addressed by the Modbus map of ``--plc-flavor``.
- ``program_plc`` (module): the PLC running it; by default a soft PLC started on a free
  loopback port (one per test module and xdist worker), with ``--plc-address HOST:PORT`` a
  real one, checked once per session: a PLC that does not answer, answers with another
  program's signature, or does not scan ends the session with one line.
- ``plc_vars``: typed access by name, ``plc_vars["Level"] = 12.5``, ``plc_vars.wait_scans(1)``,
  ``plc_vars.wait_until("Pump", True)``; a wait gives up after 5 s (``timeout_s=`` on the call,
  ``--plc-wait-timeout S`` or ``plc_wait_timeout = S`` in the ini file for every wait).
- ``modbus``: a plain :class:`~armbench.softplc.modbus_client.PlcClient` connected to it.
- ``soft_plc``: a factory, ``soft_plc("a.st", library=False)``, for tests that start soft PLCs
  of their own (``flavor="codesys"``: serving the CODESYS layout; ``flavor="openplc-v4"``:
  answering as OpenPLC v4's Modbus plugin); each is stopped at the end of the test.

The arm controller (``plc_project/Controller.st``):

- ``plc_address`` (module scope): ``(host, port)`` of the PLC under test. By default a soft
  PLC running the controller on a free loopback port (one per test module; under
  pytest-xdist every worker process starts its own). With ``--plc-address
  HOST:PORT[,HOST:PORT...]`` (or ``--plc-host`` / ``--plc-port`` for one) real PLCs (OpenPLC
  running ``plc_project/openplc/arm_controller.st``): xdist worker N gets the N-th address.
  More workers than addresses is a usage error unless ``--plc-share`` lets the workers take
  the addresses in turn. The controller's 16 mailboxes keep the workers' commands apart, but
  the arm is one: a suite that moves it, calibrates it or counts its answers (tests/modbus:
  the motion, calibration, gripper and soak tests) needs the PLC to itself, and fails when
  another worker moves the same arm. Share a PLC only between suites that read, solve or
  answer without moving it.
- ``plc``: an :class:`~armbench.controller_client.ArmControllerClient` connected to it.
- ``motion_recorder``: a factory of :class:`~armbench.controller_client.MotionRecorder`s.
- ``record_points``: ``record_points(n, total=...)`` tells the session that the running test
  checked ``n`` points of a sweep of ``total``. The controlling process (the one pytest-xdist
  workers report to) adds them up into one progress bar (``--sweep-progress``) and prints
  ``armbench sweep: N points in T s = R points/s on W workers`` at the end, T being the time
  from the first sweep test's start to the last one's end (PLC start-up not included).

``--plc-flavor openplc|openplc-v4|codesys`` (or ``plc_flavor`` in the ini file; ``plc_flavor``
is also a session fixture) says which Modbus server the PLC is: OpenPLC v3's (the default),
OpenPLC v4's (the same map when its Modbus segments are set up as docs/modbus-parity.md says,
its own protocol rules: exception 02 outside the segments sized to the program, writes
applied at the next scan) or a CODESYS PLC serving the CODESYS variant's layout
(plc_project/codesys/register-map.md: what the program writes in input registers, what
clients write in holding registers and coils, 32-bit values least significant word first).
The soft PLCs the fixtures start serve that way; every client speaks it.

A real PLC that does not answer Modbus, or does not run the program the fixtures expect (the
controller: it does not answer a Hello command; your program: see ``plc_program``), ends the
session with one line naming host:port and the reason (pytest exit code 4); when it runs it in
another flavor's layout, or is the other OpenPLC (v3 answers a request to unit id 2, v4 refuses
it with exception 0x0B), the line says so and names the option that fits.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import socket
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from .. import argtypes

# armbench.harness.program.DEFAULT_WAIT_TIMEOUT_S, not imported: the plugin's import stays cheap
DEFAULT_WAIT_TIMEOUT_S = 5.0

# armbench.softplc.modbus_map.FLAVORS (name: layout), not imported: cheap
FLAVORS = ("openplc", "openplc-v4", "codesys")
LAYOUTS = {"openplc": "openplc", "openplc-v4": "openplc", "codesys": "codesys"}

if TYPE_CHECKING:  # imported by the fixtures that need them: see the module docstring
    from ..controller_client import ArmControllerClient, MotionRecorder
    from ..softplc.modbus_client import PlcClient
    from .program import PlcProgram, PlcVariables, ProgramPlc

PROBE_TIMEOUT_S = 3.0


POINTS_KEY = "armbench_points"  # user_properties entry: (points, total, start, stop)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("armbench", "PLC under test (armbench)")
    group.addoption("--plc-host", default=None,
                    help="run the Modbus tests against a real PLC at this host")
    group.addoption("--plc-port", type=argtypes.port, default=None,
                    help="its Modbus TCP port (502)")
    group.addoption("--plc-address", type=argtypes.plc_addresses, default=None,
                    metavar="HOST:PORT[,HOST:PORT...]",
                    help="real PLCs, one per pytest-xdist worker (worker N takes the N-th)")
    group.addoption("--plc-share", action="store_true",
                    help="let more xdist workers than --plc-address entries share the PLCs")
    group.addoption("--plc-flavor", choices=FLAVORS, default=None,
                    help="the PLC's Modbus server: openplc (OpenPLC v3, the default), "
                         "openplc-v4 (OpenPLC v4's Modbus plugin: v3's map, segments sized "
                         "to the program, docs/modbus-parity.md) or codesys (the CODESYS "
                         "variant's layout, plc_project/codesys/register-map.md); the soft "
                         "PLCs serve it")
    group.addoption("--plc-program", nargs="+", action="extend", default=None,
                    metavar="FILE.st",
                    help="your ST program (files or folders) for the plc_program, "
                         "program_plc, plc_vars and modbus fixtures: run in a soft PLC, or "
                         "the variable map of the PLC at --plc-address (put test paths "
                         "before this option)")
    group.addoption("--plc-no-library", action="store_true", default=None,
                    help="compile --plc-program without the armbench ST library")
    group.addoption("--plc-signature", default=None, metavar="NAME",
                    help="the program's located variable whose declared initial value "
                         "identifies it (default: Signature, when declared)")
    group.addoption("--plc-scan-counter", default=None, metavar="NAME",
                    help="the program's located variable it increments every scan "
                         "(default: ScanCount, when declared)")
    group.addoption("--plc-wait-timeout", type=argtypes.positive_seconds, default=None,
                    metavar="S",
                    help="seconds plc_vars.wait_until and wait_scans wait before they fail, "
                         f"unless the call gives timeout_s (default {DEFAULT_WAIT_TIMEOUT_S:g}; "
                         "plc_wait_timeout in the ini file)")
    group.addoption("--sweep-progress", choices=("auto", "bar", "off"), default="auto",
                    help="progress bar of the points tests report with record_points "
                         "(auto: when stderr is a terminal)")
    parser.addini("plc_flavor", default="",
                  help="the PLC's Modbus server, openplc, openplc-v4 or codesys "
                       "(--plc-flavor)")
    parser.addini("plc_program", type="paths", default=[],
                  help="your ST program's files, relative to this ini file (--plc-program)")
    parser.addini("plc_no_library", type="bool", default=False,
                  help="compile plc_program without the armbench ST library")
    parser.addini("plc_signature", default="",
                  help="the program's signature variable (--plc-signature)")
    parser.addini("plc_scan_counter", default="",
                  help="the program's scan counter variable (--plc-scan-counter)")
    parser.addini("plc_wait_timeout", default="",
                  help="seconds plc_vars' waits wait before they fail (--plc-wait-timeout)")


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


def flavor_name(config: pytest.Config) -> str:
    """--plc-flavor, else the ini file's plc_flavor, else "openplc"."""
    given: str | None = config.getoption("--plc-flavor")
    if given:
        return given
    ini = str(config.getini("plc_flavor")).strip().lower()
    if ini and ini not in FLAVORS:
        raise pytest.UsageError(f"plc_flavor (ini) is {ini!r}: choose "
                                f"{', '.join(FLAVORS[:-1])} or {FLAVORS[-1]}")
    return ini or "openplc"


def wait_timeout(config: pytest.Config) -> float:
    """--plc-wait-timeout, else the ini file's plc_wait_timeout, else 5 s: how long the waits
    of ``plc_vars`` wait when the call gives no timeout_s."""
    given: float | None = config.getoption("--plc-wait-timeout")
    if given is not None:
        return given
    ini = str(config.getini("plc_wait_timeout")).strip()
    if not ini:
        return DEFAULT_WAIT_TIMEOUT_S
    try:
        return argtypes.positive_seconds(ini)
    except argparse.ArgumentTypeError as exc:
        raise pytest.UsageError(f"plc_wait_timeout (ini) is {ini!r}: {exc}") from None


def _flavor_hint(found: str) -> str:
    return f"add --plc-flavor {found}" if found != "openplc" else \
        "leave out --plc-flavor (or give --plc-flavor openplc)"


@dataclass(frozen=True)
class ProgramOptions:
    """What the command line and the ini file say about the user's program."""

    files: tuple[Path, ...]  # empty: no program given
    library: bool
    signature: str | None
    scan_counter: str | None
    option: str  # where the files came from, for messages


def program_options(config: pytest.Config) -> ProgramOptions:
    """--plc-program and friends, else the ini file's plc_program and friends; the files are
    checked to exist (a usage error names the first that does not)."""
    given: list[str] | None = config.getoption("--plc-program")
    if given:
        files = [Path(p) for p in given]
        option = "--plc-program"
    else:
        files = [Path(p) for p in config.getini("plc_program")]
        option = "plc_program (ini)"
    expanded: list[Path] = []
    for path in files:
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix.lower() == ".st")
            if not found:
                raise pytest.UsageError(f"{option}: {path} holds no .st file (test paths go "
                                        "before --plc-program)")
            expanded += found
        elif not path.is_file():
            raise pytest.UsageError(f"{option}: no such file: {path}")
        elif path.suffix.lower() != ".st":
            raise pytest.UsageError(f"{option}: {path} is not an .st file (test paths go "
                                    "before --plc-program)")
        else:
            expanded.append(path)
    no_library = config.getoption("--plc-no-library")
    if no_library is None:
        no_library = bool(config.getini("plc_no_library"))
    signature = config.getoption("--plc-signature") or config.getini("plc_signature") or None
    counter = config.getoption("--plc-scan-counter") or config.getini("plc_scan_counter") \
        or None
    return ProgramOptions(tuple(expanded), not no_library, signature, counter, option)


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
    flavor_name(config)  # a bad ini value is a usage error before any test
    wait_timeout(config)
    program_options(config)  # a missing --plc-program file is a usage error before any test
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


@pytest.hookimpl(trylast=True)  # after the session's fixtures are torn down
def pytest_sessionfinish(session: pytest.Session) -> None:
    """In a pytest-xdist worker: free the session's garbage now, before the worker tells the
    controller it has finished.

    pytest collects garbage once more when it unconfigures, after that message, and the
    controller then gives the worker 5 s to end (execnet) before it sends it a SIGINT. After a
    long run a worker holds hundreds of thousands of objects in reference cycles (syntax trees
    of compiled programs, hypothesis' search trees), which only a full collection frees; that
    took over 5 s on a loaded 2-core machine, and the KeyboardInterrupt, landing in whatever
    Python code ran during the collection (hypothesis' gc callback), printed a traceback
    after a green run. Collected here, while the controller still waits for this worker, the
    later collections have nothing to free, and frozen survivors are not even traversed."""
    if not hasattr(session.config, "workerinput"):
        return
    gc.collect()
    gc.freeze()


def pytest_report_header(config: pytest.Config) -> list[str]:
    opts = program_options(config)
    if not opts.files:
        return []
    addresses = plc_addresses(config)
    where = (f"the PLC at {', '.join(f'{h}:{p}' for h, p in addresses)}" if addresses
             else "a soft PLC per test module")
    return [f"armbench: program {', '.join(p.name for p in opts.files)} on {where} "
            f"({flavor_name(config)} layout)"]


def probe(host: str, port: int, timeout_s: float = PROBE_TIMEOUT_S) -> str | None:
    """None when a Modbus TCP server answers at host:port, else the reason it does not."""
    from ..softplc.modbus_client import ModbusError, PlcClient

    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:  # refused, unreachable, unknown host, timeout
        return exc.strerror or str(exc) or type(exc).__name__
    start = time.monotonic()
    try:
        with PlcClient(host, port, timeout_s=timeout_s, retry_reads=False) as client:
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


def controller_probe(host: str, port: int, timeout_s: float = PROBE_TIMEOUT_S,
                     flavor: str = "openplc") -> str | None:
    """None when the PLC at host:port runs the arm controller in ``flavor``'s register
    layout: it answers a Hello command (claims a mailbox, then gives it back), which needs the
    controller's register map and its CRC-32 check words; else the reason, in one line. When
    it answers in another flavor's layout instead, the line names that flavor. The tests would
    write commands to this PLC anyway; this writes one Hello and one Close (and, when the
    first fails, one Hello in the other layout)."""
    from ..softplc.modbus_map import CODESYS

    reason = _hello(host, port, timeout_s, flavor)
    if reason is None:
        return _other_openplc(host, port, timeout_s, flavor, "the arm controller")
    if reason.startswith("has no free mailbox"):
        return reason
    for other in FLAVORS:
        if LAYOUTS[other] != LAYOUTS[flavor] and _counts_scans(host, port, timeout_s, other) \
                and _hello(host, port, timeout_s, other) is None:
            layout = "the CODESYS variant's layout" if other == CODESYS.name else \
                "OpenPLC's register map"
            return (f"runs the arm controller in {layout}, not the {flavor} one this session "
                    f"speaks (--plc-flavor {flavor}): {_flavor_hint(other)}")
    load = ("import plc_project/codesys/arm_controller_codesys.xml, its Modbus TCP Server "
            "Device set up as plc_project/codesys/register-map.md says" if flavor == CODESYS.name
            else "upload plc_project/openplc/arm_controller.st")
    return (f"answers Modbus but does not run the arm controller: no answer to a Hello "
            f"command within {timeout_s:g} s ({load})")


def _other_openplc(host: str, port: int, timeout_s: float, flavor: str,
                   what: str) -> str | None:
    """None unless the PLC, running ``what`` in OpenPLC's map, is the other OpenPLC than
    ``flavor`` says (v3 for openplc-v4, v4 for openplc): then why, in one line."""
    if LAYOUTS[flavor] != "openplc":
        return None
    from .program import openplc_generation

    found = openplc_generation(host, port, timeout_s)
    if found is None or found == flavor:
        return None
    name = {"openplc": "OpenPLC v3's", "openplc-v4": "OpenPLC v4's"}
    return (f"runs {what}, but answers as {name[found]} Modbus server, not "
            f"{name[flavor]} this session speaks (--plc-flavor {flavor}; a request to unit id 2 "
            f"{'is answered' if found == 'openplc' else 'gets exception 0x0B'}): "
            f"{_flavor_hint(found)}")


def _counts_scans(host: str, port: int, timeout_s: float, flavor: str,
                  within_s: float = 0.5) -> bool:
    """The controller's ScanCount, read where ``flavor`` has it, moves within ``within_s``:
    a quick look before a Hello (which waits ``timeout_s`` for an answer that never comes
    from a PLC speaking another layout)."""
    from ..controller_client import ArmControllerClient
    from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient

    try:
        with PlcClient(host, port, timeout_s=timeout_s) as client:
            ctl = ArmControllerClient(client, timeout_s=timeout_s, flavor=flavor)
            first = ctl.scan_count()
            deadline = time.monotonic() + within_s
            while time.monotonic() < deadline:
                time.sleep(0.01)
                if ctl.scan_count() != first:
                    return True
    except (ModbusError, ModbusIoError):
        pass
    return False


def _hello(host: str, port: int, timeout_s: float, flavor: str) -> str | None:
    """None when a Hello in ``flavor``'s layout is answered, else why not."""
    from ..controller_client import ArmControllerClient, HandshakeError, NoFreeMailbox
    from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient

    try:
        with PlcClient(host, port, timeout_s=timeout_s) as client, \
                ArmControllerClient(client, timeout_s=timeout_s, flavor=flavor) as ctl:
            ctl.open()
    except NoFreeMailbox:
        return ("has no free mailbox of the arm controller, or does not run it: every "
                "answer block shows another session")
    except (HandshakeError, ModbusError, ModbusIoError) as exc:
        return str(exc)
    return None


def _worker_plc(config: pytest.Config) -> tuple[str, int, str] | None:
    """(host, port, the option that named it) of this worker's real PLC; None: soft PLCs."""
    addresses = plc_addresses(config)
    if not addresses:
        return None
    index, _count = _worker(config)
    # pytest_configure refused more workers than addresses without --plc-share; a worker
    # xdist started later to replace a crashed one can still number past the list
    if index >= len(addresses) and not config.getoption("--plc-share"):
        pytest.exit(f"armbench: pytest-xdist worker gw{index} has no PLC address of its own "
                    f"({len(addresses)} given with --plc-address); add --plc-share to let "
                    f"workers share", returncode=pytest.ExitCode.USAGE_ERROR)
    host, port = addresses[index % len(addresses)]
    option = "--plc-address" if config.getoption("--plc-address") else "--plc-host/--plc-port"
    reason = probe(host, port)
    if reason is not None:
        pytest.exit(f"armbench: the PLC at {host}:{port} ({option}) does not "
                    f"answer: {reason}", returncode=pytest.ExitCode.USAGE_ERROR)
    return host, port, option


@pytest.fixture(scope="session")
def _real_plc(request: pytest.FixtureRequest) -> tuple[str, int] | None:
    """This worker's real PLC for the controller fixtures, checked once: one clear line and
    the end of the session when it does not answer Modbus or does not run the controller,
    instead of every test failing with the same connection error or handshake timeout."""
    found = _worker_plc(request.config)
    if found is None:
        return None
    host, port, option = found
    reason = controller_probe(host, port, flavor=flavor_name(request.config))
    if reason is not None:
        pytest.exit(f"armbench: the PLC at {host}:{port} ({option}) {reason}",
                    returncode=pytest.ExitCode.USAGE_ERROR)
    return host, port


@pytest.fixture(scope="session")
def plc_flavor(request: pytest.FixtureRequest) -> str:
    """The Modbus server of the PLC under test, "openplc", "openplc-v4" or "codesys"
    (``--plc-flavor``, ``plc_flavor`` in the ini file): give it to the clients a test makes
    itself, ``ArmControllerClient(modbus, flavor=plc_flavor)``."""
    return flavor_name(request.config)


@pytest.fixture(scope="module")
def plc_address(_real_plc: tuple[str, int] | None,
                plc_flavor: str) -> Iterator[tuple[str, int]]:
    """``(host, port)`` of the PLC running the arm controller: this worker's
    ``--plc-address`` entry (checked once per session), else a soft PLC running the packaged
    controller on a free loopback port, started for the test module, serving the
    ``plc_flavor`` layout."""
    if _real_plc is not None:
        yield _real_plc
        return
    from ..demo import serve_controller

    with serve_controller(flavor=plc_flavor) as running:
        yield running.host, running.port


@pytest.fixture
def plc(plc_address: tuple[str, int], plc_flavor: str) -> Iterator[ArmControllerClient]:
    """An ArmControllerClient of the controller at ``plc_address`` (in the ``plc_flavor``
    layout), on a connection of its own; it claims a mailbox at its first command and gives
    it back after the test."""
    from ..controller_client import ArmControllerClient
    from ..softplc.modbus_client import PlcClient

    host, port = plc_address
    with PlcClient(host, port) as client, \
            ArmControllerClient(client, flavor=plc_flavor) as ctl:
        # One request before the test starts: a PLC that takes new connections one at a time
        # (OpenPLC's accept loop) has then taken this one before the test opens another.
        ctl.scan_count()
        yield ctl


@pytest.fixture
def motion_recorder(plc_address: tuple[str, int],
                    plc_flavor: str) -> Iterator[Callable[[], MotionRecorder]]:
    """A factory of MotionRecorders of the controller at ``plc_address``: each records the
    motion registers once per scan (one FC3 read tagged with the PLC's ScanCount) on its own
    connection, from ``start()`` to ``stop()``; any still recording are stopped after the
    test."""
    from ..controller_client import MotionRecorder

    made: list[MotionRecorder] = []

    def make() -> MotionRecorder:
        rec = MotionRecorder(*plc_address, flavor=plc_flavor)
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


# -- the user's own program ----------------------------------------------------------------


def _load_or_exit(files: Sequence[Path], *, library: bool, signature: str | None,
                  scan_counter: str | None, option: str, flavor: str) -> PlcProgram:
    """The checked program; its diagnostics (or why it cannot be tested over Modbus) end the
    session instead of failing every test with them."""
    from ..compiler.diagnostics import CompileFailed
    from .program import PlcProgram, ProgramError

    try:
        return PlcProgram.load(files, library=library, signature=signature,
                               scan_counter=scan_counter, flavor=flavor)
    except CompileFailed as exc:
        hint = ("\narmbench: note: compiled together with the armbench ST library; "
                "--plc-no-library (plc_no_library = true in the ini file) leaves it out"
                if library else "")
        pytest.exit(f"armbench: {option} does not compile:\n{exc}{hint}",
                    returncode=pytest.ExitCode.USAGE_ERROR)
    except ProgramError as exc:
        pytest.exit(f"armbench: {option}: {exc}", returncode=pytest.ExitCode.USAGE_ERROR)


@pytest.fixture(scope="session")
def plc_program(request: pytest.FixtureRequest) -> PlcProgram:
    """The program given with ``--plc-program FILE.st ...`` (or ``plc_program`` in the ini
    file), checked once: its located variables by name (``.variables``, ``.variable(name)``),
    its ``signature`` (a located integer ``Signature`` with a non-zero initial value: a PLC
    found by address must hold that value there) and ``scan_counter`` (a located
    ``ScanCount`` the program increments every scan)."""
    opts = program_options(request.config)
    if not opts.files:
        pytest.exit("armbench: the plc_program, program_plc, plc_vars and modbus fixtures "
                    "need your program: --plc-program FILE.st (or plc_program = FILE.st in "
                    "the ini file)", returncode=pytest.ExitCode.USAGE_ERROR)
    return _load_or_exit(opts.files, library=opts.library, signature=opts.signature,
                         scan_counter=opts.scan_counter, option=opts.option,
                         flavor=flavor_name(request.config))


@pytest.fixture(scope="session")
def _real_program_plc(request: pytest.FixtureRequest,
                      plc_program: PlcProgram) -> tuple[str, int] | None:
    """This worker's real PLC for the program fixtures, checked once: it answers Modbus,
    holds the program's signature and its scan counter moves; otherwise one line ends the
    session."""
    found = _worker_plc(request.config)
    if found is None:
        return None
    host, port, option = found
    from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient
    from .program import check_identity, other_flavor

    try:
        with PlcClient(host, port, timeout_s=PROBE_TIMEOUT_S) as client:
            try:
                reason = check_identity(client, plc_program, PROBE_TIMEOUT_S)
            except ModbusError as exc:
                reason = (f"answers Modbus, but reading {plc_program.name}'s variables fails "
                          f"({exc})")
            if reason is not None:
                layout = other_flavor(client, plc_program, PROBE_TIMEOUT_S)
                if layout is not None:
                    reason = (f"serves {plc_program.name} in the {layout.title} layout, not the "
                              f"{plc_program.flavor.title} one this session speaks "
                              f"(--plc-flavor {plc_program.flavor.name}): "
                              f"{_flavor_hint(layout.name)}")
    except ModbusIoError as exc:
        reason = f"answers Modbus, but reading {plc_program.name}'s variables fails ({exc})"
    if reason is None:
        reason = _other_openplc(host, port, PROBE_TIMEOUT_S, plc_program.flavor.name,
                                plc_program.name)
    if reason is not None:
        pytest.exit(f"armbench: the PLC at {host}:{port} ({option}) {reason}",
                    returncode=pytest.ExitCode.USAGE_ERROR)
    sig = plc_program.signature
    if sig is None:
        warnings.warn(ProgramIdentityWarning(
            f"{plc_program.name} declares no Signature variable: nothing checks that the PLC "
            f"at {host}:{port} runs it (declare e.g. `Signature AT %MD0 : UDINT := "
            "16#5EED0001;`)"), stacklevel=1)
    elif not sig.readable:
        warnings.warn(ProgramIdentityWarning(
            f"{sig.variable.name} cannot identify {plc_program.name} on the PLC at "
            f"{host}:{port}: the program never assigns it, so the CODESYS variant puts it in "
            f"%I ({sig.variable.location}, a holding register), where the Modbus device's "
            "data overwrites its initial value; assign it in the program "
            f"(`{sig.variable.name} := {_hex(sig.value)};`) to move it to %Q"), stacklevel=1)
    return host, port


def _hex(value: int) -> str:
    return f"16#{value:X}" if value >= 0 else str(value)


class ProgramIdentityWarning(pytest.PytestWarning):
    """A PLC found by address could not be checked to run the program under test."""


@pytest.fixture(scope="module")
def program_plc(plc_program: PlcProgram,
                _real_program_plc: tuple[str, int] | None) -> Iterator[ProgramPlc]:
    """The PLC running ``plc_program``: with ``--plc-address`` this worker's PLC (checked
    once per session), else a soft PLC started for the test module on a free loopback port.
    ``.address``; on the soft PLC also ``.set_input(name, value)`` (inputs, as its I/O would
    write them), ``.scans()`` and ``.fault()``."""
    from .program import ProgramPlc, serve_program

    if _real_program_plc is not None:
        host, port = _real_program_plc
        found = ProgramPlc(host, port, plc_program)
        try:
            yield found
        finally:
            found.close()
        return
    with serve_program(plc_program) as running:
        yield running


@pytest.fixture
def modbus(program_plc: ProgramPlc) -> Iterator[PlcClient]:
    """A plain Modbus TCP client (PlcClient: read_coils, read_holding_registers,
    write_registers, read_real, ...) connected to ``program_plc`` for this test."""
    from ..softplc.modbus_client import PlcClient

    with PlcClient(*program_plc.address) as client:
        client.read_holding_registers(0, 1)  # served before the test starts (see ``plc``)
        yield client


@pytest.fixture
def plc_vars(request: pytest.FixtureRequest, program_plc: ProgramPlc) -> Iterator[PlcVariables]:
    """Typed access to ``program_plc``'s located variables by name: ``plc_vars["Level"]``
    reads, ``plc_vars["Level"] = 12.5`` writes (type and address from the declaration),
    ``plc_vars.write(A=1, B=2.0)`` in one request, ``plc_vars.wait_scans(n)``,
    ``plc_vars.wait_until(name, value_or_predicate)``. The waits give up after 5 s with a
    TimeoutError naming the variable, the condition and the last value read: give
    ``timeout_s=`` to one call, or ``--plc-wait-timeout S`` (``plc_wait_timeout = S`` in the
    ini file) for every wait."""
    with program_plc.connect(wait_timeout_s=wait_timeout(request.config)) as v:
        yield v


@dataclass
class SoftPlcFactory:
    """``soft_plc(*files, library=True, signature=None, scan_counter=None,
    flavor="openplc")``: compile the files and start a soft PLC running them, serving as
    ``flavor``'s Modbus server does; returns its ProgramPlc."""

    stack: contextlib.ExitStack[bool | None] = field(default_factory=contextlib.ExitStack)

    def __call__(self, *files: str | Path, library: bool = True,
                 signature: str | None = None, scan_counter: str | None = None,
                 flavor: str = "openplc") -> ProgramPlc:
        from .program import PlcProgram, serve_program

        program = PlcProgram.load(files, library=library, signature=signature,
                                  scan_counter=scan_counter, flavor=flavor)
        return self.stack.enter_context(serve_program(program))


@pytest.fixture
def soft_plc() -> Iterator[SoftPlcFactory]:
    """A factory of soft PLCs: ``plc = soft_plc("counter.st", library=False)`` compiles the
    files (with the armbench ST library unless ``library=False``), runs them with a Modbus
    server on a free loopback port and returns the ProgramPlc (``plc.connect()`` gives typed
    access, ``plc.address`` the address); every one is stopped after the test."""
    factory = SoftPlcFactory()
    with factory.stack:
        yield factory


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
