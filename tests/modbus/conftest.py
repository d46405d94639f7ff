"""Fixture ``plc``: the controller over Modbus. By default a soft PLC + Modbus server started
in-process on a free loopback port; with ``--plc-host``/``--plc-port`` a real PLC (OpenPLC
running the concatenation of st/*.st and plc_project/Controller.st)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from armbench.controller_client import ArmControllerClient
from armbench.softplc.modbus_client import PlcClient


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("armbench-modbus")
    group.addoption("--plc-host", default=None,
                    help="run tests/modbus against a real PLC at this host")
    group.addoption("--plc-port", type=int, default=502, help="its Modbus TCP port (502)")


@pytest.fixture(scope="module")
def plc_address(request: pytest.FixtureRequest) -> Iterator[tuple[str, int]]:
    host = request.config.getoption("--plc-host")
    if host is not None:
        yield host, int(request.config.getoption("--plc-port"))
        return
    from armbench.demo import serve_controller

    with serve_controller() as running:
        yield running.host, running.port


@pytest.fixture
def plc(plc_address: tuple[str, int]) -> Iterator[ArmControllerClient]:
    host, port = plc_address
    with PlcClient(host, port) as client:
        yield ArmControllerClient(client)
