"""The mailbox handshake's rules and the controller's self-defence (tests/modbus/conftest.py:
soft PLC by default, a real PLC with --plc-host).

Each test writes raw blocks the way a careless or hostile client would and checks what the
header of Controller.st promises: a block runs only when whole and new, once, for its owner;
every answer names the block it answers; no register a client writes can wedge, replay or
spoof the controller beyond the next scan.
"""

from __future__ import annotations

import math
import time
import zlib
from collections.abc import Iterator

import pytest

from armbench.controller_client import (
    CMD_CLOSE,
    CMD_HELLO,
    CMD_INIT_PWM,
    CMD_MOVE_JOINTS,
    CMD_RESERVE_BATCH,
    CMD_SOLVE_BATCH,
    ERR_BAD_CHECK,
    ERR_BAD_SEQUENCE,
    ERR_BUSY,
    ERR_NOT_BATCH_OWNER,
    ERR_OK,
    MAILBOXES,
    ArmControllerClient,
    NoFreeMailbox,
    check_word,
    next_seq,
)
from armbench.softplc.modbus_client import PlcClient

SCANS = 3


@pytest.fixture
def second(plc_address: tuple[str, int], plc_flavor: str) -> Iterator[ArmControllerClient]:
    """A second client on its own connection, with its own session and mailbox."""
    with PlcClient(*plc_address) as modbus, \
            ArmControllerClient(modbus, flavor=plc_flavor) as ctl:
        ctl.scan_count()  # served before the test goes on (see the plc fixture)
        yield ctl


def _seq(plc: ArmControllerClient) -> int:
    """The mailbox's answered Seq: the next block of this client must carry next_seq()."""
    assert plc.mailbox is not None
    return plc.answer(plc.mailbox).ack_seq


def test_check_word_matches_the_documented_formula() -> None:
    # zlib's CRC-32 of the 22 registers before Check as a function 16 request carries them:
    # 44 bytes, each 32-bit value most significant byte first
    def wire(*values: int) -> bytes:
        return b"".join((v & 0xFFFFFFFF).to_bytes(4, "big") for v in values)

    assert check_word(1, 1234, 2, 0, 0) == zlib.crc32(wire(1, 1234, 2, 0, 0) + bytes(24))
    assert check_word(5, -1, 1, 0, 0) == zlib.crc32(wire(5, 0xFFFFFFFF, 1, 0, 0) + bytes(24))
    assert check_word(1, 1234, 2, 0, 0, (10.0, 70.0, 65.0)) == zlib.crc32(
        wire(1, 1234, 2, 0, 0, 0x41200000, 0x428C0000, 0x42820000, 0, 0, 0))
    assert check_word(1, 1234, 2, 0, 0, (10.0, 70.0, 65.0)) == 0x7E66DC19  # the docs' example
    # the patterns the PLC cannot tell apart by arithmetic: every NaN, and -0.0 as +0.0
    assert check_word(0, 0, 0, 0, 0, (float("nan"),)) == zlib.crc32(
        wire(0, 0, 0, 0, 0, 0x7FC00000, 0, 0, 0, 0, 0))
    assert check_word(0, 0, 0, 0, 0, (-0.0,)) == zlib.crc32(bytes(44))
    # two arguments swapped, or one argument changed, change the word
    assert check_word(1, 2, 3, 0, 0, (1.0, 2.0)) != check_word(1, 2, 3, 0, 0, (2.0, 1.0))
    assert check_word(1, 2, 3, 0, 0, (30.0,)) != check_word(1, 2, 3, 0, 0, (-30.0,))


def _in_word_order(plc: ArmControllerClient, msw_first: list[int]) -> list[int]:
    """Words of 32-bit values, most significant first as docs/register-map.md writes them, in
    the PLC's order: swapped pairwise for a least-significant-word-first (CODESYS) layout."""
    if not plc.flavor.lsw_first:
        return msw_first
    return [w for i in range(0, len(msw_first), 2) for w in (msw_first[i + 1], msw_first[i])]


