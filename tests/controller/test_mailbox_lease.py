"""Mailbox leases on the soft PLC with a fast clock: the controller's 10 ms task is stepped as
fast as the host runs it (simulated time), so the 1000-scan lease passes in well under a
second of wall time. Not part of the Modbus suite: a real PLC takes the full 10 s."""

from __future__ import annotations

import time

import pytest
from fast_plc import FastPlc

from armbench.controller_client import (
    CMD_MOVE_JOINTS,
    CMD_RESERVE_BATCH,
    ERR_OK,
    LEASE_SCANS,
    ArmControllerClient,
    HandshakeLost,
)
from armbench.softplc.modbus_client import PlcClient


def test_silent_owner_loses_mailbox_and_batch_buffer(fast_controller: FastPlc) -> None:
    with PlcClient(*fast_controller.address) as modbus:
        a = ArmControllerClient(modbus)
        assert a.command(CMD_RESERVE_BATCH).error_id == ERR_OK
        k = a.mailbox
        assert k is not None and a.status().batch_owner == k
        a.wait_scans(LEASE_SCANS // 2, timeout_s=20.0)
        assert a.answer(k).owner == a.session  # half a lease: still held
        a.wait_scans(LEASE_SCANS // 2 + 10, timeout_s=20.0)
        assert a.answer(k).owner == 0
        assert a.status().batch_owner == 0
        # a client that comes back after its lease simply claims a mailbox again
        assert a.move_joints(1.0, 70.0, 65.0).error_id == ERR_OK


def test_renewed_lease_is_kept(fast_controller: FastPlc) -> None:
    with PlcClient(*fast_controller.address) as modbus, ArmControllerClient(modbus) as a:
        a.hello()
        k = a.mailbox
        for _ in range(3):
            a.wait_scans(LEASE_SCANS * 2 // 3, timeout_s=20.0)
            assert a.hello().error_id == ERR_OK
            assert a.mailbox == k and a.answer(k).owner == a.session


def test_a_client_silent_past_the_lease_is_told_it_cannot_know(
        fast_controller: FastPlc) -> None:
    """Its command ran, the mailbox expired and was taken over, and only then did it look:
    the client must not guess (resend = run twice, give up = maybe lost)."""
    with PlcClient(*fast_controller.address) as modbus:
        a = ArmControllerClient(modbus)
        a.hello()
        k = a.mailbox
        assert k is not None
        pending = a.submit(CMD_MOVE_JOINTS, args=(3.0, 70.0, 65.0))
        a.wait_scans(LEASE_SCANS + 20, timeout_s=20.0)  # answered, then the lease ran out
        # The client judges the lease in wall time from the scan period it measured when it
        # opened the mailbox; a real PLC never scans faster than its task interval, but this
        # free-running clock does when the host gets less busy. Stay silent long enough for
        # any period the host's load can have shown at open() (up to 16x the nominal one).
        time.sleep(2.0)
        b = ArmControllerClient(modbus)
        address, words = b.block_words(k, 5, 10)  # b claims exactly that mailbox (Hello)
        modbus.write_registers(address, words)
        b.wait_scans(3, timeout_s=20.0)
        assert b.answer(k).owner == b.session
        with pytest.raises(HandshakeLost, match="may or may not have run"):
            a.wait(pending)


def test_an_answer_outlives_the_lease_and_a_stalled_owner_is_not_misled(
        fast_controller: FastPlc) -> None:
    """A stalled connection (OpenPLC's accept loop can leave one unserved for seconds) is
    harmless while the mailbox is still the client's, and an answer that arrived before the
    lease ran out still counts afterwards: only a mailbox taken over is undecidable."""
    with PlcClient(*fast_controller.address) as modbus:
        a = ArmControllerClient(modbus)
        a.hello()
        k = a.mailbox
        pending = a.submit(CMD_MOVE_JOINTS, args=(4.0, 70.0, 65.0))
        a.wait_scans(LEASE_SCANS + 20, timeout_s=20.0)  # answered, then freed by the lease
        assert a.answer(k).owner == 0
        assert a.wait(pending) == ERR_OK  # the answer is still there, and it is this one
        assert a.mailbox is None  # the client knows the mailbox is gone
        assert a.move_joints(5.0, 70.0, 65.0).joints_deg == (5.0, 70.0, 65.0)
