"""pytest plugin `armbench`: fixtures for Modbus regression tests of the arm controller.

Installed with the package (entry point `pytest11`), so any test suite in this environment
can use them:

- ``plc_address`` (module scope): ``(host, port)`` of the PLC under test. By default a soft
  PLC running ``plc_project/Controller.st`` with its Modbus server on a free loopback port;
  with ``--plc-host``/``--plc-port`` a real PLC (OpenPLC running
  ``plc_project/openplc/arm_controller.st``).
- ``plc``: an :class:`~armbench.controller_client.ArmControllerClient` connected to it.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from ..controller_client import ArmControllerClient
from ..softplc.modbus_client import PlcClient


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("armbench", "arm controller under test")
    group.addoption("--plc-host", default=None,
                    help="run the Modbus tests against a real PLC at this host")
    group.addoption("--plc-port", type=int, default=502, help="its Modbus TCP port (502)")


@pytest.fixture(scope="module")
def plc_address(request: pytest.FixtureRequest) -> Iterator[tuple[str, int]]:
    host = request.config.getoption("--plc-host")
    if host is not None:
        yield host, int(request.config.getoption("--plc-port"))
        return
    from ..demo import serve_controller

    with serve_controller() as running:
        yield running.host, running.port


@pytest.fixture
def plc(plc_address: tuple[str, int]) -> Iterator[ArmControllerClient]:
    host, port = plc_address
    with PlcClient(host, port) as client, ArmControllerClient(client) as ctl:
        yield ctl