def test_documented_example_moves_the_arm(plc: ArmControllerClient) -> None:
    """The register-map page's example, word for word, does what the page says."""
    free = [k for k, a in enumerate(plc.answers(), start=1) if a.owner == 0]
    session = 1234
    if any(a.owner == session for a in plc.answers()):
        pytest.skip("session 1234 is in use on this PLC")
    k = free[0]
    base = plc.registers[f"MBX{k:02d}SEQ"].address
    words = _in_word_order(plc, [
        0x0000, 0x0001, 0x0000, 0x04D2, 0x0000, 0x0002, 0, 0, 0, 0,
        0x4120, 0x0000, 0x428C, 0x0000, 0x4282, 0x0000, 0, 0, 0, 0, 0, 0, 0x7E66, 0xDC19])
    plc.plc.write_registers(base, words)
    deadline = time.monotonic() + 2.0
    while plc.answer(k).ack_seq != 1 and time.monotonic() < deadline:
        time.sleep(0.002)
    a = plc.answer(k)
    assert (a.owner, a.ack_seq, a.result, a.ack_check) == (session, 1, 0, 0x7E66DC19)
    assert plc.status().joints_deg == (10.0, 70.0, 65.0)
    close = _in_word_order(plc, [0x0000, 0x0002, 0x0000, 0x04D2, 0x0000, 0x0009] + [0] * 16
                           + [0xC5F0, 0x4463])
    plc.plc.write_registers(base, close)
    while plc.answer(k).owner != 0 and time.monotonic() < deadline + 2.0:
        time.sleep(0.002)
    assert plc.answer(k).owner == 0


def test_rewriting_only_seq_runs_nothing(plc: ArmControllerClient) -> None:
    plc.move_joints(0.0, 70.0, 65.0, wait=True)
    before = plc.status()
    assert plc.mailbox is not None
    seq_reg = plc.registers[f"MBX{plc.mailbox:02d}SEQ"]
    answered = _seq(plc)
    # FC16 of Seq alone: the stale MoveJoints arguments and Check do not match a new Seq
    plc.plc.write_registers(seq_reg.address, seq_reg.encode(next_seq(answered)))
    plc.wait_scans(SCANS)
    a = plc.answer(plc.mailbox)
    assert (a.ack_seq, a.result) == (next_seq(answered), ERR_BAD_CHECK)
    # FC06 of the low word only (the second register MSW first, the first LSW first)
    low = 0 if plc.flavor.lsw_first else 1
    plc.plc.write_register(seq_reg.address + low, (next_seq(next_seq(answered))) & 0xFFFF)
    plc.wait_scans(SCANS)
    assert plc.answer(plc.mailbox).result == ERR_BAD_CHECK
    after = plc.status()
    assert (after.joints_deg, after.pulses_us) == (before.joints_deg, before.pulses_us)
    assert after.commands_answered - before.commands_answered == 2  # both told, none run


def test_a_burst_of_commands_is_never_silently_skipped(plc: ArmControllerClient) -> None:
    """100 MoveJoints written back to back without waiting: either every one ran, or the
    last answer is BadSequence (the PLC sees only the last block of each scan; after the first
    gap it runs nothing until the client says Hello), so the client always knows."""
    plc.move_joints(0.0, 70.0, 65.0)
    assert plc.mailbox is not None
    seq = _seq(plc)
    answered = plc.status().commands_answered
    poses = [(-40.0 + 0.8 * i, 70.0, 65.0) for i in range(100)]
    for pose in poses:
        seq = next_seq(seq)
        address, words = plc.block_words(plc.mailbox, seq, CMD_MOVE_JOINTS, args=pose)
        plc.plc.write_registers(address, words)
    plc.wait_scans(SCANS)
    a = plc.answer(plc.mailbox)
    st = plc.status()
    assert a.ack_seq == seq
    ran = st.commands_answered - answered
    if a.result == ERR_OK:
        assert ran == 100, "an OK last answer means no block was skipped"
        assert st.joints_deg == poses[-1]
    else:
        assert a.result == ERR_BAD_SEQUENCE
        assert ran < 100
        assert st.joints_deg in [(0.0, 70.0, 65.0), *poses[: ran]]  # none after the gap ran
        # the mailbox refuses moves until the client re-synchronises with Hello
        assert plc.move_joints(1.0, 70.0, 65.0).error_id == ERR_BAD_SEQUENCE
        assert plc.hello().error_id == ERR_OK
    assert plc.move_joints(2.0, 70.0, 65.0).joints_deg == (2.0, 70.0, 65.0)


