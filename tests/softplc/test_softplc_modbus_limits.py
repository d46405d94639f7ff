"""Connection limits of the Modbus server: idle timeout, a full connection table that never
locks a new client out, trickling and non-reading peers, no leaked threads or descriptors,
and the warning for a non-loopback address.

Timeouts here are a few tenths of a second; the upper bounds on "closed within" are loose
(several seconds) so that a loaded machine does not fail them, the lower bounds are exact
because the server must never close a connection before its timeout.
"""

from __future__ import annotations

import logging
import os
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from softplc_fakes import MBAP, closed_by_peer, frame, recv_reply

from armbench.softplc import ModbusServer, ProcessImage
from armbench.softplc.modbus_client import PlcClient
from armbench.softplc.modbus_server import (
    DEFAULT_IDLE_TIMEOUT_S,
    DEFAULT_MAX_CLIENTS,
    non_loopback_warning,
)

READ_QW0 = struct.pack(">BHH", 3, 0, 1)
READ_127 = struct.pack(">BHH", 3, 0, 127)  # 12-byte request, 263-byte reply
IDLE_S = 0.3
SLACK_S = 5.0  # upper bound for "closed after the timeout" on a busy machine


def connect(server: ModbusServer, timeout_s: float = 5.0) -> socket.socket:
    return socket.create_connection(("127.0.0.1", server.port), timeout=timeout_s)


def served(sock: socket.socket, transaction: int = 7) -> bool:
    sock.sendall(frame(READ_QW0, transaction=transaction))
    return recv_reply(sock) == (transaction, b"\x03\x02\x00\x00")


def time_until_closed(sock: socket.socket, since: float) -> float:
    assert closed_by_peer(sock, SLACK_S), "the server kept the connection open"
    return time.monotonic() - since


