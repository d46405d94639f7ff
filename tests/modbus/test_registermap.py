"""docs/register-map.md is generated from plc_project/Controller.st: fail when it is stale."""

from __future__ import annotations

import re

import pytest

from armbench import registermap
from armbench.controller_client import MAILBOXES


def test_register_map_doc_is_current() -> None:
    expected = registermap.render_markdown(registermap.derive())
    actual = registermap.DOC.read_text(encoding="utf-8")
    assert actual == expected, "stale: run `.venv/bin/python -m armbench.registermap`"


def test_each_mailbox_block_fits_one_fc16_write() -> None:
    regs = registermap.controller_map()
    for k in range(1, MAILBOXES + 1):
        block = [r for r in regs.values() if r.name.upper().startswith(f"MBX{k:02d}")]
        assert len(block) == 16  # 12 command fields + 4 answer fields
        cmd = [r for r in block if r.name[5:] in
               ("Seq", "Session", "Code", "Int1", "Int2", "Arg1", "Arg2", "Arg3", "Arg4",
                "Arg5", "Arg6", "Check")]
        assert len(cmd) == 12
        assert all(r.table == "holding" and r.location.startswith("%MD") for r in block)
        span = max(r.address + r.count for r in cmd) - min(r.address for r in cmd)
        assert span == 24 <= 123  # contiguous, one FC16 request
        ans = [r for r in block if r not in cmd]
        assert max(r.address + r.count for r in ans) - min(r.address for r in ans) == 8


def test_no_two_variables_share_a_register() -> None:
    taken: dict[tuple[str, int], str] = {}
    for r in registermap.controller_map().values():
        for a in range(r.address, r.address + r.count):
            assert (r.table, a) not in taken, f"{r.name} overlaps {taken[(r.table, a)]}"
            taken[(r.table, a)] = r.name


def test_addresses_follow_openplc_map() -> None:
    regs = registermap.controller_map()
    assert regs["SCANCOUNT"].address == 2048 and regs["SCANCOUNT"].count == 2
    assert regs["MBX01OWNER"].address == 2048 + 2 * 64
    assert regs["MBX01SEQ"].address == 2048 + 2 * 128
    assert regs["MBX16CHECK"].address == 2048 + 2 * (128 + 15 * 16 + 11)
    assert regs["PWMINITREQUEST"].table == "coil" and regs["PWMINITREQUEST"].address == 0
    assert regs["PWMDRIVERFAULT"].table == "discrete" and regs["PWMDRIVERFAULT"].address == 1
    assert regs["INITREG1"].address == 1024
    assert regs["CH15OFF"].address == 15
    assert registermap.modbus_location("%QX2.5") == ("coil", 21, 1)
    assert registermap.modbus_location("%ML1") == ("holding", 4100, 4)


def test_batch_blocks_are_regular_and_match_the_program() -> None:
    """The SolveBatch declarations are generated (armbench.batchgen): the pattern holds."""
    regs = registermap.controller_map()
    n = sum(1 for name in regs if name.startswith("BATCHX"))
    source = registermap.CONTROLLER.read_text(encoding="utf-8")
    solver = (registermap.CONTROLLER.parent / "controller" / "BatchSolver.st").read_text(
        encoding="utf-8")
    assert f"BatchMax : DINT := {n};" in solver
    assert f"BatchTargets : ARRAY[1..{n}] OF Coordinates;" in solver
    assert f"ArmPointResults : ARRAY[1..{n}] OF ArmPointResult;" in solver
    assert f"MailboxMax : DINT := {MAILBOXES};" in source
    server = (registermap.CONTROLLER.parent / "controller" / "MailboxServer.st").read_text(
        encoding="utf-8")
    assert f"MailboxBlocks : ARRAY[1..{MAILBOXES}] OF MailboxCommand;" in server
    assert f"MailboxStates : ARRAY[1..{MAILBOXES}] OF MailboxState;" in server
    assert f"MailboxCount : DINT := {MAILBOXES};" in server
    first_target = regs["BATCHX01"].address
    first_result = regs["RESBASE01"].address
    for k in range(1, n + 1):
        for j, axis in enumerate("XYZ"):
            r = regs[f"BATCH{axis}{k:02d}"]
            assert (r.st_type, r.address) == ("REAL", first_target + 6 * (k - 1) + 2 * j)
            assert f"BatchIn[{k}].{axis} := Batch{axis}{k:02d};" in source
        for j, field in enumerate(("BASE", "SHOULDER", "ELBOW", "X", "Y", "Z", "ERRORID")):
            r = regs[f"RES{field}{k:02d}"]
            assert r.address == first_result + 14 * (k - 1) + 2 * j
        assert f"ResErrorId{k:02d} := Batch.Results[{k}].ErrorId;" in source
    assert first_target + 6 * n <= first_result  # targets and results do not overlap


def test_psm_handshake_bits_are_where_the_psm_sees_them() -> None:
    regs = registermap.controller_map()
    # OpenPLC's PSM exchanges %IX/%QX 0.0..49.7 and %IW/%QW 0..49 only
    assert regs["PWMINITREQUEST"].location == "%QX0.0"
    assert regs["PWMDRIVERREADY"].location == "%IX0.0"
    assert regs["PWMDRIVERFAULT"].location == "%IX0.1"
    assert [regs[f"CH{n:02d}OFF"].location for n in range(16)] == [f"%QW{n}" for n in range(16)]


