"""Modbus TCP throughput: our soft PLC server against a plain pymodbus asyncio server.

One pymodbus sync client does sequential write_register + read_holding_registers pairs for a
fixed time against each server in turn (each server in its own process, like OpenPLC) and
the script prints transactions per second (one
transaction = one request/response) and the ratio. For scale: the real OpenPLC v3 runtime
answers ~3,550 tx/s with the same client loop.

    .venv/bin/python bench/modbus_tps.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import multiprocessing
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
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


def measure(port: int, seconds: float, address: int = 1) -> float:
    """Transactions per second of write+read pairs against 127.0.0.1:port."""
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    # pymodbus 3.16 leaves connect/close/shutdown and the data block unannotated.
    if not client.connect():  # type: ignore[no-untyped-call]
        raise SystemExit(f"cannot connect to port {port}")
    try:
        for i in range(200):  # warm-up: connection, code paths, CPU frequency
            client.write_register(address, i)
            client.read_holding_registers(address, count=1)
        pairs = 0
        value = 0
        start = time.perf_counter()
        deadline = start + seconds
        while True:
            for _ in range(100):
                value = (value + 1) & 0xFFFF
                w = client.write_register(address, value)
                r = client.read_holding_registers(address, count=1)
                if w.isError() or r.isError() or r.registers[0] != value:
                    raise SystemExit(f"bad answer on port {port}: {w} {r}")
            pairs += 100
            now = time.perf_counter()
            if now >= deadline:
                return 2 * pairs / (now - start)
    finally:
        client.close()  # type: ignore[no-untyped-call]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def pin(cpus: set[int] | None) -> None:
    if cpus is not None:
        os.sched_setaffinity(0, cpus)


def serve_ours(conn: Connection, cpus: set[int] | None) -> None:
    """Child process: our server on a free port until told to stop."""
    pin(cpus)
    with ModbusServer(ProcessImage.allocate(), port=0) as server:
        conn.send(server.port)
        conn.recv()


def serve_pymodbus(conn: Connection, cpus: set[int] | None) -> None:
    """Child process: a stock pymodbus ModbusTcpServer (asyncio) until told to stop."""
    pin(cpus)
    logging.getLogger("pymodbus").setLevel(logging.ERROR)  # its v4 deprecation warnings
    port = free_port()

    async def serve() -> None:
        # pymodbus 3.16 adds 1 to addresses internally, so the block starts at 1.
        block = ModbusSequentialDataBlock(1, [0] * 8192)  # type: ignore[no-untyped-call]
        context = ModbusServerContext(devices=ModbusDeviceContext(hr=block), single=True)
        server = ModbusTcpServer(context, address=("127.0.0.1", port))
        await server.serve_forever(background=True)
        conn.send(port)
        await asyncio.get_running_loop().run_in_executor(None, conn.recv)
        await server.shutdown()  # type: ignore[no-untyped-call]

    asyncio.run(serve())


# %MW100: a holding register the controller program does not locate, so a client write
# stays (docs/matiec-facts.md) while the 10 ms scans run.
SERVE_ADDRESS = 1024 + 100
ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def armbench_serve(cpus: set[int] | None) -> Iterator[int]:
    """`armbench serve` of the controller project, as a user runs it: real-time scans plus
    Modbus in one process."""
    port = free_port()
    files = [str(p) for p in sorted((ROOT / "st").glob("*.st"))]
    files.append(str(ROOT / "plc_project" / "Controller.st"))
    cmd = [sys.executable, "-m", "armbench.cli", "serve", *files, "--port", str(port)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True,
                            preexec_fn=(lambda: pin(cpus)) if cpus else None)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        if "serving" not in line:
            raise SystemExit(f"armbench serve did not start: {line!r}")
        yield port
    finally:
        proc.terminate()
        proc.wait(10)


@contextlib.contextmanager
def server_process(
    target: Callable[[Connection, set[int] | None], None], cpus: set[int] | None
) -> Iterator[int]:
    """Run a server in its own process (as OpenPLC is), so client and server do not share
    one GIL; yields its port."""
    ctx = multiprocessing.get_context("spawn")
    parent, child = ctx.Pipe()
    process = ctx.Process(target=target, args=(child, cpus), daemon=True)
    process.start()
    try:
        if not parent.poll(30):
            raise SystemExit(f"{target.__name__} did not start")
        port: int = parent.recv()
        yield port
    finally:
        parent.send("stop")
        process.join(10)
        if process.is_alive():
            process.kill()
            process.join()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument(
        "--cpus",
        choices=["any", "same", "split"],
        default="any",
        help="pin client and server to one CPU (same) or to two (split); on VMs the cross-CPU "
        "wake-up per request dominates and the figure is bimodal unless pinned",
    )
    args = parser.parse_args()
    client_cpus: set[int] | None = None
    server_cpus: set[int] | None = None
    if args.cpus != "any":
        first, *rest = sorted(os.sched_getaffinity(0))
        client_cpus = {first}
        server_cpus = {first} if args.cpus == "same" or not rest else {rest[0]}
    pin(client_cpus)
    logging.getLogger("pymodbus").setLevel(logging.ERROR)  # its deprecation chatter

    with server_process(serve_ours, server_cpus) as port:
        ours = measure(port, args.seconds)
    with server_process(serve_pymodbus, server_cpus) as port:
        theirs = measure(port, args.seconds)
    with armbench_serve(server_cpus) as port:
        serve = measure(port, args.seconds, SERVE_ADDRESS)

    print(f"client/server CPUs      : {args.cpus}")
    print(f"armbench softplc server : {ours:8.0f} tx/s")
    print(f"pymodbus asyncio server : {theirs:8.0f} tx/s")
    print(f"armbench serve (controller, 10 ms scans running): {serve:8.0f} tx/s")
    print(f"ratio ours/pymodbus     : {ours / theirs:8.2f}")
    print("(real OpenPLC v3 runtime, same client loop: ~3550 tx/s)")


if __name__ == "__main__":
    main()
