"""The client against OpenPLC v3's two Modbus-server races, injected deterministically by a
proxy in front of the PLC (the soft PLC by default; docs/modbus-parity.md):

- the accept race: the runtime hands each accepted socket to its thread through one stack
  variable, so a connection accepted right after another is served by no thread (the next
  one by two): the proxy accepts a connection and never reads it;
- the reply-length race: every reply is written with the global MessageLength, which another
  connection's thread may have just set: the proxy writes a reply shorter than its MBAP
  length, none at all, or longer (bytes after the frame).

Reads are sent again on a new connection; a write is never sent on a connection that has not
answered yet, and one whose reply is lost is not sent again by PlcClient (the mailbox
handshake reads its block back instead): no command lost, none run twice.
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import pytest

from armbench.controller_client import ERR_OK, ArmControllerClient
from armbench.softplc.modbus_client import PlcClient

# (connection index, reply index on it, reply) -> bytes to send, and bytes to send 50 ms later
Fault = Callable[[int, int, bytes], tuple[bytes, bytes]]


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("closed")
        data += chunk
    return data


def _recv_frame(sock: socket.socket) -> bytes:
    head = _recv_exact(sock, 7)
    return head + _recv_exact(sock, struct.unpack(">H", head[4:6])[0] - 1)


@dataclass
class Proxy:
    """Forwards Modbus TCP frames to ``upstream``, one upstream connection per client
    connection; connections in ``unserved`` are accepted and never read, and ``fault``
    rewrites replies."""

    upstream: tuple[str, int]
    unserved: frozenset[int] = frozenset()
    fault: Fault | None = None
    requests: list[tuple[int, int]] = field(default_factory=list)  # (connection, function)
    connections: int = 0
    _listener: socket.socket = field(init=False, repr=False)
    _socks: list[socket.socket] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.address = ("127.0.0.1", self._listener.getsockname()[1])
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            self._socks.append(conn)
            index = self.connections
            self.connections += 1
            if index not in self.unserved:
                threading.Thread(target=self._serve, args=(conn, index), daemon=True).start()

    def _serve(self, conn: socket.socket, index: int) -> None:
        try:
            with socket.create_connection(self.upstream, timeout=10.0) as up:
                self._socks.append(up)
                n = 0
                while True:
                    request = _recv_frame(conn)
                    self.requests.append((index, request[7]))
                    up.sendall(request)
                    reply = _recv_frame(up)
                    now, later = (reply, b"") if self.fault is None \
                        else self.fault(index, n, reply)
                    n += 1
                    conn.sendall(now)
                    if later:
                        time.sleep(0.05)
                        conn.sendall(later)
        except OSError:
            pass
        finally:
            conn.close()

    def close(self) -> None:
        self._listener.close()
        for s in self._socks:
            s.close()


@pytest.fixture
def proxy_for(plc_address: tuple[str, int]) -> Iterator[Callable[..., Proxy]]:
    made: list[Proxy] = []

    def make(**kw: object) -> Proxy:
        p = Proxy(plc_address, **kw)  # type: ignore[arg-type]
        made.append(p)
        return p

    yield make
    for p in made:
        p.close()


def _only_first(conn: int, reply: int, change: Callable[[bytes], tuple[bytes, bytes]]) -> Fault:
    def fault(c: int, n: int, data: bytes) -> tuple[bytes, bytes]:
        return change(data) if (c, n) == (conn, reply) else (data, b"")
    return fault


ANY_REGISTER = 0


def test_a_read_on_a_connection_nobody_serves_is_sent_again(
        proxy_for: Callable[..., Proxy]) -> None:
    proxy = proxy_for(unserved=frozenset({0}))
    t0 = time.monotonic()
    with PlcClient(*proxy.address, timeout_s=3.0) as client:
        assert len(client.read_holding_registers(ANY_REGISTER, 2)) == 2
    assert proxy.connections == 2
    assert time.monotonic() - t0 < 2.9  # not the whole timeout


def test_a_write_is_sent_once_and_only_on_a_connection_that_answered(
        proxy_for: Callable[..., Proxy], plc_address: tuple[str, int],
        plc_flavor: str) -> None:
    proxy = proxy_for(unserved=frozenset({0}))
    with PlcClient(*plc_address) as direct:
        ctl = ArmControllerClient(direct, flavor=plc_flavor)
        mbx = ctl.open()
        # Int2 of this client's own block, already answered (the claim): changing it beside
        # the same Seq runs nothing
        reg = ctl.registers[f"MBX{mbx:02d}INT2"]
        with PlcClient(*proxy.address, timeout_s=3.0) as client:
            client.write_registers(reg.address, [0, 7])
        assert [c for c, f in proxy.requests if f == 16] == [1]  # once, on the second
        assert direct.read_holding_registers(reg.address, 2) == [0, 7]
        ctl.close()


@pytest.mark.parametrize("cut", ["short", "none"])
def test_a_read_whose_reply_is_cut_is_sent_again(proxy_for: Callable[..., Proxy],
                                                 plc_address: tuple[str, int], cut: str) -> None:
    def change(data: bytes) -> tuple[bytes, bytes]:
        return (data[:-2] if cut == "short" else b""), b""
    proxy = proxy_for(fault=_only_first(0, 1, change))
    with PlcClient(*proxy.address, timeout_s=1.0) as client:
        client.read_holding_registers(ANY_REGISTER, 2)
        words = client.read_holding_registers(ANY_REGISTER, 2)  # its reply is cut
    assert len(words) == 2
    assert proxy.connections == 2


def test_bytes_after_a_reply_are_never_taken_for_the_next_reply(
        proxy_for: Callable[..., Proxy], plc_address: tuple[str, int],
        plc_flavor: str) -> None:
    # The worst tail: a whole frame that fits the next request (its transaction id, function
    # code and count) with other data.
    def change(data: bytes) -> tuple[bytes, bytes]:
        tid = struct.unpack(">H", data[:2])[0] + 1
        forged = struct.pack(">HHHBBBH", tid, 0, 5, data[6], 3, 2, 0xBEEF)
        return data, forged
    proxy = proxy_for(fault=_only_first(0, 0, change))
    with PlcClient(*plc_address) as direct:
        # a register that stays put between two reads: a command word of an unused mailbox
        register = ArmControllerClient(direct, flavor=plc_flavor).registers["MBX08CODE"].address
        truth = direct.read_holding_registers(register, 1)[0]
    assert truth != 0xBEEF
    with PlcClient(*proxy.address, timeout_s=2.0) as client:
        client.read_holding_registers(register, 1)
        time.sleep(0.2)  # the tail has arrived
        assert client.read_holding_registers(register, 1) == [truth]


def test_a_command_whose_write_reply_is_lost_runs_once(
        proxy_for: Callable[..., Proxy], plc_address: tuple[str, int],
        plc_flavor: str) -> None:
    """The FC16 of a command lands and its reply is lost: PlcClient raises, and the handshake
    reads its block back and waits for the answer instead of writing it again."""
    writes = [0]

    def fault(c: int, n: int, data: bytes) -> tuple[bytes, bytes]:
        if data[7] == 16:
            writes[0] += 1
            if writes[0] == 2:  # the Hello after the claim
                return b"", b""
        return data, b""
    proxy = proxy_for(fault=fault)
    with PlcClient(*plc_address) as direct:
        monitor = ArmControllerClient(direct, flavor=plc_flavor)
        before = monitor.status().commands_answered
        with PlcClient(*proxy.address, timeout_s=1.0) as bus:
            ctl = ArmControllerClient(bus, timeout_s=10.0, flavor=plc_flavor)
            ctl.open()
            assert ctl.hello().error_id == ERR_OK
            assert ctl.answered == 2  # the claim and the Hello, each answered once
            assert monitor.status().commands_answered - before == 2
            assert writes[0] == 2  # the Hello's block was not written again
            ctl.close()


@pytest.mark.parametrize("garble", ["function code", "count"])
def test_a_reply_that_does_not_fit_its_read_is_not_taken(proxy_for: Callable[..., Proxy],
                                                         garble: str) -> None:
    # A frame that is not the answer to this request (another one's, or a stale buffer's)
    # under the request's own transaction id: an FC16 echo, or one register fewer.
    def change(data: bytes) -> tuple[bytes, bytes]:
        tid, pid, _, unit = struct.unpack(">HHHB", data[:7])
        if garble == "function code":
            pdu = struct.pack(">BHH", 16, 0, 2)
        else:
            pdu = data[7:8] + bytes([data[8] - 2]) + data[9:-2]
        return struct.pack(">HHHB", tid, pid, len(pdu) + 1, unit) + pdu, b""
    proxy = proxy_for(fault=_only_first(0, 1, change))
    with PlcClient(*proxy.address, timeout_s=2.0) as client:
        client.read_holding_registers(ANY_REGISTER, 2)
        assert len(client.read_holding_registers(ANY_REGISTER, 2)) == 2  # garbled, read again
    assert proxy.connections == 2
