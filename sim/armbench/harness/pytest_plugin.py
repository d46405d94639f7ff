"""pytest plugin `armbench`: fixtures for Modbus regression tests of the arm controller.

Installed with the package (entry point `pytest11`), so any test suite in this environment
can use them:

- ``plc_address`` (module scope): ``(host, port)`` of the PLC under test. By default a soft
  PLC running ``plc_project/Controller.st`` with its Modbus server on a free loopback port;
  with ``--plc-host``/``--plc-port`` a real PLC (OpenPLC running
  ``plc_project/openplc/arm_controller.st``).
- ``plc``: an :class:`~armbench.controller_client.ArmControllerClient` connected to it.
- ``motion_recorder``: a factory of :class:`~armbench.controller_client.MotionRecorder`s on
  their own connections to it (one FC3 read of the motion registers per scan, tagged with
  the PLC's ScanCount), stopped at the end of the test; a suite asserts on the whole path.

A ``--plc-host`` PLC that does not answer Modbus ends the session with one line naming
host:port and the reason (pytest exit code 4).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator

import pytest

from .. import argtypes
from ..controller_client import ArmControllerClient, MotionRecorder
from ..softplc.modbus_client import ModbusError, PlcClient

PROBE_TIMEOUT_S = 3.0


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("armbench", "arm controller under test")
    group.addoption("--plc-host", default=None,
                    help="run the Modbus tests against a real PLC at this host")
    group.addoption("--plc-port", type=argtypes.port, default=502,
                    help="its Modbus TCP port (502)")


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
    """The --plc-host PLC, checked once: one clear line and the end of the session when it
    does not answer, instead of every test failing with the same connection error."""
    host = request.config.getoption("--plc-host")
    if host is None:
        return None
    port = int(request.config.getoption("--plc-port"))
    reason = probe(host, port)
    if reason is not None:
        pytest.exit(f"armbench: the PLC at {host}:{port} (--plc-host/--plc-port) does not "
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
