"""Soak: 10 clients command one PLC at once, with abrupt disconnects and a meddling client,
and every acknowledgement is checked (tests/modbus/conftest.py: soft PLC by default, a real
PLC with --plc-host; the PLC must have no other clients during the run).

Each client sends a random mix of commands whose result it predicts on its own (reachable and
unreachable targets, joints inside and outside the servos' travel, bad calibrations, unknown
codes, batches): a result taken from another client's command would not match. Some commands
are followed by an abrupt close of the client's connection (the answer is collected on a new
one), some by a half-sent request on a raw socket. A meddler writes whole, valid foreign
blocks into mailboxes other clients own. At the end the PLC's own count of answered blocks
must equal the sum of the answers the clients received: no command lost, none answered twice.

Duration: ARMBENCH_SOAK_SECONDS (default 15 s; CI keeps it under 60 s).
"""

from __future__ import annotations

import math
import os
import random
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from armbench.controller_client import (
    CMD_CLOSE,
    CMD_HELLO,
    CMD_MOVE_JOINTS,
    CMD_MOVE_XYZ,
    ERR_BAD_CALIBRATION,
    ERR_BAD_JOINT,
    ERR_JOINT_LIMIT,
    ERR_NOT_FINITE,
    ERR_OK,
    ERR_UNKNOWN_COMMAND,
    ERR_UNREACHABLE,
    ArmControllerClient,
    Calibration,
    Status,
)
from armbench.softplc.modbus_client import PlcClient

CLIENTS = 10
SECONDS = float(os.environ.get("ARMBENCH_SOAK_SECONDS", "15"))


class CountingPlcClient(PlcClient):
    """A PlcClient that counts its Modbus transactions."""

    transactions = 0

    def _check(self, request: Callable[[], Any], function: int,
               consistent: Callable[[Any], bool] | None = None) -> Any:
        self.transactions += 1
        return super()._check(request, function, consistent)


@dataclass
class Tally:
    commands: int = 0
    wrong: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    drops: int = 0
    half_frames: int = 0
    half_frames_not_sent: int = 0  # the saboteur could not connect: nothing sent
    answered: int = 0  # the client's blocks the PLC answered, as the client counted them


Step = tuple[str, Callable[[ArmControllerClient], Status | list[int]], int | list[int]]


def _steps(rng: random.Random) -> list[Step]:
    """(what, action, predicted result) of one random command, predicted from the arm's
    geometry and the servos' travel alone (zero offsets 0/70/65, +-60 deg)."""
    x, y, z = 120.0 + 60.0 * rng.random(), -40.0 + 80.0 * rng.random(), 90.0 + 60.0 * rng.random()
    b, s, e = -50.0 + 100.0 * rng.random(), 30.0 + 80.0 * rng.random(), 25.0 + 80.0 * rng.random()
    n = rng.randint(1, 32)
    batch = [((150.0, 0.0, 120.0 + i), ERR_OK) if rng.random() < 0.7
             else ((900.0 + i, 0.0, 100.0), ERR_UNREACHABLE) for i in range(n)]
    return [
        (f"MoveXyz{(x, y, z)}", lambda c: c.move_xyz(x, y, z), ERR_OK),
        ("MoveXyz far", lambda c: c.move_xyz(1000.0 + x, y, z), ERR_UNREACHABLE),
        ("MoveXyz NaN", lambda c: c.move_xyz(math.nan, y, z), ERR_NOT_FINITE),
        (f"MoveJoints{(b, s, e)}", lambda c: c.move_joints(b, s, e), ERR_OK),
        ("MoveJoints past travel", lambda c: c.move_joints(61.0 + abs(b), s, e),
         ERR_JOINT_LIMIT),
        ("SetCalibration min > max",
         lambda c: c.set_calibration(rng.randint(0, 2), Calibration(min_angle_deg=60.0,
                                                                    max_angle_deg=-60.0)),
         ERR_BAD_CALIBRATION),
        ("SetCalibration joint 6", lambda c: c.set_calibration(6, Calibration()), ERR_BAD_JOINT),
        ("unknown code 55", lambda c: c.command(55), ERR_UNKNOWN_COMMAND),
        ("Hello", lambda c: c.hello(), ERR_OK),
        (f"SolveBatch x{n}",
         lambda c: [p.error_id for p in c.solve_batch([t for t, _ in batch])],
         [r for _, r in batch]),
    ]


