"""The soft PLC as OpenPLC v4's Modbus server (armbench.softplc.openplc_v4): the plugin's
sizing of its segments from the program's image, the requests pymodbus answered when measured
(data/openplc_v4_pymodbus_3.12.1.jsonl, replayed through the model), the write journal's
timing, and what it means for the controller's mailboxes: a command block torn across two
scans, or cut by an overflowing journal, is caught by its check word and never runs."""

from __future__ import annotations

import json
import re
import struct
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from armbench.controller_client import (
    CMD_MOVE_JOINTS,
    ERR_BAD_CHECK,
    ArmControllerClient,
    next_seq,
)
from armbench.demo import RunningPlc, serve_controller
from armbench.registermap import controller_map, program_map
from armbench.softplc import ImageLock, ProcessImage
from armbench.softplc.image import QX_OFFSET
from armbench.softplc.modbus_client import PlcClient
from armbench.softplc.openplc_v4 import (
    JOURNAL_MAX_ENTRIES,
    Close,
    OpenPlcV4Device,
    PymodbusStream,
    Segments,
    V4Settings,
    configured_tables,
    fit_segments,
    image_floor,
    image_tables,
    required_counts,
    v3_map_problems,
)

REPO = Path(__file__).resolve().parents[2]
MEASURED = Path(__file__).with_name("data") / "openplc_v4_pymodbus_3.12.1.jsonl"
# the segments of the measurement (its "about" line)
PROBE = Segments(qw_count=1024, mw_count=1024, md_count=900, ml_count=0, qx_bits=8,
                 mx_bits=0, ix_bits=8, iw_count=10)


@pytest.fixture(scope="module")
def controller_locations() -> list[str]:
    pm = program_map(list(_controller_sources()))
    return [r.location for r in pm.registers] + [u.location for u in pm.unreachable]


def _controller_sources() -> Iterator[str]:
    from armbench.registermap import SOURCES

    yield from (str(p) for p in SOURCES)


# -- sizing -----------------------------------------------------------------------------------


def test_the_floor_is_the_highest_index_plus_one_per_table() -> None:
    floor = image_floor(["%QX0.0", "%QX2.7", "%IX0.1", "%IW9", "%QW15", "%MW3", "%MD899",
                         "%ML2", "%MB4"])
    assert floor == {"bool_output": 3, "bool_input": 1, "int_input": 10, "int_output": 16,
                     "int_memory": 4, "dint_memory": 900, "lint_memory": 3}  # %MB: no table


def test_the_controller_needs_qw_and_mw_counts_to_keep_v3_addresses(
        controller_locations: list[str]) -> None:
    """Computed from the map: %QW, %MW and %MD are used; %QW and %MW lie before %MD, so both
    must be v3's 1024 long (the counts a user sets in v4's editor), %MD sizes itself."""
    assert required_counts(controller_locations) == {"qw_count": 1024, "mw_count": 1024}
    seg = V4Settings().segments(controller_locations)
    assert seg == Segments(qw_count=1024, mw_count=1024, md_count=900, ml_count=0,
                           qx_bits=8, mx_bits=0, ix_bits=8, iw_count=10)
    assert v3_map_problems(seg, controller_locations) == []
    # the highest register the map uses is the last the segments serve
    highest = max(r.address + r.count for r in controller_map().values() if r.table == "holding")
    assert highest == seg.holding_registers == 3848


def test_left_at_the_defaults_the_controller_moves(controller_locations: list[str]) -> None:
    seg = V4Settings(counts={}).segments(controller_locations)
    assert (seg.qw_count, seg.mw_count, seg.md_count) == (16, 10, 900)
    assert seg.holding_start("mw_count") == 16 and seg.holding_start("md_count") == 26
    problems = v3_map_problems(seg, controller_locations)
    assert problems == ["qw_count is 16, not 1024: the holding segments after it move",
                        "mw_count is 10, not 1024: the holding segments after it move"]
    with pytest.raises(ValueError, match="qw_count is 16, not 1024"), \
            serve_controller_v4(V4Settings(counts={})):
        pass


def test_the_docs_name_the_counts_the_map_needs(controller_locations: list[str]) -> None:
    doc = (REPO / "docs" / "modbus-parity.md").read_text(encoding="utf-8")
    needed = required_counts(controller_locations)
    line = ",".join(f"{k}={v}" for k, v in needed.items())
    assert f"`{line}`" in doc, f"docs/modbus-parity.md should name `{line}`"


def test_image_conf_takes_explicit_counts_in_address_units() -> None:
    assert configured_tables({"qx_bits": 9, "qw_count": 1024, "mx_bits": 0}) == \
        {"bool_output": 2, "int_output": 1024}
    tables = image_tables({"int_output": 16, "dint_memory": 900}, {"int_output": 1024})
    assert tables == {"int_output": 1024, "dint_memory": 900}
    square = image_tables({"int_output": 16, "dint_memory": 900}, {}, square=True)
    assert set(square.values()) == {900} and len(square) == 14


