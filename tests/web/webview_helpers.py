"""Helpers of the live-view tests: HTTP requests to the view, waiting for a condition, and a
soft PLC running any program (tests/web/st/counter.st: a program that is not the arm
controller)."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from armbench.demo import RunningPlc
from armbench.softplc.loader import load_program
from armbench.softplc.modbus_server import ModbusServer
from armbench.softplc.scan import SoftPlc
from armbench.web.app import WebView

COUNTER = Path(__file__).resolve().parent / "st" / "counter.st"


def get(w: WebView, path: str) -> Any:
    with urllib.request.urlopen(w.url + path, timeout=10) as r:
        return json.load(r)


def post(w: WebView, body: object, raw: bytes | None = None,
         path: str = "api/command") -> tuple[int, Any]:
    data = raw if raw is not None else json.dumps(body).encode()
    req = urllib.request.Request(w.url + path, data,
                                 {"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=20) as r:
            return r.status, json.load(r)
    except urllib.error.HTTPError as e:
        return e.code, json.load(e)


def wait_for(cond: Callable[[], bool], what: str, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


@contextmanager
def serve_program(files: Sequence[Path]) -> Iterator[RunningPlc]:
    """The soft PLC (real-time thread) running ``files`` with its Modbus server on a free
    loopback port, as ``armbench serve`` runs them; stopped on exit."""
    prog = load_program(list(files))
    plc = SoftPlc(prog)
    server = ModbusServer(prog.image, plc.lock, host="127.0.0.1", port=0)
    server.start()
    try:
        plc.start()
        try:
            yield RunningPlc(plc, server, "127.0.0.1", server.port)
        finally:
            plc.stop()
    finally:
        server.stop()
