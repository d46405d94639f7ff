"""Two motion commands from two clients in ONE scan (possible only where the test holds the
scan, so it runs on the in-process fast-clock PLC): a Stop of a running jog, then another
client's JogStart. The second start must really start a jog: the jog block starts on Enable's
rising edge, and it was still enabled from the previous scan. Before the controller re-armed
it, the start was answered 0 while the block reported itself aborted, and nothing moved."""

from __future__ import annotations

import threading
import time

from fast_plc import FastPlc

from armbench.controller_client import (
    CMD_JOG_START,
    CMD_STOP,
    ERR_OK,
    ArmControllerClient,
    Status,
)
from armbench.registermap import controller_map
from armbench.softplc.modbus_client import PlcClient

KIND_JOG = 3


def test_stop_then_jog_start_in_one_scan(fast_controller: FastPlc) -> None:
    cmap = controller_map()
    with PlcClient(*fast_controller.address) as la, PlcClient(*fast_controller.address) as lb, \
            PlcClient(*fast_controller.address) as lc, ArmControllerClient(la) as a, \
            ArmControllerClient(lb) as b, ArmControllerClient(lc) as c:
        for cl in (a, b, c):
            assert cl.hello().error_id == ERR_OK
        # mailboxes run in number order: the Stop must come from the lower one
        assert b.mailbox is not None and c.mailbox is not None
        if c.mailbox < b.mailbox:
            b, c = c, b
        assert a.move_xyz(180.0, 0.0, 120.0, wait=True).error_id == ERR_OK
        assert a.jog_start((0.0, 1.0, 0.0), 40.0, 300.0).error_id == ERR_OK
        a.wait_scans(30)
        assert a.motion().busy

        # hold the scan, let B's Stop and C's JogStart both land, then let it run once
        gate = threading.Event()
        held = threading.Event()

        def hold() -> None:
            held.set()
            gate.wait(10.0)
        fast_controller.before_scan.append(hold)
        answers: dict[str, Status] = {}
        try:
            assert held.wait(5.0)
            tb = threading.Thread(target=lambda: answers.setdefault("stop", b.stop()))
            tc = threading.Thread(target=lambda: answers.setdefault(
                "jog", c.jog_start((1.0, 0.0, 0.0), 40.0, 300.0)))
            tb.start()
            tc.start()
            code_b = cmap[f"MBX{b.mailbox:02d}CODE"].index
            code_c = cmap[f"MBX{c.mailbox:02d}CODE"].index
            deadline = time.monotonic() + 5.0
            while True:
                with fast_controller.plc.lock:
                    md = fast_controller.plc.image.md
                    landed = md[code_b] == CMD_STOP and md[code_c] == CMD_JOG_START
                if landed:
                    break
                assert time.monotonic() < deadline, "the two commands did not land"
                time.sleep(0.001)
        finally:
            fast_controller.before_scan.remove(hold)
            gate.set()
        tb.join(10.0)
        tc.join(10.0)
        assert answers["stop"].error_id == ERR_OK
        assert answers["jog"].error_id == ERR_OK
        start = c.motion()
        c.wait_scans(20)
        assert c.jog_update((1.0, 0.0, 0.0)).error_id == ERR_OK  # C owns the jog
        later = c.motion()
        assert later.kind == KIND_JOG and later.busy and not later.aborted, later
        assert later.ticket == c.last_ticket, (later.ticket, c.last_ticket)
        assert later.cart_mm[0] > start.cart_mm[0] + 1.0  # it moves along +X
        assert c.jog_stop().error_id == ERR_OK
