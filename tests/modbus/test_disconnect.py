"""Clients that go away mid-command (tests/modbus/conftest.py).

The mailbox handshake's promise: a block runs only when it arrived whole (its Check matches)
and new (its Seq not yet answered), so a client that stops half-way through writing a command
block leaves the arm untouched, and the PLC keeps serving the next client; a command whose
block arrived whole is executed even when its client disconnects at once, exactly once, and
the client (or its reconnection) reads its answer.
"""

from __future__ import annotations

import math
import socket
import struct
import time

import numpy as np

from armbench.controller_client import (
    CMD_MOVE_JOINTS,
    ERR_BAD_CHECK,
    ArmControllerClient,
    Status,
)
from armbench.plant import arm
from armbench.softplc.modbus_client import PlcClient

SCANS = 5  # scans to wait before concluding "nothing happened"
ACCEPT_PERIOD_S = 0.15  # OpenPLC v3 accepts a pending connection every 100 ms


def _client(address: tuple[str, int], flavor: str) -> tuple[PlcClient, ArmControllerClient]:
    modbus = PlcClient(*address)
    modbus.connect()
    return modbus, ArmControllerClient(modbus, flavor=flavor)


def _snapshot(ctl: ArmControllerClient) -> tuple[Status, list[int]]:
    st = ctl.status()
    return st, ctl.channel_words()


def _unchanged(ctl: ArmControllerClient, before: tuple[Status, list[int]]) -> None:
    st, words = _snapshot(ctl)
    b = before[0]
    assert (st.joints_deg, st.echo_mm, st.pulses_us) == (b.joints_deg, b.echo_mm, b.pulses_us)
    assert words == before[1]


def _nothing_ran(address: tuple[str, int], flavor: str,
                 before: tuple[Status, list[int]]) -> None:
    """A new client sees the state from before, after a few scans, and is served."""
    modbus, ctl = _client(address, flavor)
    try:
        ctl.wait_scans(SCANS)
        _unchanged(ctl, before)
    finally:
        modbus.close()
    _serves_a_new_client(address, flavor)


def _serves_a_new_client(address: tuple[str, int], flavor: str) -> None:
    modbus, ctl = _client(address, flavor)
    with modbus, ctl:
        target = (155.0, -12.0, 118.0)
        st = ctl.move_xyz(*target)
        assert st.error_id == 0
        assert math.dist(target, st.echo_mm) <= 0.05
        assert math.dist(target, arm.forward(*st.joints_deg)) <= 0.05


def test_half_block_of_single_writes_then_disconnect(plc_address: tuple[str, int],
                                                     plc_flavor: str) -> None:
    modbus, ctl = _client(plc_address, plc_flavor)
    ctl.move_xyz(150.0, 0.0, 120.0, wait=True)
    before = _snapshot(ctl)
    # A MoveJoints to another pose, written the wrong way: FC06, one register at a time; the
    # client dies after the new Seq, Code and one half of Arg1 -- Check never written.
    address, words = ctl.block_words(ctl.open(), before[0].ack_seq + 1, CMD_MOVE_JOINTS,
                                     args=(30.0, 80.0, 70.0))
    for i in (0, 1, 4, 5, 10):  # Seq, Code, first word of Arg1
        modbus.write_register(address + i, words[i])
    ctl.wait_scans(SCANS)
    mailbox = ctl.mailbox
    assert mailbox is not None
    answer = ctl.answer(mailbox)  # the owner is told: the block was not whole
    assert (answer.ack_seq, answer.result) == (before[0].ack_seq + 1, ERR_BAD_CHECK)
    modbus.close()

    _nothing_ran(plc_address, plc_flavor, before)


def test_socket_closed_in_the_middle_of_a_request(plc_address: tuple[str, int],
                                                  plc_flavor: str) -> None:
    modbus, ctl = _client(plc_address, plc_flavor)
    with modbus, ctl:
        ctl.move_xyz(150.0, 0.0, 120.0, wait=True)
        before = _snapshot(ctl)
        address, words = ctl.block_words(ctl.open(), before[0].ack_seq + 1, CMD_MOVE_JOINTS,
                                         args=(30.0, 80.0, 70.0))
        # The same FC16 request the client would send, cut off half-way through its data.
        pdu = struct.pack(">BHHB", 16, address, len(words), 2 * len(words))
        pdu += struct.pack(f">{len(words)}H", *words)
        frame = struct.pack(">HHHB", 0x4242, 0, len(pdu) + 1, 1) + pdu
        with socket.create_connection(plc_address, timeout=3.0) as raw:
            raw.sendall(frame[: len(frame) // 2])
        # The raw connection gets no reply, so nothing shows when the PLC has accepted it.
        # OpenPLC v3's server polls accept() every 100 ms and, when two connections are
        # pending at once, can hand both threads the same socket (a known OpenPLC race), so
        # the next client would be lost. Give it one accept period (plus margin) to take the
        # raw connection first; the soft PLC does not need this.
        time.sleep(ACCEPT_PERIOD_S)
        ctl.wait_scans(SCANS)
        _unchanged(ctl, before)
    _nothing_ran(plc_address, plc_flavor, before)


def test_disconnect_right_after_sending_a_command(plc_address: tuple[str, int],
                                                  plc_flavor: str) -> None:
    """The block arrived whole: it runs once, and the client's reconnection finds its answer."""
    modbus, ctl = _client(plc_address, plc_flavor)
    with modbus, ctl:
        ctl.move_joints(0.0, 70.0, 65.0)
        answered = ctl.status().commands_answered
        pending = ctl.submit(CMD_MOVE_JOINTS, args=(20.0, 75.0, 60.0))
        modbus.close()  # gone before the answer; the next request reconnects
        assert ctl.wait(pending) == 0
        st = ctl.status()
        assert st.joints_deg == (20.0, 75.0, 60.0)
        assert st.commands_answered == answered + 1  # the move, nothing else, ran once


def test_disconnect_right_after_sending_a_batch(plc_address: tuple[str, int],
                                                plc_flavor: str) -> None:
    targets = [(140.0 + i, -20.0 + 2.0 * i, 100.0 + 1.5 * i) for i in range(20)]
    modbus, ctl = _client(plc_address, plc_flavor)
    with modbus, ctl, ctl.batch_buffer():
        pending = ctl.submit_batch(targets)  # written, not waited for
        modbus.close()
        assert ctl.wait(pending) == 0
        st = ctl.status()
        assert st.batch_count == len(targets) and st.batch_failures == 0
        res = ctl.batch_results(len(targets))
    want = np.array(targets)
    ref = arm.forward_batch(np.array([r.joints_deg for r in res]))
    assert np.max(np.linalg.norm(ref - want, axis=1)) <= 0.05
    assert np.max(np.linalg.norm(np.array([r.echo_mm for r in res]) - want, axis=1)) <= 0.05
    _serves_a_new_client(plc_address, plc_flavor)
