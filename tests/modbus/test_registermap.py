"""docs/register-map.md is generated from plc_project/Controller.st: fail when it is stale."""

from __future__ import annotations

from armbench import registermap


def test_register_map_doc_is_current() -> None:
    expected = registermap.render_markdown(registermap.derive())
    actual = registermap.DOC.read_text(encoding="utf-8")
    assert actual == expected, "stale: run `.venv/bin/python -m armbench.registermap`"


def test_command_block_fits_one_fc16_write() -> None:
    regs = registermap.controller_map()
    cmd = [r for r in regs.values() if r.name.startswith("Cmd")]
    assert all(r.table == "holding" and r.location.startswith("%MD") for r in cmd)
    span = max(r.address + r.count for r in cmd) - min(r.address for r in cmd)
    assert span <= 123  # FC16 limit


def test_addresses_follow_openplc_map() -> None:
    regs = registermap.controller_map()
    assert regs["CMDSEQ"].address == 2048 and regs["CMDSEQ"].count == 2
    assert regs["CMDX"].address == 2048 + 2 * 2
    assert regs["INITREG1"].address == 1024
    assert regs["CH15OFF"].address == 15
    assert registermap.modbus_location("%QX2.5") == ("coil", 21, 1)
    assert registermap.modbus_location("%ML1") == ("holding", 4100, 4)
