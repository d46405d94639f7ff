"""Modbus TCP throughput: our soft PLC server against a plain pymodbus asyncio server.

One pymodbus sync client does sequential write_register + read_holding_registers pairs for a
fixed time against each server in turn and the script prints transactions per second (one
transaction = one request/response) and the ratio. For scale: the real OpenPLC v3 runtime
answers ~3,550 tx/s with the same client loop.

    .venv/bin/python bench/modbus_tps.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import socket
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from pymodbus.client import ModbusTcpClient
from pymodbus.datastore import (
    ModbusDeviceContext,
    ModbusSequentialDataBlock,
    ModbusServerContext,
)
from pymodbus.server import ModbusTcpServer

try:
    from armbench.softplc import ModbusServer, ProcessImage
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
    from armbench.softplc import ModbusServer, ProcessImage


def measure(port: int, seconds: float) -> float:
    """Transactions per second of write+read pairs against 127.0.0.1:port."""
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    if not client.connect():
        raise SystemExit(f"cannot connect to port {port}")
    try:
        for i in range(200):  # warm-up: connection, code paths, CPU frequency
            client.write_register(1, i)
            client.read_holding_registers(1, count=1)
        pairs = 0
        value = 0
        start = time.perf_counter()
        deadline = start + seconds
        while True:
            for _ in range(100):
                value = (value + 1) & 0xFFFF
                w = client.write_register(1, value)
                r = client.read_holding_registers(1, count=1)
                if w.isError() or r.isError() or r.registers[0] != value:
                    raise SystemExit(f"bad answer on port {port}: {w} {r}")
            pairs += 100
            now = time.perf_counter()
            if now >= deadline:
                return 2 * pairs / (now - start)
    finally:
        client.close()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextlib.contextmanager
def pymodbus_server() -> Iterator[int]:
    """A stock pymodbus ModbusTcpServer on its own event loop thread; yields its port."""
    port = free_port()
    ready = threading.Event()
    holder: dict[str, object] = {}

    async def serve() -> None:
        # pymodbus 3.16 adds 1 to addresses internally, so the block starts at 1.
        block = ModbusSequentialDataBlock(1, [0] * 8192)
        context = ModbusServerContext(devices=ModbusDeviceContext(hr=block), single=True)
        server = ModbusTcpServer(context, address=("127.0.0.1", port))
        holder["server"] = server
        holder["loop"] = asyncio.get_running_loop()
        await server.serve_forever(background=True)
        ready.set()
        await server.serving

    thread = threading.Thread(target=lambda: asyncio.run(serve()), name="pymodbus-server")
    thread.start()
    if not ready.wait(10):
        raise SystemExit("pymodbus server did not start")
    try:
        yield port
    finally:
        loop = holder["loop"]
        server = holder["server"]
        assert isinstance(loop, asyncio.AbstractEventLoop)
        assert isinstance(server, ModbusTcpServer)
        asyncio.run_coroutine_threadsafe(server.shutdown(), loop).result(10)
        thread.join(10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    logging.getLogger("pymodbus").setLevel(logging.ERROR)  # its deprecation chatter

    image = ProcessImage.allocate()
    with ModbusServer(image, port=0) as server:
        ours = measure(server.port, args.seconds)
    with pymodbus_server() as port:
        theirs = measure(port, args.seconds)

    print(f"armbench softplc server : {ours:8.0f} tx/s")
    print(f"pymodbus asyncio server : {theirs:8.0f} tx/s")
    print(f"ratio ours/pymodbus     : {ours / theirs:8.2f}")
    print("(real OpenPLC v3 runtime, same client loop: ~3550 tx/s)")


if __name__ == "__main__":
    main()