def test_a_block_is_trimmed_from_its_tail_to_one_modbus_table() -> None:
    big = dict.fromkeys(("int_output", "int_memory", "dint_memory", "lint_memory",
                         "bool_output", "bool_input", "int_input"), 65536)
    seg = fit_segments({"qw_count": 30000, "mw_count": 30000, "md_count": 3000,
                        "ml_count": 1000}, big)
    assert (seg.qw_count, seg.mw_count, seg.md_count, seg.ml_count) == (30000, 30000, 2768, 0)
    assert seg.holding_registers == 65536


# -- the measured requests --------------------------------------------------------------------


def _measured() -> list[dict[str, object]]:
    lines = MEASURED.read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines[1:]]  # the first: where they come from


def test_replays_what_pymodbus_answered() -> None:
    """Every exchange measured on pymodbus 3.12.1, through the model, on one image as the
    measurement's server had it (its state carries over from exchange to exchange)."""
    image = ProcessImage.allocate()
    for i in range(10):
        image.iw[i] = 100 + i
    device = OpenPlcV4Device(image, ImageLock(), PROBE)
    wrong = []
    for ex in _measured():
        stream, replies, closed = PymodbusStream(device), b"", False
        for chunk in ex["send"]:  # type: ignore[union-attr]
            try:
                reply = stream.feed(bytes.fromhex(str(chunk)))
            except Close:
                closed = True
                break
            replies += reply or b""
        if (replies.hex(), closed) != (ex["reply"], ex["closed"]):
            wrong.append(f"{ex['label']}: model {replies.hex() or '-'} closed={closed}, "
                         f"measured {ex['reply'] or '-'} closed={ex['closed']}")
    assert wrong == []


# -- the journal ------------------------------------------------------------------------------


def _request(device: OpenPlcV4Device, pdu: bytes) -> bytes:
    reply, _ = device.handle(1, pdu)
    assert reply is not None
    return reply


def _device(capacity: int = 4096) -> OpenPlcV4Device:
    return OpenPlcV4Device(ProcessImage.allocate(), ImageLock(), PROBE, capacity)


def test_a_write_waits_in_the_journal_until_the_next_scan_or_read() -> None:
    d = _device()
    _request(d, struct.pack(">BHHB2H", 16, 2048, 2, 4, 0x3FC0, 0))  # %MD0 := 1.5
    assert d.pending == 1 and d.image.md[0] == 0  # one entry per DINT, not yet in the image
    d.read_inputs()  # the next task's copy-in drains it
    assert d.pending == 0 and d.image.md[0] == 0x3FC00000
    _request(d, struct.pack(">BHH", 5, 3, 0xFF00))
    assert d.image.qx[3] == 0
    assert _request(d, struct.pack(">BHH", 1, 0, 8)) == b"\x01\x01\x08"  # a read drains first


def test_a_client_write_during_a_scan_loses_to_an_output_the_program_changes() -> None:
    """The task commits the outputs it changed behind what clients wrote during the scan;
    what it did not change keeps the client's write."""
    d = _device()
    qx = d.image.raw[QX_OFFSET: QX_OFFSET + 3]
    d.read_inputs()  # scan start
    for coil, value in ((0, 0xFF00), (1, 0xFF00), (2, 0x0000)):  # clients, during the scan
        _request(d, struct.pack(">BHH", 5, coil, value))
    qx[1] = 1  # the program sets coil 1 and clears it again: unchanged at the scan's end
    qx[1] = 0
    qx[2] = 1  # and changes coil 2; coil 0 it leaves alone
    d.write_outputs()  # scan end
    d.read_inputs()  # the next scan's drain
    assert list(qx) == [1, 1, 1]  # coil 2: the program's, the client's write is lost


def test_an_overflowing_journal_drops_the_tail_of_a_write() -> None:
    d = _device(capacity=4)
    reply = _request(d, struct.pack(">BHHB6H", 16, 0, 6, 12, 1, 2, 3, 4, 5, 6))
    assert reply == struct.pack(">BHH", 16, 0, 6)  # answered as written
    d.read_inputs()
    assert list(d.image.qw[0:6]) == [1, 2, 3, 4, 0, 0] and d.dropped == 2


def test_register_writes_journal_under_the_image_lock(monkeypatch: pytest.MonkeyPatch) -> None:
    """The plugin takes the image lock (which every drain holds) before a register write's
    first journal entry and releases it after its last; coil writes take no lock."""
    d = _device()
    held: list[tuple[int, bool]] = []
    append = d._append

    def spy(entries):  # type: ignore[no-untyped-def]
        entries = list(entries)
        held.extend((e.offset, d.lock.locked()) for e in entries)
        append(entries)

    monkeypatch.setattr(d, "_append", spy)
    _request(d, struct.pack(">BHHB24H", 16, 2046, 24, 48, *range(24)))  # %MW + %MD
    _request(d, struct.pack(">BHH", 6, 100, 7))
    assert len(held) == 2 + 11 + 1 and all(locked for _, locked in held)
    held.clear()
    _request(d, struct.pack(">BHHB", 15, 0, 8, 1) + b"\xff")
    assert len(held) == 8 and not any(locked for _, locked in held)