def wait_for(condition: str, check: Callable[[], bool], timeout_s: float = SLACK_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not check():
        assert time.monotonic() < deadline, condition
        time.sleep(0.005)


def closed_after_draining(sock: socket.socket) -> bool:
    """True if the server closed ``sock``; replies still unread are skipped."""
    sock.settimeout(SLACK_S)
    try:
        while sock.recv(4096):
            pass
    except ConnectionResetError:
        pass
    except TimeoutError:
        return False
    return True


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.fixture
def short_idle(image: ProcessImage) -> Iterator[ModbusServer]:
    with ModbusServer(image, port=0, idle_timeout_s=IDLE_S) as srv:
        yield srv


# -- the reported defect: 64 idle connections lock everyone out ---------------------------


def test_64_idle_connections_do_not_lock_out_a_new_client(image: ProcessImage) -> None:
    with ModbusServer(image, port=0) as srv:  # the defaults, as `armbench serve` runs
        idle = [connect(srv) for _ in range(DEFAULT_MAX_CLIENTS)]
        try:
            wait_for("64 connections served", lambda: srv.client_count == DEFAULT_MAX_CLIENTS)
            with PlcClient(port=srv.port, timeout_s=5) as client:
                client.write_register(0, 1234)
                assert client.read_holding_registers(0) == [1234]
            # Room was made by closing exactly one of the idle connections: the oldest.
            assert closed_by_peer(idle[0])
            idle[1].settimeout(0.05)
            with pytest.raises(TimeoutError):
                idle[1].recv(1)
        finally:
            for sock in idle:
                sock.close()


def test_full_table_closes_the_connection_idle_longest(image: ProcessImage) -> None:
    with ModbusServer(image, port=0, max_clients=3, idle_timeout_s=None) as srv:
        a, b, c = connect(srv), connect(srv), connect(srv)
        try:
            for n, sock in enumerate((a, b, c)):
                assert served(sock, n)
            assert served(a, 10)  # a is now the most recently active; b idle longest
            with connect(srv) as d:
                assert served(d, 11)
                assert closed_by_peer(b)
                assert served(a, 12) and served(c, 13)
        finally:
            for sock in (a, b, c):
                sock.close()


def test_accepting_does_not_wait_for_the_scan_lock(
    image: ProcessImage, scan_lock: threading.Lock
) -> None:
    with ModbusServer(image, scan_lock, port=0, max_clients=2, idle_timeout_s=None) as srv:
        with scan_lock:  # a scan that takes for ever
            first = connect(srv)
            first.sendall(frame(READ_QW0, transaction=1))  # its thread now waits for the lock
            later = [connect(srv) for _ in range(3)]
            # The accept thread kept accepting and evicting: first and later[0] made room.
            assert closed_by_peer(later[0])
            first.settimeout(SLACK_S)
            with pytest.raises(OSError):  # closed without an answer (EOF raises in recv_reply)
                recv_reply(first)
        try:
            assert served(later[1], 2) and served(later[2], 3)
        finally:
            for sock in (first, *later):
                sock.close()


# -- idle timeout ---------------------------------------------------------------------------


# The clocks below start before the connect: the server's starts at its accept, which a
# loaded machine may run before this process returns from connect().


def test_idle_connection_closed_after_timeout(short_idle: ModbusServer) -> None:
    start = time.monotonic()
    with connect(short_idle) as sock:
        assert IDLE_S <= time_until_closed(sock, start)


def test_timeout_counts_from_the_last_complete_request(short_idle: ModbusServer) -> None:
    with connect(short_idle) as sock:
        # Requests every IDLE_S / 3 for 3 * IDLE_S keep it open ...
        for i in range(9):
            assert served(sock, i)
            time.sleep(IDLE_S / 3)
        last = time.monotonic()
        assert served(sock, 99)
        # ... and it closes IDLE_S after the last one, not after the connect.
        assert IDLE_S <= time_until_closed(sock, last)


@pytest.mark.parametrize(
    "partial",
    [b"\x00\x01\x00", MBAP.pack(1, 0, 6, 1), MBAP.pack(1, 0, 6, 1) + READ_QW0[:3]],
    ids=["half-header", "header-only", "half-pdu"],
)
def test_partial_request_then_silence_is_closed(short_idle: ModbusServer, partial: bytes) -> None:
    start = time.monotonic()
    with connect(short_idle) as sock:
        sock.sendall(partial)
        assert IDLE_S <= time_until_closed(sock, start)


def test_trickling_one_byte_at_a_time_is_closed(short_idle: ModbusServer) -> None:
    # A frame as long as the server accepts, sent one byte every 20 ms: bytes keep arriving
    # but no request ever completes.
    trickle = MBAP.pack(1, 0, 9994, 1) + bytes(9993)
    period = 0.02
    start = time.monotonic()
    with connect(short_idle) as sock, selectors.DefaultSelector() as sel:
        sel.register(sock, selectors.EVENT_READ)
        sent = 0
        last_sent = start
        closed = False
        while not closed and time.monotonic() - start < SLACK_S:
            try:
                sock.sendall(trickle[sent : sent + 1])
                sent += 1
                last_sent = time.monotonic()
            except OSError:  # reset: the server closed it
                closed = True
                break
            if sel.select(period):
                try:
                    closed = sock.recv(1) == b""
                except ConnectionResetError:
                    closed = True
        elapsed = time.monotonic() - start
    assert closed, "the server kept the connection open"
    assert IDLE_S <= elapsed < SLACK_S
    # Bytes kept arriving until (about) the timeout, and it was closed all the same.
    assert last_sent - start >= IDLE_S - 2 * period


def test_peer_that_never_reads_replies_is_closed(image: ProcessImage) -> None:
    with ModbusServer(image, port=0, idle_timeout_s=IDLE_S) as srv:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect(("127.0.0.1", srv.port))
        try:
            # Pipeline requests without reading a reply until both directions are full: the
            # server thread is then stuck in sendall (and no longer reads).
            sock.setblocking(False)
            burst = frame(READ_127) * 1000
            sent = 0
            stuck_since = time.monotonic()
            while time.monotonic() - stuck_since < 0.2:
                try:
                    sent += sock.send(burst)
                    stuck_since = time.monotonic()
                except BlockingIOError:
                    time.sleep(0.01)
                except OSError:  # already closed by the server
                    break
            # Far more replies than the socket buffers hold: the server did get stuck.
            assert sent // len(frame(READ_127)) * 263 > 16 * 2**20
            wait_for("the stuck connection thread ended", lambda: srv.client_count == 0)
        finally:
            sock.close()


def test_timeout_off_keeps_idle_connections(image: ProcessImage) -> None:
    for off in (None, 0.0):
        with ModbusServer(image, port=0, idle_timeout_s=off) as srv, connect(srv) as sock:
            assert srv.idle_timeout_s is None
            time.sleep(2 * IDLE_S)
            assert served(sock)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"idle_timeout_s": -1.0}, "idle timeout"),
        ({"idle_timeout_s": float("nan")}, "idle timeout"),
        ({"max_clients": 0}, "max_clients"),
    ],
)
def test_bad_limits_are_rejected(
    image: ProcessImage, kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        ModbusServer(image, port=0, **kwargs)


def test_defaults() -> None:
    # The values documented in docs/modbus-parity.md and `armbench serve --help`.
    assert (DEFAULT_IDLE_TIMEOUT_S, DEFAULT_MAX_CLIENTS) == (300.0, 64)
    srv = ModbusServer(ProcessImage.allocate())
    assert (srv.idle_timeout_s, srv.max_clients) == (300.0, 64)


# -- no leaks -------------------------------------------------------------------------------


def test_hundreds_of_abandoned_connections_leak_nothing(image: ProcessImage) -> None:
    threads_before = set(threading.enumerate())
    fds_before = open_fds()
    srv = ModbusServer(image, port=0, max_clients=16, idle_timeout_s=IDLE_S)
    srv.start()
    kept: list[socket.socket] = []
    try:
        for i in range(400):
            sock = connect(srv)
            kind = i % 5
            if kind == 1:
                sock.sendall(MBAP.pack(i, 0, 6, 1)[:4])  # a partial header
            elif kind == 2:
                assert served(sock, i)
            elif kind == 3:
                sock.sendall(frame(READ_QW0) * 3)  # requests whose replies nobody reads
            if kind == 4:
                sock.close()  # closed by the client at once
            else:
                kept.append(sock)  # abandoned: left open, never used again
            # Bounded however many clients come and go: the table, plus connections that
            # were just shut down and whose threads are on their way out.
            assert threading.active_count() <= len(threads_before) + 3 * 16 + 2
        with connect(srv) as last:  # still no one locked out
            assert served(last)
        wait_for("every connection timed out", lambda: srv.client_count == 0)
        for sock in kept:
            assert closed_after_draining(sock)
    finally:
        for sock in kept:
            sock.close()
        srv.stop()
    assert set(threading.enumerate()) == threads_before
    assert open_fds() == fds_before


# -- non-loopback warning -------------------------------------------------------------------


def test_non_loopback_address_is_warned_about(
    image: ProcessImage, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING), ModbusServer(image, host="0.0.0.0", port=0) as srv:
        warning = srv.exposure_warning
    assert warning is not None
    assert "all network interfaces" in warning
    assert "any host" in warning and "move the servos" in warning
    assert [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING] == [warning]


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2", "localhost"])
def test_loopback_addresses_are_not_warned_about(
    image: ProcessImage, caplog: pytest.LogCaptureFixture, host: str
) -> None:
    with caplog.at_level(logging.WARNING), ModbusServer(image, host=host, port=0) as srv:
        assert srv.exposure_warning is None
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.mark.parametrize(
    ("host", "exposed"),
    [("0.0.0.0", True), ("192.168.1.20", True), ("10.0.0.1", True), ("127.0.0.1", False),
     ("127.255.0.9", False)],
)
def test_which_addresses_count_as_exposed(host: str, exposed: bool) -> None:
    warning = non_loopback_warning(host, 502)
    assert (warning is not None) == exposed
    if warning is not None:
        assert f"{host}:502" in warning
