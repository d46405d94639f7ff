"""Fixtures for the soft PLC tests: an image, a server on a free port, a pymodbus client."""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

try:
    import armbench.softplc  # noqa: F401
except ImportError:  # checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "sim"))

from armbench.softplc import ImageLock, ModbusServer, ProcessImage
from armbench.softplc.fastpath import ScanLock
from armbench.softplc.modbus_client import PlcClient


@pytest.fixture
def image() -> ProcessImage:
    return ProcessImage.allocate()


@pytest.fixture(params=["compiled", "python"])
def scan_lock(request: pytest.FixtureRequest) -> ScanLock:
    """The soft PLC's lock, one of each kind: an ImageLock puts the server on its compiled
    request path (the default), a threading.Lock on the Python one; both must answer alike."""
    return ImageLock() if request.param == "compiled" else threading.Lock()


@pytest.fixture
def server(image: ProcessImage, scan_lock: ScanLock) -> Iterator[ModbusServer]:
    with ModbusServer(image, scan_lock, port=0) as srv:
        assert srv.fast_path == isinstance(scan_lock, ImageLock)
        yield srv


@pytest.fixture
def client(server: ModbusServer) -> Iterator[PlcClient]:
    with PlcClient(port=server.port, timeout_s=5.0) as c:
        yield c
