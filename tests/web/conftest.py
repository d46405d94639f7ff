"""Fixtures of the live-view tests: the packaged controller in a soft PLC (real time, Modbus on
a free loopback port) and the web view on another free port, talking to it over Modbus."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from webview_helpers import get, wait_for

from armbench.controller_client import ArmControllerClient
from armbench.demo import RunningPlc, serve_controller
from armbench.softplc.modbus_client import PlcClient
from armbench.web.app import WebView


@pytest.fixture(scope="module")
def running() -> Iterator[RunningPlc]:
    with serve_controller() as r:
        yield r


@pytest.fixture(scope="module")
def web(running: RunningPlc) -> Iterator[WebView]:
    with WebView(running.host, running.port, web_port=0, local_plc=running.plc) as w:
        wait_for(lambda: get(w, "api/state").get("connected") is True, "the view's first poll")
        yield w


@pytest.fixture()
def other(running: RunningPlc) -> Iterator[ArmControllerClient]:
    """Another Modbus client of the same PLC (its own connection and mailbox)."""
    with PlcClient(running.host, running.port) as plc, ArmControllerClient(plc) as ctl:
        yield ctl

