"""The CODESYS variant (plc_project/codesys/): no two located variables share memory under
either addressing scheme, for every located variable of the program, read from the
generated XML and compared with Controller.st's own declarations.

The two schemes, written out here from their definitions (not from armbench.export.codesys):
- OpenPLC v3 (docs/matiec-facts.md): one table per kind, %IX/%QX bit 8*byte+bit, %IW, %QW, %MW, %MD,
  %ML each indexed by n: two variables clash when kind and index are equal.
- CODESYS: one byte memory per area I, Q, M; %XWn = bytes 2n..2n+1, %XDn = 4n..4n+3,
  %XLn = 8n..8n+7, %XBn = byte n, %XXb.i = bit i of byte b: two variables clash when they
  share a bit in the same area.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

import pytest
from lxml import etree
from plcopen_to_st import xml_to_st

from armbench.compiler import ast as A
from armbench.compiler import check_files
from armbench.compiler.driver import analyse
from armbench.export import CODESYS_FILE, CODESYS_MAP_FILE, export_paths, generate
from armbench.locate import default_project

REPO = Path(__file__).resolve().parents[2]
SCHEMA = REPO.parent / "shared" / "schemas" / "tc6_xml_v201.xsd"
COMMITTED_XML = REPO / "plc_project" / CODESYS_FILE
COMMITTED_MAP = REPO / "plc_project" / CODESYS_MAP_FILE
N = {"p": "http://www.plcopen.org/xml/tc6_0201"}
ADDR = re.compile(r"^%([IQM])([XBWDL])(\d+)(?:\.(\d+))?$")
BYTES = {"B": 1, "W": 2, "D": 4, "L": 8}


def codesys_bits(address: str) -> tuple[str, set[int]]:
    m = ADDR.match(address)
    assert m, address
    area, size, n = m.group(1), m.group(2), int(m.group(3))
    if size == "X":
        return area, {8 * n + int(m.group(4))}
    width = 8 * BYTES[size]
    return area, set(range(width * n, width * (n + 1)))


def openplc_slot(address: str) -> tuple[str, int]:
    m = ADDR.match(address)
    assert m, address
    area, size, n = m.group(1), m.group(2), int(m.group(3))
    if size == "X":
        return f"{area}X", 8 * n + int(m.group(4))
    return f"{area}{size}", n


def codesys_clashes(named: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
    seen: dict[tuple[str, int], str] = {}
    out = []
    for name, address in named:
        area, bits = codesys_bits(address)
        for b in sorted(bits):
            if (area, b) in seen:
                out.append((seen[(area, b)], name))
                break
        for b in bits:
            seen[(area, b)] = name
    return out


def openplc_clashes(named: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
    seen: dict[tuple[str, int], str] = {}
    out = []
    for name, address in named:
        slot = openplc_slot(address)
        if slot in seen:
            out.append((seen[slot], name))
        seen[slot] = name
    return out


def source_located(files: list[Path]) -> dict[str, str]:
    """name -> address of every located variable declared in the sources' POUs."""
    prog, diags = analyse(files)
    assert prog is not None, diags
    return {d.name: d.address.upper() for u in prog.units for p in u.pous for b in p.blocks
            for d in b.decls if d.address is not None}


def xml_located(xml: bytes) -> dict[str, str]:
    root = etree.fromstring(xml)
    return {str(v.get("name")): str(v.get("address"))
            for v in root.iterfind(".//p:pou//p:variable[@address]", N)}


@pytest.fixture(scope="module")
def controller() -> dict[str, str]:
    return source_located(default_project().sources())


@pytest.fixture(scope="module")
def variant() -> dict[str, str]:
    return xml_located(COMMITTED_XML.read_bytes())


def test_committed_codesys_files_are_fresh() -> None:
    exp = generate()
    assert exp.files[CODESYS_FILE] == COMMITTED_XML.read_bytes(), \
        "stale: run armbench export --regenerate"
    assert exp.files[CODESYS_MAP_FILE] == COMMITTED_MAP.read_bytes()


def test_codesys_xml_validates_against_tc6_schema() -> None:
    if not SCHEMA.exists():
        pytest.skip(f"TC6 schema not found at {SCHEMA}")
    xsd = etree.XMLSchema(etree.parse(str(SCHEMA)))
    doc = etree.fromstring(COMMITTED_XML.read_bytes())
    assert xsd.validate(doc), "\n".join(str(e) for e in xsd.error_log)


def test_every_located_variable_is_in_the_variant_with_its_size(
        controller: dict[str, str], variant: dict[str, str]) -> None:
    assert set(variant) == set(controller)
    for name, address in controller.items():
        # the size letter (X/W/D/L) is the variable's type size: it must not change
        assert ADDR.match(variant[name]).group(2) == ADDR.match(address).group(2), name  # type: ignore[union-attr]
        assert not variant[name].startswith("%M"), name  # %M is not on Modbus in CODESYS


def test_no_overlap_under_either_scheme(controller: dict[str, str],
                                        variant: dict[str, str]) -> None:
    assert codesys_clashes(variant.items()) == []
    assert openplc_clashes(variant.items()) == []
    assert openplc_clashes(controller.items()) == []


def test_the_openplc_program_does_overlap_under_codesys(controller: dict[str, str]) -> None:
    """Why the variant exists, and proof that the checker above can fail."""
    clashes = {frozenset(c) for c in codesys_clashes(controller.items())}
    assert frozenset({"ScanCount", "InitReg1"}) in clashes  # %MD0 vs %MW0
    assert frozenset({"PwmInitRequest", "Ch00Off"}) in clashes  # %QX0.0 vs %QW0