def test_a_foreign_block_in_an_owned_mailbox_is_not_run(plc: ArmControllerClient,
                                                        second: ArmControllerClient) -> None:
    plc.move_joints(0.0, 70.0, 65.0)
    second.hello()
    assert plc.mailbox is not None and second.mailbox is not None
    before = plc.status()
    theirs = second.answer(second.mailbox)
    # the first client writes a whole, valid block into the second client's mailbox
    address, words = plc.block_words(second.mailbox, next_seq(theirs.ack_seq), CMD_MOVE_JOINTS,
                                     args=(30.0, 80.0, 70.0))
    plc.plc.write_registers(address, words)
    plc.wait_scans(SCANS)
    after = plc.status()
    assert second.answer(second.mailbox) == theirs  # not answered, owner unchanged
    assert after.joints_deg == before.joints_deg
    assert after.commands_ignored == before.commands_ignored + 1
    # the owner is not disturbed: its next command runs
    assert second.move_joints(5.0, 75.0, 60.0).joints_deg == (5.0, 75.0, 60.0)


def test_overwritten_pending_command_is_written_again(plc: ArmControllerClient,
                                                      second: ArmControllerClient) -> None:
    """A foreign block lands on top of the owner's pending one before the PLC takes it: the
    owner notices, writes its block again, and it runs once."""
    second.hello()
    assert second.mailbox is not None
    # Over Modbus nothing guarantees that the overwrite lands before the PLC's next scan, so
    # both orders are allowed: taken first (the foreign block is then ignored), or overwritten
    # first (the owner's re-check finds a foreign block and writes its own again).
    pending = second.submit(CMD_MOVE_JOINTS, args=(-7.0, 71.0, 64.0))
    address, words = plc.block_words(second.mailbox, 77, CMD_HELLO, session=424242)
    plc.plc.write_registers(address, words)
    answered = second.status().commands_answered
    assert second.wait(pending) == ERR_OK
    st = second.status()
    assert st.joints_deg == (-7.0, 71.0, 64.0)
    # ran exactly once whether or not the PLC took it before the overwrite
    assert st.commands_answered - answered <= 1


def test_commands_of_others_are_busy_while_init_pwm_runs(plc: ArmControllerClient,
                                                         second: ArmControllerClient) -> None:
    second.retry_busy = False
    second.hello()
    pending = plc.submit(CMD_INIT_PWM)
    saw_busy = False
    deadline = time.monotonic() + 2.0
    while plc.answer(pending.mailbox).ack_seq != pending.seq and time.monotonic() < deadline:
        st = second.move_joints(0.0, 70.0, 65.0)
        saw_busy |= st.error_id == ERR_BUSY
    assert plc.wait(pending) == ERR_OK
    assert saw_busy, "InitPwm lasts several scans: a move meanwhile must be answered Busy"
    assert second.move_joints(0.0, 70.0, 65.0).error_id == ERR_OK  # and runs afterwards


def test_batch_buffer_belongs_to_one_mailbox(plc: ArmControllerClient,
                                             second: ArmControllerClient) -> None:
    second.retry_busy = False
    with plc.batch_buffer():
        assert plc.status().batch_owner == plc.mailbox
        assert second.command(CMD_RESERVE_BATCH).error_id == ERR_BUSY
        assert second.command(CMD_SOLVE_BATCH, ints=(0, 1)).error_id == ERR_NOT_BATCH_OWNER
        res = plc.solve_batch([(150.0, 0.0, 120.0)])
        assert res[0].error_id == 0
    assert plc.status().batch_owner == 0
    # released: the second client gets it, and Close gives it back too
    assert second.command(CMD_RESERVE_BATCH).error_id == ERR_OK
    assert second.status().batch_owner == second.mailbox
    second.close()
    assert plc.status().batch_owner == 0