def test_function_16_reaches_a_drain_whole() -> None:
    """Register writes take the image lock over all of their journal entries, so a drain (a
    scan's copy-in) sees all of one or none: blocks of 12 equal DINTs written while another
    thread drains as fast as it can are never seen mixed."""
    d = _device()
    seen_mixed = []
    stop = threading.Event()

    def drainer() -> None:
        while not stop.is_set():
            with d.lock:
                d.read_inputs()
                block = list(d.image.md[0:12])
            if len(set(block)) != 1:
                seen_mixed.append(block)

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as CPython allows
    t = threading.Thread(target=drainer)
    t.start()
    try:
        for n in range(1, 3001):
            words = [w for _ in range(12) for w in (n >> 16, n & 0xFFFF)]
            _request(d, struct.pack(">BHHB24H", 16, 2048, 24, 48, *words))
    finally:
        stop.set()
        t.join()
        sys.setswitchinterval(old)
    assert seen_mixed == []


# -- the controller's mailboxes under v4's timing ---------------------------------------------


def serve_controller_v4(settings: V4Settings | None = None):  # type: ignore[no-untyped-def]
    return serve_controller(flavor="openplc-v4", v4=settings)


def _scans(running: RunningPlc) -> int:
    """The soft PLC's own scan count: waiting on it reads nothing over Modbus (every v4 read
    drains the journal)."""
    return sum(st.scans for st in running.plc.stats().values())


def _wait_scans(running: RunningPlc, n: int) -> None:
    start = _scans(running)
    while _scans(running) < start + n:
        threading.Event().wait(0.001)


def _moved(ctl: ArmControllerClient) -> bool:
    return ctl.status().joints_deg != (0.0, 70.0, 65.0)


@pytest.fixture(scope="module")
def v4_controller() -> Iterator[RunningPlc]:
    with serve_controller_v4() as running:
        yield running


def _opened(running: RunningPlc, modbus: PlcClient) -> ArmControllerClient:
    ctl = ArmControllerClient(modbus, flavor="openplc-v4")
    ctl.open()
    assert ctl.move_joints(0.0, 70.0, 65.0, wait=True).error_id == 0
    return ctl


def test_a_block_torn_across_two_scans_is_caught_by_its_check_word(
        v4_controller: RunningPlc) -> None:
    """A client (or a gateway splitting long writes) sends a MoveJoints block as two function
    16 requests; v4 applies the first at the next scan, which sees Seq and Session new but the
    old Check: BadCheck, answered once, and the arm does not move when the rest arrives."""
    with PlcClient(v4_controller.host, v4_controller.port) as modbus:
        ctl = _opened(v4_controller, modbus)
        assert ctl.mailbox is not None
        seq = next_seq(ctl.answer(ctl.mailbox).ack_seq)
        address, words = ctl.block_words(ctl.mailbox, seq, CMD_MOVE_JOINTS,
                                         args=(10.0, 80.0, 70.0))
        modbus.write_registers(address, words[:12])  # Seq .. Arg1
        _wait_scans(v4_controller, 3)  # scans only: no Modbus read drains the journal
        modbus.write_registers(address + 12, words[12:])  # Arg2 .. Check
        ctl.wait_scans(3)
        a = ctl.answer(ctl.mailbox)
        assert (a.ack_seq, a.result) == (seq, ERR_BAD_CHECK)
        assert not _moved(ctl)


def test_a_block_cut_by_a_full_journal_is_caught_by_its_check_word(
        v4_controller: RunningPlc) -> None:
    """v4's journal drops writes once it holds 4096 between two drains (other plugins write
    into it too); a MoveJoints block that loses its tail that way carries a stale Check:
    BadCheck, nothing moves. Modelled by leaving the block 8 entries of room: its 12 DINTs
    lose their last 4 (Arg4 .. Check)."""
    device = v4_controller.server.device
    assert isinstance(device, OpenPlcV4Device)
    with PlcClient(v4_controller.host, v4_controller.port) as modbus:
        ctl = _opened(v4_controller, modbus)
        assert ctl.mailbox is not None
        seq = next_seq(ctl.answer(ctl.mailbox).ack_seq)
        address, words = ctl.block_words(ctl.mailbox, seq, CMD_MOVE_JOINTS,
                                         args=(10.0, 80.0, 70.0))
        dropped, device.journal_capacity = device.dropped, 8
        try:
            modbus.write_registers(address, words)
        finally:
            device.journal_capacity = JOURNAL_MAX_ENTRIES
        ctl.wait_scans(3)
        a = ctl.answer(ctl.mailbox)
        assert (a.ack_seq, a.result) == (seq, ERR_BAD_CHECK)
        assert not _moved(ctl)
        assert device.dropped - dropped == 4


def test_the_serve_line_names_the_segments() -> None:
    from armbench.cli import _v4_layout

    with serve_controller_v4() as running:
        line = _v4_layout(running.server)
    assert re.search(r"holding registers 0\.\.\.3847: %QW 1024, %MW 1024, %MD 900, %ML 0; "
                     r"coils 8, discrete inputs 8, input registers 10", line), line
