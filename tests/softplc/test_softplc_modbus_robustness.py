"""Malformed frames, pipelining, concurrent clients and clean shutdown of the Modbus server."""

from __future__ import annotations

import random
import socket
import struct
import threading
import time

import pytest
from softplc_fakes import MBAP, closed_by_peer, frame, raw_call, recv_exact, recv_reply

from armbench.softplc import ModbusServer, ProcessImage
from armbench.softplc.modbus_client import PlcClient

READ_QW0 = struct.pack(">BHH", 3, 0, 1)


def still_serving(server: ModbusServer) -> None:
    assert raw_call(server.port, READ_QW0)[:2] == b"\x03\x02"


def connect(server: ModbusServer) -> socket.socket:
    return socket.create_connection(("127.0.0.1", server.port), timeout=5)


@pytest.mark.parametrize(
    "garbage",
    [
        b"\x00",  # short header, then EOF
        b"\x00\x01\x00\x00\x00",
        MBAP.pack(1, 0, 6, 1),  # header only, PDU never comes
    ],
)
def test_truncated_frame_then_close(server: ModbusServer, garbage: bytes) -> None:
    with connect(server) as sock:
        sock.sendall(garbage)
    still_serving(server)


@pytest.mark.parametrize(
    "bad_header",
    [
        MBAP.pack(1, 1, 6, 1) + READ_QW0,  # protocol id must be 0
        MBAP.pack(1, 0xFFFF, 6, 1) + READ_QW0,
        MBAP.pack(1, 0, 0, 1) + READ_QW0,  # length shorter than unit id + function code
        MBAP.pack(1, 0, 1, 1) + READ_QW0,
        MBAP.pack(1, 0, 9995, 1) + READ_QW0,  # longer than OpenPLC's 10000-byte frame buffer
        MBAP.pack(1, 0, 0xFFFF, 1) + READ_QW0,
    ],
)
def test_bad_header_drops_only_that_connection(server: ModbusServer, bad_header: bytes) -> None:
    with connect(server) as bystander, connect(server) as sock:
        sock.sendall(bad_header)
        assert closed_by_peer(sock)
        bystander.sendall(frame(READ_QW0, transaction=9))
        assert recv_reply(bystander) == (9, b"\x03\x02\x00\x00")


def test_length_too_long_stalls_only_that_connection(server: ModbusServer) -> None:
    with connect(server) as liar:
        # Announces 20 PDU bytes and sends 5: the server must wait for the rest, not guess.
        liar.sendall(MBAP.pack(1, 0, 21, 1) + READ_QW0)
        liar.settimeout(0.2)
        with pytest.raises(TimeoutError):
            liar.recv(1)
        still_serving(server)


def test_length_too_short_inside_frame_is_exception(server: ModbusServer) -> None:
    with connect(server) as sock:
        # Length covers only 3 PDU bytes of a 5-byte read: the server sees a short FC3 PDU
        # (exception 3), then the stray 2 bytes start a header that never completes.
        sock.sendall(MBAP.pack(4, 0, 4, 1) + READ_QW0)
        assert recv_reply(sock) == (4, b"\x83\x03")
    still_serving(server)


def test_pipelined_and_split_frames(image: ProcessImage, server: ModbusServer) -> None:
    image.qw[0] = 0x0102
    with connect(server) as sock:
        burst = b"".join(frame(READ_QW0, transaction=t) for t in range(1, 6))
        sock.sendall(burst)
        assert [recv_reply(sock) for _ in range(5)] == [
            (t, b"\x03\x02\x01\x02") for t in range(1, 6)
        ]
        for byte in frame(READ_QW0, transaction=77):  # one byte per segment
            sock.sendall(bytes([byte]))
        assert recv_reply(sock) == (77, b"\x03\x02\x01\x02")


def test_unit_id_and_transaction_echoed(server: ModbusServer) -> None:
    with connect(server) as sock:
        sock.sendall(frame(READ_QW0, transaction=0xBEEF, unit=0xF7))
        # length 5 = unit id + the 4-byte reply PDU
        assert MBAP.unpack(recv_exact(sock, 7)) == (0xBEEF, 0, 5, 0xF7)


def test_random_frames_never_kill_the_server(server: ModbusServer) -> None:
    rng = random.Random(61131)
    for i in range(300):
        length = rng.choice([rng.randint(0, 300), rng.randint(2, 12)])
        protocol = 0 if rng.random() < 0.8 else rng.randint(0, 0xFFFF)
        pdu = bytes(rng.randint(0, 255) for _ in range(rng.randint(0, 20)))
        if rng.random() < 0.7:
            pdu = bytes([rng.choice([1, 2, 3, 4, 5, 6, 15, 16, rng.randint(0, 255)])]) + pdu
        with connect(server) as sock:
            sock.sendall(MBAP.pack(i, protocol, length, 1) + pdu)
            sock.shutdown(socket.SHUT_WR)
            sock.settimeout(5)
            while sock.recv(4096):  # drain whatever it answers until it closes
                pass
    still_serving(server)


def test_concurrent_clients(image: ProcessImage, server: ModbusServer) -> None:
    errors: list[BaseException] = []

    def worker(n: int) -> None:
        try:
            with PlcClient(port=server.port, timeout_s=10) as c:
                for i in range(100):
                    c.write_registers(1024 + 4 * n, [n, i, n, i])
                    assert c.read_holding_registers(1024 + 4 * n, 4) == [n, i, n, i]
                    c.write_real(n, float(i))
                    assert c.read_real(n) == float(i)
        except BaseException as exc:  # reported to the main thread below
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(n,)) for n in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors
    assert [image.mw[4 * n + 1] for n in range(8)] == [99] * 8


def test_client_limit_closes_the_longest_idle(image: ProcessImage) -> None:
    with ModbusServer(image, port=0, max_clients=2) as srv:
        with connect(srv) as a, connect(srv) as b:
            for s in (a, b):
                s.sendall(frame(READ_QW0))
                recv_reply(s)
            with connect(srv) as c:
                # The table is full: c is served, a (idle longest) makes room, b stays.
                c.sendall(frame(READ_QW0, transaction=3))
                assert recv_reply(c) == (3, b"\x03\x02\x00\x00")
                assert closed_by_peer(a)
                b.sendall(frame(READ_QW0, transaction=2))
                assert recv_reply(b) == (2, b"\x03\x02\x00\x00")
        # The slots free up once the server threads have seen b and c close.
        deadline = time.monotonic() + 10
        while srv.client_count:
            assert time.monotonic() < deadline
            time.sleep(0.001)
        still_serving(srv)


def test_port_zero_and_fixed_port(image: ProcessImage) -> None:
    with ModbusServer(image, port=0) as srv:
        port = srv.port
        assert port > 0 and srv.address == ("127.0.0.1", port)
    with ModbusServer(image, port=port) as srv:  # rebinding right after stop works
        assert srv.port == port
        still_serving(srv)


def test_stop_closes_everything(image: ProcessImage) -> None:
    before = set(threading.enumerate())
    srv = ModbusServer(image, port=0)
    srv.start()
    idle = connect(srv)
    stalled = connect(srv)
    stalled.sendall(MBAP.pack(1, 0, 21, 1))
    with PlcClient(port=srv.port) as c:
        c.write_register(0, 1)
        srv.stop()
    assert closed_by_peer(idle) and closed_by_peer(stalled)
    idle.close()
    stalled.close()
    assert set(threading.enumerate()) == before
    srv.stop()  # idempotent
    with pytest.raises(RuntimeError):
        _ = srv.port