def test_close_frees_the_mailbox_and_a_new_session_can_claim_it(
        plc: ArmControllerClient, second: ArmControllerClient) -> None:
    second.hello()
    k = second.mailbox
    assert k is not None
    second.close()
    assert second.answer(k).owner == 0
    # a raw claim of that very mailbox by a new session, with any Seq
    address, words = plc.block_words(k, 999, CMD_HELLO, session=777001)
    plc.plc.write_registers(address, words)
    plc.wait_scans(SCANS)
    a = plc.answer(k)
    assert (a.owner, a.ack_seq, a.result) == (777001, 999, ERR_OK)
    address, words = plc.block_words(k, 1000, CMD_CLOSE, session=777001)
    plc.plc.write_registers(address, words)
    plc.wait_scans(SCANS)
    assert plc.answer(k).owner == 0


def test_all_mailboxes_taken_gives_a_clear_error(plc_address: tuple[str, int],
                                                 plc_flavor: str) -> None:
    with PlcClient(*plc_address) as modbus:
        clients = [ArmControllerClient(modbus, timeout_s=2.0, flavor=plc_flavor)
                   for _ in range(MAILBOXES)]
        try:
            taken = sum(1 for a in clients[0].answers() if a.owner != 0)
            for c in clients[: MAILBOXES - taken]:
                c.open()
            late = ArmControllerClient(modbus, timeout_s=0.3, flavor=plc_flavor)
            with pytest.raises(NoFreeMailbox, match=f"all {MAILBOXES} mailboxes"):
                late.open()
            clients[0].close()
            late.timeout_s = 2.0
            assert late.hello().error_id == ERR_OK
            late.close()
        finally:
            for c in clients:
                c.close()


# -- self-defence: registers the program writes -------------------------------------------------

_CLIENT_WRITTEN = ("MBX", "BATCHX", "BATCHY", "BATCHZ")  # command blocks, batch targets


def _outputs(plc: ArmControllerClient) -> list[str]:
    """Every register and bit the program writes: all but the client-written blocks and the
    inputs it declares at %IX/%IW (the PSM's: only its I/O writes them)."""
    return [name for name, r in plc.registers.items()
            if not r.source_location.startswith("%I")
            and not (name.startswith(_CLIENT_WRITTEN) and not name.endswith(
                ("OWNER", "ACKSEQ", "RESULT", "ACKCHECK")))]


def _read_outputs(plc: ArmControllerClient, names: list[str]) -> dict[str, list[int]]:
    regs = plc.registers
    return {n: plc.plc.read_table(regs[n].table, regs[n].address, regs[n].count)
            for n in names}


def _spoof(plc: ArmControllerClient, name: str, words: list[int]) -> bool:
    """Write ``words`` over the program's output ``name`` where a client can (holding
    registers and coils: OpenPLC); False where no Modbus function writes it (an input
    register or discrete input: the CODESYS layout)."""
    r = plc.registers[name]
    if r.table == "holding":
        plc.plc.write_registers(r.address, words)
    elif r.table == "coil":
        plc.plc.write_coil(r.address, bool(words[0]))
    else:
        assert r.table in ("input", "discrete"), (name, r.table)
        return False
    return True


def test_every_output_heals_within_a_scan(plc: ArmControllerClient) -> None:
    plc.init_pwm()
    plc.move_xyz(150.0, 10.0, 120.0, wait=True)
    plc.solve_batch([(150.0, 0.0, 120.0), (1000.0, 0.0, 0.0)])
    names = _outputs(plc)
    assert len(names) > 300  # status, calibration, answers, results, init frames, channels
    moving = {"SCANCOUNT", "MOTIONSCAN"}
    before = _read_outputs(plc, names)
    spoofed = [n for n in names  # spoof every one of them a client can write
               if _spoof(plc, n, [0x7FC0 if i == 0 else 0x1234
                                  for i in range(plc.registers[n].count)])]
    # OpenPLC: every output is a holding register or coil a client can write; CODESYS: none is
    assert len(spoofed) == (len(names) if plc.flavor.openplc_map else 0)
    plc.wait_scans(2)
    after = _read_outputs(plc, names)
    diff = [n for n in names if n not in moving and after[n] != before[n]]
    assert diff == []
    assert plc.read_register("PWMINITREQUEST") == 0


