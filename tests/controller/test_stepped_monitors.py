"""The harness itself (stepped_controller.py): the check word against hand-computed values,
and each monitor shown to fail on the fault it exists for, by tampering with the registers a
real scan wrote (a monitor that cannot fail would pass any controller)."""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterator

import pytest
from stepped_controller import (
    HELLO,
    MOVE_JOINTS,
    STOP,
    AnswerMonitor,
    Bits,
    Client,
    OutputMonitor,
    SteppedController,
    StopMonitor,
    check_crc,
    check_sum,
    check_weighted,
    load_controller,
    real_bits,
)

from armbench.softplc.loader import LoadedProgram

ONE = 0x3F800000  # 1.0f


def test_check_word_by_hand() -> None:
    # CRC-32 (IEEE 802.3): its standard check value, then the block's 44 bytes spelled out
    assert zlib.crc32(b"123456789") == 0xCBF43926
    two = struct.unpack("<I", struct.pack("<f", 2.0))[0]
    wire = (bytes.fromhex("00000001 00000002 00000003 FFFFFFFF 00000005")
            + ONE.to_bytes(4, "big") + bytes(16) + two.to_bytes(4, "big"))
    args = [real_bits(1.0), 0, 0, 0, 0, real_bits(2.0)]
    assert check_crc((1, 2, 3, -1, 5), args) == zlib.crc32(wire)
    assert check_sum((1, 2, 3, -1, 5), args) == (1 + 2 + 3 - 1 + 5) % 2**32
    # every NaN counts as 0x7FC00000 and -0.0 as 0
    nan_a = [real_bits(Bits(0x7FA00001))] + [0] * 5
    nan_b = [real_bits(math.nan)] + [0] * 5
    assert check_crc((0, 0, 0, 0, 0), nan_a) == check_crc((0, 0, 0, 0, 0), nan_b) \
        == zlib.crc32(bytes(20) + bytes.fromhex("7FC00000") + bytes(20))
    assert check_crc((0, 0, 0, 0, 0), [real_bits(-0.0)] + [0] * 5) == zlib.crc32(bytes(44))
    # an argument change alone changes the word (the old sum does not see it)
    other = [real_bits(1.5), 0, 0, 0, 0, real_bits(2.0)]
    assert check_crc((1, 2, 3, -1, 5), other) != check_crc((1, 2, 3, -1, 5), args)
    assert check_sum((1, 2, 3, -1, 5), other) == check_sum((1, 2, 3, -1, 5), args)
    # the weighted sum's weakness: low halves alone decide its low half
    assert check_weighted((1, 2, 3, -1, 5), other) & 0xFFFF == \
        check_weighted((1, 2, 3, -1, 5), args) & 0xFFFF


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@pytest.fixture()
def moving(program: LoadedProgram) -> Iterator[SteppedController]:
    """A controller (old check word: any controller takes its Hello) with the base powered
    and at rest, monitors not attached."""
    ctl = SteppedController(program, check_sum)
    a = Client(ctl, 1, 77)
    if a.command(HELLO) != 0:  # 106: the controller takes the new word (next Seq)
        ctl.check_formula = check_crc
        assert a.command(HELLO) == 0
    assert a.command(MOVE_JOINTS, args=(0.0, 70.0, 65.0)) == 0
    ctl.step(100)
    yield ctl


def test_output_monitor_sees_a_jump_a_nan_and_a_pulse_outside(
        moving: SteppedController) -> None:
    ctl = moving
    out = OutputMonitor()
    out(ctl)  # the base at rest, 1500 us
    assert not out.violations, out.failure()
    ctl.write_raw("BASEPULSEUS", real_bits(1530.0))  # a 30 us step (limit 12.5)
    out(ctl)
    kinds = " / ".join(v.kind for v in out.violations)
    assert "step 1500 -> 1530" in kinds and "step change" in kinds, kinds
    ctl.write_raw("BASEPULSEUS", real_bits(2600.0))
    ctl.write_raw("CARTX", real_bits(math.nan))
    out(ctl)
    kinds = " / ".join(v.kind for v in out.violations)
    assert "pulse outside [1000, 2000]" in kinds and "register not finite" in kinds, kinds
    assert any(v.channel == "CARTX" for v in out.violations)


def test_stop_monitor_sees_a_joint_still_moving_past_the_bound(
        moving: SteppedController) -> None:
    ctl = moving
    out = OutputMonitor()
    stop = StopMonitor(out)
    ctl.observers += [out, stop]
    b = Client(ctl, 2, 88)
    b.command(HELLO)
    assert b.command(STOP) == 0
    assert stop.braking is not None
    bound = stop.braking.bounds[0]
    ctl.step(bound)
    assert not stop.violations
    # the controller's base output creeping on after the bound (tampered after each scan)
    ctl.observers.remove(out)
    ctl.observers.remove(stop)
    pulse = float(ctl.read("BASEPULSEUS"))
    for k in range(3):
        ctl.step()
        ctl.write_raw("BASEPULSEUS", real_bits(pulse + 0.1 * (k + 1)))
        out(ctl)
        stop(ctl)
    assert stop.violations and "still moving" in stop.violations[0].kind, stop.violations


def test_answer_monitor_sees_an_answer_to_the_wrong_client(moving: SteppedController) -> None:
    ctl = moving
    answers = AnswerMonitor()
    answers(ctl)
    assert not answers.violations
    a = ctl.answer(1)
    ctl.write_raw("MBX01ACKSEQ", a.ack_seq + 7)  # as if another block had been answered
    answers(ctl)
    assert answers.violations and "is no block that session wrote" in answers.violations[0]
