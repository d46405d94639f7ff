"""Source files in UTF-8 (with or without BOM) and in Windows-1252 (CODESYS V2 exports) are
read, positions stay right, and a note says when cp1252 was assumed."""

from __future__ import annotations

import codecs
from pathlib import Path

import pytest

from armbench.cli import main
from armbench.compiler import check_files, compile_files
from armbench.export import export_paths, generate

# Line 3 has a non-ASCII comment before the error (the literal 2 where REAL is needed), so a
# column counted in bytes instead of characters would be off.
TEXT = ("(* Umrechnung: Winkel in \u00b0, f\u00fcr Gr\u00f6\u00dfen *)\n"
        "FUNCTION Twice : REAL\n"
        "  VAR_INPUT X : REAL; END_VAR (* \u00b5s \u00e4\u00f6\u00fc *) "
        "VAR Y : REAL; END_VAR Y := X * 2;\n"
        "  Twice := Y;\nEND_FUNCTION\n")
GOOD = TEXT.replace("X * 2;", "X * 2.0;")


def error_column(text: str) -> int:
    line = text.splitlines()[2]
    return line.index("X * 2;") + len("X * ") + 1


def write(tmp_path: Path, name: str, data: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


@pytest.mark.parametrize("encoding", ["cp1252", "latin-1"])
def test_cp1252_file_is_read_with_a_note(tmp_path: Path, encoding: str) -> None:
    src = write(tmp_path, "legacy.st", TEXT.encode(encoding))
    diags = check_files([src])
    assert [(d.severity, d.code, d.pos.line, d.pos.col) for d in diags] == [
        ("note", "N0001", 1, 1), ("error", "E0301", 3, error_column(TEXT))]
    assert "cp1252" in diags[0].message


def test_utf8_bom_positions_count_from_the_first_character(tmp_path: Path) -> None:
    src = write(tmp_path, "bom.st", codecs.BOM_UTF8 + TEXT.encode("utf-8"))
    diags = check_files([src])
    assert [(d.code, d.pos.line, d.pos.col) for d in diags] == [("E0301", 3, error_column(TEXT))]
    line = "FUNCTION Half : REAL VAR_INPUT X : REAL; END_VAR Half := X / 2; END_FUNCTION"
    one_line = write(tmp_path, "bom1.st", codecs.BOM_UTF8 + line.encode() + b"\n")
    diags = check_files([one_line])
    assert [(d.code, d.pos.line, d.pos.col) for d in diags] == [
        ("E0301", 1, line.index("/ 2;") + 3)]


def test_plain_utf8_gives_no_note(tmp_path: Path) -> None:
    src = write(tmp_path, "new.st", GOOD.encode("utf-8"))
    assert check_files([src]) == []


@pytest.mark.parametrize("data", [
    GOOD.encode("cp1252"),
    codecs.BOM_UTF8 + GOOD.encode("utf-8"),
    codecs.BOM_UTF16_LE + GOOD.encode("utf-16-le"),
])
def test_every_encoding_compiles_and_runs(tmp_path: Path, data: bytes) -> None:
    module = compile_files([write(tmp_path, "twice.st", data)])
    assert module.call("Twice", 1.25) == 2.5


def test_cli_check_prints_the_note_and_passes(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    src = write(tmp_path, "legacy.st", GOOD.encode("cp1252"))
    assert main(["check", "--no-library", str(src)]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"{src}:1:1: note[N0001]: ")
    assert err.strip() == "checked 1 file, 1 POU: 0 errors, 1 note"


def test_export_writes_cp1252_sources_as_utf8(tmp_path: Path) -> None:
    program = GOOD + ("PROGRAM Main\nVAR r AT %MD0 : REAL; END_VAR\n  r := Twice(1.0);\n"
                      "END_PROGRAM\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
                      "    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);\n"
                      "    PROGRAM inst0 WITH MainTask : Main;\n"
                      "  END_RESOURCE\nEND_CONFIGURATION\n")
    src = write(tmp_path, "legacy.st", program.encode("cp1252"))
    text = generate([src]).files[export_paths("Main")[0]].decode("utf-8")  # its PROGRAM
    assert "Winkel in \u00b0, f\u00fcr Gr\u00f6\u00dfen" in text
