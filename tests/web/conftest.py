"""Fixtures of the live-view tests: the packaged controller in a soft PLC (real time, Modbus on
a free loopback port) and the web view on another free port, talking to it over Modbus; one
headless chromium for every browser test of the session.

scripts/setup.sh installs chromium with apt-get where it is missing; Playwright is pointed at
that browser (``playwright install`` would download one, which these machines cannot).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from typing import TYPE_CHECKING

import pytest
from webview_helpers import get, wait_for

from armbench.controller_client import ArmControllerClient
from armbench.demo import RunningPlc, serve_controller
from armbench.softplc.modbus_client import PlcClient
from armbench.web.app import WebView

if TYPE_CHECKING:
    from playwright.sync_api import Browser


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="session")
def browser() -> Iterator[Browser]:
    from playwright.sync_api import sync_playwright

    path = chromium_path()
    if path is None:
        pytest.skip("chromium is not installed and could not be: scripts/setup.sh installs it "
                    "with apt-get (Debian package chromium) where apt-get runs as root")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, args=["--no-sandbox"])
        yield b
        b.close()


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