def test_spoofed_state_cannot_wedge_or_replay(plc: ArmControllerClient) -> None:
    plc.init_pwm()
    st = plc.move_joints(0.0, 70.0, 65.0)
    assert plc.mailbox is not None
    regs = plc.registers
    answered = st.commands_answered
    # Busy state, a zero AckSeq (the old way to replay the last command) and a fake PwmReady
    # (the CODESYS layout has no function that writes them: nothing to spoof there)
    for name, value in (("CTLSTATE", 1), ("BUSYMAILBOX", plc.mailbox),
                        (f"MBX{plc.mailbox:02d}ACKSEQ", 0)):
        assert _spoof(plc, name, regs[name].encode(value)) == plc.flavor.openplc_map
    plc.wait_scans(SCANS)
    st = plc.status()
    assert st.state == 0 and st.busy_mailbox == 0
    assert st.commands_answered == answered  # nothing replayed
    assert plc.move_joints(10.0, 70.0, 65.0).error_id == ERR_OK  # not wedged


def test_bad_calibration_then_an_ordinary_move_cannot_jump(plc: ArmControllerClient) -> None:
    """The audit's case: limits 0..20,000 us / +-1e30 deg were accepted, then MoveJoints(10,
    70, 65) put out an 11.7 ms pulse. Now they are refused and the move is normal."""
    from armbench.controller_client import Calibration

    saved = plc.calibration()
    for cal in (Calibration(min_pulse_us=0.0, max_pulse_us=20000.0),
                Calibration(min_angle_deg=-1.0e30, max_angle_deg=1.0e30),
                Calibration(min_pulse_us=400.0), Calibration(max_pulse_us=2600.0),
                Calibration(min_angle_deg=-95.0), Calibration(zero_offset_deg=1.0e6)):
        for joint in range(3):
            st = plc.set_calibration(joint, cal)
            assert st.error_id != ERR_OK, (joint, cal)
    assert plc.calibration() == saved
    st = plc.move_joints(10.0, 70.0, 65.0, wait=True)
    assert st.error_id == ERR_OK
    zero = [c.zero_offset_deg for c in saved]
    for ch, angle in enumerate((10.0, 70.0, 65.0)):
        want = 1500.0 + (angle - zero[ch]) * 1000.0 / 120.0  # MG996R: 1..2 ms = -60..+60 deg
        assert math.isclose(st.pulses_us[ch], want, abs_tol=1e-3)
        assert 500.0 <= st.pulses_us[ch] <= 2500.0


@pytest.mark.parametrize("session", [-1, -2**31, 2**31 - 1])
def test_extreme_sessions_and_sequence_wrap(plc_address: tuple[str, int], plc_flavor: str,
                                            session: int) -> None:
    """Negative and extreme session ids (the check word wraps modulo 2^32 in the PLC as in
    the client), and Seq 2147483647 followed by 1."""
    with PlcClient(*plc_address) as modbus, \
            ArmControllerClient(modbus, session=session, flavor=plc_flavor) as c:
        c._seq = 2**31 - 4  # claim (any Seq may claim) and Hello, then 2^31 - 1, then 1
        assert c.hello().error_id == ERR_OK
        assert c.move_joints(2.0, 70.0, 65.0).error_id == ERR_OK
        assert c.status().ack_seq == 2**31 - 1
        assert c.move_joints(3.0, 70.0, 65.0).error_id == ERR_OK
        assert c.status().ack_seq == 1 and c.status().joints_deg == (3.0, 70.0, 65.0)