def test_batch_regions_are_current() -> None:
    from armbench.batchgen import main

    assert main(["--check"]) == 0, "run python -m armbench.batchgen"


def test_register_map_doc_lists_every_command() -> None:
    """Each command constant of Controller.st is described in the doc ("46 FollowImu ..."):
    the doc copies the header's sections, and a line that looks like a section heading would
    silently cut one short."""
    text = registermap.DOC.read_text(encoding="utf-8")
    commands = {name[3:]: code for name, code in registermap.controller_constants().items()
                if name.startswith("Cmd") and not name.endswith(("First", "Last"))}
    assert len(commands) >= 30
    missing = [f"{code} {name}" for name, code in commands.items()
               if not re.search(rf"(?m)^ *{code} {name}\b", text)]
    assert not missing, f"docs/register-map.md does not describe {missing}"


def test_every_located_output_is_written_by_one_generated_copy() -> None:
    """The copy table (armbench.register_copies) is the one place that says what a register
    shows: the generator refuses a body that writes a register by hand, a register no copy
    writes, a copy of an undeclared name and a register copied twice."""
    from armbench import batchgen

    text = batchgen.CONTROLLER.read_text(encoding="utf-8")
    batchgen.check_copies(text)  # the committed program keeps the rules
    by_hand = text.replace("  Pwm(StartMailbox := PwmStart, Pulses := Pulses);\n",
                           "  Pwm(StartMailbox := PwmStart, Pulses := Pulses);\n"
                           "  ch05off := Pwm.Words[5];\n", 1)
    assert by_hand != text
    with pytest.raises(ValueError, match=r"hand-written body .* names the located variable "
                                         r"Ch05Off \(%QW5\)"):
        batchgen.check_copies(by_hand)
    read_by_hand = text.replace("Imu(Run := FALSE, Cmd := Cmd, Raw := ImuRaw, SampleSeq := ImuSeq",
                                "Imu(Run := FALSE, Cmd := Cmd, Raw := ImuRaw, "
                                "SampleSeq := ImuSampleSeq", 1)
    assert read_by_hand != text
    with pytest.raises(ValueError, match=r"names the located variable ImuSampleSeq \(%IW9\)"):
        batchgen.check_copies(read_by_hand)


def test_the_copy_table_must_cover_the_map(monkeypatch: pytest.MonkeyPatch) -> None:
    from armbench import batchgen
    from armbench.register_copies import COPY_OUT

    text = batchgen.CONTROLLER.read_text(encoding="utf-8")
    title, rows = COPY_OUT[0]
    assert rows[0][0] == "ScanCount"
    monkeypatch.setattr(batchgen, "COPY_OUT", ((title, rows[1:]), *COPY_OUT[1:]))
    with pytest.raises(ValueError, match=r"no copy writes the located output ScanCount \(%MD0\)"):
        batchgen.check_copies(text)
    monkeypatch.setattr(batchgen, "COPY_OUT",
                        ((title, (*rows, ("ScanCounts", "Scans"), ("CtlState", "0"))),
                         *COPY_OUT[1:]))
    with pytest.raises(ValueError, match=r"ScanCounts is copied out but not declared"):
        batchgen.check_copies(text)
    with pytest.raises(ValueError, match=r"CtlState is copied out twice"):
        batchgen.check_copies(text)
    monkeypatch.setattr(batchgen, "COPY_OUT",
                        ((title, (*rows, ("ImuGyroX", "0"))), *COPY_OUT[1:]))
    with pytest.raises(ValueError, match=r"ImuGyroX \(%IW0\) is an input"):
        batchgen.check_copies(text)


def test_the_codesys_flavor_map_is_the_committed_codesys_register_map() -> None:
    """controller_map("codesys") (what the clients and the soft PLC use) and
    plc_project/codesys/register-map.md (what a CODESYS user sets the device up from) agree
    row for row, and the map's blocks fit the client's requests."""
    from armbench.export import CODESYS_MAP_FILE

    regs = registermap.controller_map("codesys")
    assert registermap.DOC is not None
    text = (registermap.DOC.parents[1] / "plc_project" / CODESYS_MAP_FILE).read_text()
    tables = {"holding register": "holding", "input register": "input", "coil": "coil",
              "discrete input": "discrete"}
    rows = [[c.strip().strip("`") for c in ln.strip("|").split("|")]
            for ln in text.splitlines() if ln.startswith("| `")]
    assert len(rows) == len(regs) > 800
    for name, _, openplc, codesys, table, address, words in rows:
        r = regs[name.upper()]
        assert (r.declared or r.location, r.location, r.table, r.address, r.count) == (
            openplc, codesys, tables[table], int(address), int(words)), name
        assert r.flavor.lsw_first
    # each mailbox's command block is one FC16 write, its answer block one FC4 read
    for k in range(1, MAILBOXES + 1):
        cmd = [regs[f"MBX{k:02d}{f}"] for f in ("SEQ", "SESSION", "CODE", "INT1", "INT2",
                                                 "ARG1", "ARG2", "ARG3", "ARG4", "ARG5",
                                                 "ARG6", "CHECK")]
        assert {r.table for r in cmd} == {"holding"}
        assert max(r.address + r.count for r in cmd) - cmd[0].address == 24
        ans = [regs[f"MBX{k:02d}{f}"] for f in ("OWNER", "ACKSEQ", "RESULT", "ACKCHECK")]
        assert {r.table for r in ans} == {"input"}
        assert max(r.address + r.count for r in ans) - ans[0].address == 8