def test_clients_write_holding_registers_the_program_writes_input_registers(
        variant: dict[str, str]) -> None:
    for name in ("Mbx01Seq", "Mbx16Check", "BatchX01", "BatchZ32", "PwmDriverReady"):
        assert variant[name].startswith("%I"), name
    for name in ("ScanCount", "Mbx01Owner", "ResErrorId32", "Ch00Off", "InitReg1",
                 "PwmInitRequest", "LutSession"):
        assert variant[name].startswith("%Q"), name


def test_register_map_lists_every_variable_at_its_codesys_register(
        variant: dict[str, str]) -> None:
    rows = [ln for ln in COMMITTED_MAP.read_text().splitlines() if ln.startswith("| `")]
    seen = {}
    for row in rows:
        cells = [c.strip().strip("`") for c in row.strip("|").split("|")]
        name, _, _, codesys, table, address, words = cells
        assert codesys == variant[name]
        area, bits = codesys_bits(codesys)
        first = min(bits)
        if len(bits) == 1:
            assert (table, int(address)) == (
                "discrete input" if area == "Q" else "coil", first), name
        else:
            assert (table, int(address), int(words)) == (
                "input register" if area == "Q" else "holding register", first // 16,
                len(bits) // 16), name
        seen[name] = codesys
    assert seen == variant


MIXED_ST = """
PROGRAM Mixed
  VAR
    OutD AT %MD0 : DINT;
    OutW AT %MW0 : WORD;
    OutW2 AT %MW3 : WORD;
    OutL AT %ML1 : LINT;
    OutBit AT %QX0.0 : BOOL;
    OutQ AT %QW0 : WORD;
    InD AT %MD0 : DINT;
    InW AT %MW1 : WORD;
    InBit AT %IX0.3 : BOOL;
    InMx AT %MX0.1 : BOOL;
  END_VAR
  VAR
    Tmp : DINT;
  END_VAR
  Tmp := InD + WORD_TO_DINT(InW);
  IF InBit OR InMx THEN
    Tmp := Tmp + 1;
  END_IF;
  OutD := Tmp;
  OutW := DINT_TO_WORD(Tmp);
  OutW2 := OutW;
  OutL := DINT_TO_LINT(Tmp);
  OutBit := InBit;
  OutQ := OutW;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Mixed;
  END_RESOURCE
END_CONFIGURATION
"""


def test_a_program_full_of_clashes_is_laid_out_without_any(tmp_path: Path) -> None:
    src = tmp_path / "Mixed.st"
    src.write_text(MIXED_ST)
    exp = generate([src])
    source = source_located([src])
    placed = xml_located(exp.files[export_paths("Mixed")[2]])  # named after its PROGRAM
    assert set(placed) == set(source)
    assert codesys_clashes(source.items()) != []  # the input is full of clashes
    assert codesys_clashes(placed.items()) == []
    assert openplc_clashes(placed.items()) == []
    for name in source:
        assert placed[name][1] == ("Q" if name.startswith("Out") else "I"), (name, placed)


def test_located_decls_in_the_source_are_what_the_ast_says() -> None:
    """The fixture's own reading of Controller.st agrees with a plain text scan of it, so the
    tests above cover every located variable the file declares."""
    text = default_project().controller.read_text()
    declared = dict(re.findall(r"^\s*(\w+)\s+AT\s+(%[IQM][XBWDL][\d.]+)\s*:", text, re.M))
    prog, _ = analyse(default_project().sources())
    assert prog is not None
    ast_decls = {d.name: d.address for u in prog.units for p in u.pous
                 if isinstance(p, A.Pou) and p.name == "ArmController"
                 for b in p.blocks for d in b.decls if d.address}
    assert ast_decls == declared


def test_the_variant_carries_the_whole_program(tmp_path: Path, variant: dict[str, str]) -> None:
    """ST rebuilt from nothing but the CODESYS XML checks clean except for what is OpenPLC's
    alone: the moved variables lie beyond OpenPLC's buffers (E0600), which CODESYS has not."""
    rebuilt = tmp_path / "codesys_from_xml.st"
    rebuilt.write_text(xml_to_st(COMMITTED_XML.read_bytes()))
    diags = check_files([rebuilt])
    assert diags, "expected OpenPLC's buffer limit to flag the moved variables"
    for d in diags:
        assert d.code == "E0600" and "outside OpenPLC's buffers" in d.render(), d.render()
        address = re.search(r"%[IQ][XWD][\d.]+", d.render())
        assert address is not None and address.group(0) in variant.values(), d.render()


def test_the_device_sizes_cover_every_register_and_bit() -> None:
    """The Modbus TCP Server Device settings the map asks for reach every variable in it:
    coils share the holding registers' data and discrete inputs the input registers' (16 bits
    per register), so a bit at Modbus address a needs register a // 16."""
    text = COMMITTED_MAP.read_text()
    holding = int(re.search(r"starting at\s+`%IW0`, at least (\d+) of them", text).group(1))  # type: ignore[union-attr]
    inputs = int(re.search(r"starting at\s+`%QW0`, at least (\d+) of them", text).group(1))  # type: ignore[union-attr]
    need = {"holding": 0, "input": 0}
    for row in (ln for ln in text.splitlines() if ln.startswith("| `")):
        cells = [c.strip().strip("`") for c in row.strip("|").split("|")]
        table, address, words = cells[4], int(cells[5]), int(cells[6])
        kind = "holding" if table in ("holding register", "coil") else "input"
        last = address // 16 if table in ("coil", "discrete input") else address + words - 1
        need[kind] = max(need[kind], last + 1)
    assert (holding, inputs) == (need["holding"], need["input"])
