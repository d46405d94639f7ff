"""A pure-Python stand-in for a compiled ST program, implementing CompiledProgram, and a raw
Modbus TCP helper for the malformed-frame tests."""

from __future__ import annotations

import socket
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from armbench.softplc import PlcFault, ProcessImage, TaskSpec

Body = Callable[[ProcessImage, int], None]

MS = 1_000_000


@dataclass
class FakeProgram:
    """Runs a Python ``body`` per task; can be told to fault on a given scan of a task.

    Like the compiler's C side, a faulted scan puts the outputs (%QX, %QW) back to their
    values from before the scan, then raises PlcFault.
    """

    tasks: Sequence[TaskSpec]
    bodies: dict[str, Body] = field(default_factory=dict)
    image: ProcessImage = field(default_factory=ProcessImage.allocate)
    fault_at: dict[str, int] = field(default_factory=dict)  # task -> 1-based scan number
    calls: list[tuple[str, int]] = field(default_factory=list)
    scans: dict[str, int] = field(default_factory=dict)

    def run_task(self, task: str, now_ns: int) -> None:
        self.calls.append((task, now_ns))
        n = self.scans.get(task, 0) + 1
        self.scans[task] = n
        saved_qx = self.image.qx.tobytes()
        saved_qw = self.image.qw.tobytes()
        body = self.bodies.get(task)
        if body is not None:
            body(self.image, now_ns)
        if self.fault_at.get(task) == n:
            self.image.qx[:] = saved_qx
            self.image.qw.cast("B")[:] = saved_qw
            raise PlcFault("division by zero", "controller.st:12:5")

    def instance_vars(self, instance: str) -> dict[str, object]:
        return {"scans": sum(self.scans.values()), "instance": instance}


def task(name: str, interval_ms: float, priority: int = 0) -> TaskSpec:
    return TaskSpec(name, int(interval_ms * MS), priority, (f"{name}_inst",))


def copy_md_to_qw(count: int) -> Body:
    """%QW[2i], %QW[2i+1] := high, low word of %MD[i] for i < count: the scan publishes what
    a client wrote, so a torn FC16 write would show as unequal words."""

    def body(image: ProcessImage, now_ns: int) -> None:
        md, qw = image.md, image.qw
        for i in range(count):
            value = md[i]
            qw[2 * i] = value >> 16
            qw[2 * i + 1] = value & 0xFFFF

    return body


MBAP = struct.Struct(">HHHB")


def frame(pdu: bytes, transaction: int = 1, unit: int = 1, protocol: int = 0) -> bytes:
    return MBAP.pack(transaction, protocol, len(pdu) + 1, unit) + pdu


def recv_exact(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError(f"closed after {len(data)} of {n} bytes")
        data += chunk
    return data


def recv_reply(sock: socket.socket) -> tuple[int, bytes]:
    """(transaction id, response PDU) of one response."""
    transaction, protocol, length, _unit = MBAP.unpack(recv_exact(sock, MBAP.size))
    assert protocol == 0
    return transaction, recv_exact(sock, length - 1)


def raw_call(port: int, pdu: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall(frame(pdu, transaction=0x1234))
        transaction, reply = recv_reply(sock)
        assert transaction == 0x1234
        return reply


def closed_by_peer(sock: socket.socket, timeout_s: float = 5.0) -> bool:
    """True if the server closed the connection (EOF or reset) within the timeout."""
    sock.settimeout(timeout_s)
    try:
        return sock.recv(1) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False
