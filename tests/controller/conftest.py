"""The controller on a soft PLC with a fast clock, for the tests that need many scans: the
10 ms task is stepped as fast as the host runs it (simulated time), so 1000 scans pass in
well under a second of wall time, and its Modbus server is on a free loopback port."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from fast_plc import FastPlc

from armbench.controller_client import ArmControllerClient
from armbench.registermap import SOURCES
from armbench.softplc.loader import load_program
from armbench.softplc.modbus_client import PlcClient
from armbench.softplc.modbus_server import ModbusServer
from armbench.softplc.scan import SoftPlc

TASK_NS = 10_000_000


@pytest.fixture(scope="module")
def fast_controller() -> Iterator[FastPlc]:
    prog = load_program(list(SOURCES))
    plc = SoftPlc(prog)
    server = ModbusServer(prog.image, plc.lock, port=0)
    server.start()
    stop = threading.Event()

    fast: FastPlc | None = None

    def run() -> None:
        now = 0
        plc.run()
        while not stop.is_set():
            if fast is not None:
                for hook in list(fast.before_scan):
                    hook()
            plc.step(now)
            now += TASK_NS
            time.sleep(0.0002)  # about 5,000 scans/s: room for the Modbus threads

    fast = FastPlc(plc, ("127.0.0.1", server.port))
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield fast
    finally:
        stop.set()
        thread.join(5.0)
        server.stop()


@pytest.fixture()
def ctl(fast_controller: FastPlc) -> Iterator[ArmControllerClient]:
    """A controller client on the fast PLC, its session closed after the test."""
    with PlcClient(*fast_controller.address) as modbus, ArmControllerClient(modbus) as c:
        yield c
