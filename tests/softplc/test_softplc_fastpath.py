"""The compiled request path (softplc/modbus_fast.c) against the Python one (PduHandler).

The OpenPLC behaviour itself is pinned by tests/modbus/test_modbus_openplc_parity.py (it runs
on the compiled path, the soft PLC's default) and the other tests in this folder (which run
on both, through the ``scan_lock`` fixture). Here the two implementations get the same
requests on the same image -- every function code, addresses and quantities around every
limit, broken byte counts and lengths -- and must give the same reply and leave the same
bytes in the image.
"""

from __future__ import annotations

import random
import socket
import struct
import threading
import time

import pytest

from armbench.softplc import ImageLock, ModbusServer, PduHandler, ProcessImage
from armbench.softplc.fastpath import FastHandler
from armbench.softplc.image import IMAGE_SIZE

# Around every table end and area boundary: 0, %MW, %MD, %ML starts, 1024 (input registers),
# 8192 (coils, discrete inputs, holding registers), 65535.
EDGES = (0, 1, 7, 8, 1023, 1024, 1025, 2047, 2048, 2049, 4095, 4096, 4097, 8064, 8184, 8185,
         8190, 8191, 8192, 8193, 65535)
QUANTITIES = (0, 1, 2, 3, 4, 5, 7, 8, 9, 123, 125, 126, 127, 128, 2000, 2040, 2041, 2048,
              65535)


def random_pdu(rng: random.Random) -> bytes:
    function = rng.choice((1, 2, 3, 4, 5, 6, 15, 16, 0, 7, 17, 0x83, 0x90, 255))
    address = rng.choice(EDGES) if rng.random() < 0.7 else rng.randrange(65536)
    quantity = rng.choice(QUANTITIES) if rng.random() < 0.7 else rng.randrange(65536)
    if function in (15, 16) and rng.random() < 0.8:
        nbytes = (quantity + 7) // 8 if function == 15 else 2 * quantity
        if rng.random() < 0.2:
            nbytes += rng.choice((-1, 1))  # a byte count that does not match
        nbytes &= 0xFF
        data = rng.randbytes(nbytes + rng.choice((0, 0, 0, -1, 3)) if nbytes else 0)
        pdu = struct.pack(">BHHB", function, address, quantity, nbytes) + data
    else:
        pdu = struct.pack(">BHH", function, address, quantity)
    if rng.random() < 0.1:
        pdu = pdu[: rng.randrange(1, len(pdu) + 1)]  # short PDUs
    return pdu


def test_same_replies_and_same_image_as_the_python_path() -> None:
    rng = random.Random(12)
    start = rng.randbytes(IMAGE_SIZE)
    slow_image, fast_image = ProcessImage.allocate(), ProcessImage.allocate()
    slow_image.restore(start)
    fast_image.restore(start)
    slow = PduHandler(slow_image, threading.Lock())
    fast = FastHandler(fast_image, ImageLock())
    functions: dict[int, int] = {}
    for _ in range(30_000):
        pdu = random_pdu(rng)
        want = slow.handle(pdu)
        assert fast.handle(pdu) == want, f"request {pdu.hex()}"
        functions[want[0]] = functions.get(want[0], 0) + 1
    assert fast_image.snapshot() == slow_image.snapshot()
    assert fast_image.snapshot() != start  # the writes did land
    # every normal reply and every exception reply occurred
    for f in (1, 2, 3, 4, 5, 6, 15, 16):
        assert functions.get(f, 0) > 50 and functions.get(f | 0x80, 0) > 50, functions


def test_wide_values_are_written_word_by_word_like_the_python_path() -> None:
    """FC6 on one word of a REAL or LREAL keeps the other words; FC16 across areas."""
    for pdu in (struct.pack(">BHH", 6, 2049, 0xBEEF), struct.pack(">BHH", 6, 4098, 0x1234),
                struct.pack(">BHHB5H", 16, 2046, 5, 10, 1, 2, 3, 4, 5),
                struct.pack(">BHHB4H", 16, 4094, 4, 8, 9, 8, 7, 6)):
        images = [ProcessImage.allocate() for _ in range(2)]
        for image in images:
            image.raw[:] = bytes(range(256)) * (IMAGE_SIZE // 256)
        assert FastHandler(images[0], ImageLock()).handle(pdu) == \
            PduHandler(images[1], threading.Lock()).handle(pdu) == pdu[:5]
        assert images[0].snapshot() == images[1].snapshot()


# -- ImageLock: threading.Lock's interface -------------------------------------------------


def test_image_lock_behaves_like_threading_lock() -> None:
    lock = ImageLock()
    assert not lock.locked()
    with lock:
        assert lock.locked()
        assert lock.acquire(False) is False
        t0 = time.monotonic()
        assert lock.acquire(timeout=0.05) is False
        assert time.monotonic() - t0 >= 0.04
    assert not lock.locked()
    with pytest.raises(RuntimeError, match="release unlocked lock"):
        lock.release()
    with pytest.raises(ValueError):
        lock.acquire(False, timeout=1.0)
    # another thread may release it (threading.Lock allows that too)
    assert lock.acquire()
    releaser = threading.Thread(target=lock.release)
    releaser.start()
    releaser.join(5)
    assert lock.acquire(timeout=5.0)
    lock.release()


def test_a_thread_waiting_for_the_image_lock_does_not_hold_the_gil() -> None:
    lock = ImageLock()
    lock.acquire()
    waiter = threading.Thread(target=lambda: (lock.acquire(), lock.release()))
    waiter.start()
    time.sleep(0.05)  # the waiter now blocks in C
    counted = 0
    deadline = time.monotonic() + 0.2
    while time.monotonic() < deadline:  # this thread still runs Python
        counted += 1
    lock.release()
    waiter.join(5)
    assert not waiter.is_alive() and counted > 1000


# -- which path a server takes ---------------------------------------------------------------


def test_server_path_follows_the_lock() -> None:
    image = ProcessImage.allocate()
    assert ModbusServer(image, port=0).fast_path
    assert ModbusServer(image, ImageLock(), port=0).fast_path
    assert not ModbusServer(image, threading.Lock(), port=0).fast_path
    assert not ModbusServer(image, ImageLock(), port=0, fast_path=False).fast_path


def test_compiled_path_answers_pipelined_frames_and_drops_broken_framing() -> None:
    image = ProcessImage.allocate()
    with ModbusServer(image, port=0) as srv, socket.create_connection(srv.address, 5) as s:
        assert srv.fast_path
        frames = b"".join(struct.pack(">HHHBBHHB2H", t, 0, 11, 1, 16, 1024 + t, 2, 4, t, 7)
                          for t in range(1, 41))
        s.sendall(frames)  # 40 requests in one go
        expected = b"".join(struct.pack(">HHHBBHH", t, 0, 6, 1, 16, 1024 + t, 2)
                            for t in range(1, 41))
        got = b""
        while len(got) < len(expected):
            chunk = s.recv(4096)
            assert chunk
            got += chunk
        assert got == expected
        # in order: each request's second word is overwritten by the next request's first
        assert list(image.mw[1:42]) == [*range(1, 41), 7]
        s.sendall(struct.pack(">HHHBBHH", 99, 1, 6, 1, 3, 0, 1))  # protocol id 1
        assert s.recv(100) == b""  # dropped, as the Python path does