def _half_frame(address: tuple[str, int]) -> bool:
    """An FC16 request cut off half-way, then the socket closed. False when the saboteur's
    own connection could not be made (the real runtime's accept loop can leave a new
    connection waiting for seconds): then nothing was sent, and the clients under test are
    judged on their own."""
    pdu = struct.pack(">BHHB", 16, 2048, 4, 8) + b"\x00\x01\x00\x02\x00\x03\x00\x04"
    frame = struct.pack(">HHHB", 7, 0, len(pdu) + 1, 1) + pdu
    try:
        with socket.create_connection(address, timeout=2.0) as raw:
            raw.sendall(frame[: len(frame) // 2])
    except OSError:
        return False
    return True


def _client(address: tuple[str, int], flavor: str, seed: int, stop: threading.Event,
            tally: Tally, modbus: CountingPlcClient) -> None:
    rng = random.Random(seed)
    ctl = ArmControllerClient(modbus, timeout_s=10.0, flavor=flavor)
    try:
        modbus.connect()
        with ctl:
            while not stop.is_set():
                what, act, want = rng.choice(_steps(rng))
                roll = rng.random()
                if roll < 0.04 and not what.startswith("SolveBatch"):
                    # the block is written, then the connection dies before the answer
                    code = CMD_MOVE_JOINTS if what.startswith("MoveJoints(") else CMD_HELLO
                    args = (0.0, 70.0, 65.0) if code == CMD_MOVE_JOINTS else ()
                    pending = ctl.submit(code, args=args)
                    modbus.close()
                    tally.drops += 1
                    got: int | list[int] = ctl.wait(pending)
                    want = ERR_OK
                    what = f"dropped {what}"
                else:
                    if roll < 0.06:
                        if _half_frame(address):
                            tally.half_frames += 1
                        else:
                            tally.half_frames_not_sent += 1
                    elif roll < 0.08:
                        modbus.close()  # next request reconnects
                        tally.drops += 1
                    r = act(ctl)
                    got = r.error_id if isinstance(r, Status) else r
                tally.commands += 1
                if got != want:
                    tally.wrong.append(f"{what}: got {got}, predicted {want}")
    except Exception as exc:  # every failure is reported by the test, with its client
        tally.errors.append(f"client {seed}: {type(exc).__name__}: {exc}")
    finally:
        tally.answered = ctl.answered
        modbus.close()


def _meddler(address: tuple[str, int], flavor: str, stop: threading.Event,
             answered: list[int]) -> None:
    """Writes valid foreign blocks into owned mailboxes; if one lands in a mailbox freed in
    the meantime it has claimed it: it counts that answer and closes the mailbox again."""
    rng = random.Random(99)
    session = 1_999_999_999
    seq = 0
    with PlcClient(*address) as modbus:
        spy = ArmControllerClient(modbus, session=session, flavor=flavor)
        while not stop.wait(0.02):
            owned = [k for k, a in enumerate(spy.answers(), start=1) if a.owner not in (0,
                                                                                     session)]
            if not owned:
                continue
            k = rng.choice(owned)
            seq += 1
            address_, words = spy.block_words(k, seq, CMD_MOVE_XYZ, args=(150.0, 0.0, 120.0))
            modbus.write_registers(address_, words)
            time.sleep(0.05)
            a = spy.answer(k)
            if a.owner == session:  # claimed a just-freed mailbox: answered; give it back
                answered[0] += 1
                seq += 1
                address_, words = spy.block_words(k, seq, CMD_CLOSE)
                modbus.write_registers(address_, words)
                deadline = time.monotonic() + 2.0
                while spy.answer(k).ack_seq != seq and time.monotonic() < deadline:
                    time.sleep(0.005)
                answered[0] += 1


def test_ten_clients_with_disconnects(plc_address: tuple[str, int], plc_flavor: str) -> None:
    with PlcClient(*plc_address) as monitor_bus:
        monitor = ArmControllerClient(monitor_bus, flavor=plc_flavor)
        answered_before = monitor.status().commands_answered
        stop = threading.Event()
        tallies = [Tally() for _ in range(CLIENTS)]
        buses = [CountingPlcClient(*plc_address) for _ in range(CLIENTS)]
        meddled = [0]
        threads = [threading.Thread(target=_client, args=(plc_address, plc_flavor, i, stop,
                                                          tallies[i], buses[i]))
                   for i in range(CLIENTS)]
        threads.append(threading.Thread(target=_meddler,
                                        args=(plc_address, plc_flavor, stop, meddled)))
        t0 = time.monotonic()
        for t in threads:
            t.start()
        time.sleep(SECONDS)
        stop.set()
        for t in threads:
            t.join(timeout=30.0)
        elapsed = time.monotonic() - t0
        assert not any(t.is_alive() for t in threads), "a client hung"
        st = monitor.status()
    errors = [e for t in tallies for e in t.errors]
    wrong = [w for t in tallies for w in t.wrong]
    commands = sum(t.commands for t in tallies)
    acks = sum(b.transactions for b in buses)
    print(f"\nsoak: {CLIENTS} clients, {elapsed:.1f} s: {commands} commands checked, "
          f"{len(wrong)} wrong, {len(errors)} failed, "
          f"{sum(t.drops for t in tallies)} dropped connections, "
          f"{sum(t.half_frames for t in tallies)} half frames "
          f"({sum(t.half_frames_not_sent for t in tallies)} more not sent: no connection), "
          f"{st.commands_ignored} foreign "
          f"blocks ignored; {acks} Modbus transactions = {acks / elapsed:.0f} tx/s, "
          f"{commands / elapsed:.0f} commands/s")
    assert errors == []
    assert wrong == []
    assert commands > 20 * CLIENTS
    # The clients' answers, counted on their side, are exactly the PLC's answered blocks: no
    # command was lost and none was answered twice (Busy answers, Hello claims and Close
    # included on both sides).
    client_answers = sum(t.answered for t in tallies)
    assert st.commands_answered - answered_before == client_answers + meddled[0]
