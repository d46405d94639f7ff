"""The front-end cache (armbench.compiler.units): a library file unchanged since the last run
is neither parsed nor lowered again, a changed one is, and a corrupt cache entry is ignored
and rewritten, never an error."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from armbench.compiler import units, uses
from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.driver import analyse_program
from armbench.compiler.frontend import parse_source as real_parse
from armbench.compiler.parse import ParsedFile

LIBRARY = """FUNCTION Twice : DINT
  VAR_INPUT
    X : DINT;
  END_VAR
  Twice := X * 2;
END_FUNCTION
"""

PROGRAM = """PROGRAM Main
VAR
  n : DINT;
END_VAR
  n := Twice(n + 1);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.fixture
def files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path, Path]:
    cache = tmp_path / "cache"
    monkeypatch.setenv("ARMBENCH_CACHE", str(cache))
    lib = tmp_path / "lib.st"
    lib.write_text(LIBRARY)
    prog = tmp_path / "main.st"
    prog.write_text(PROGRAM)
    return prog, lib, cache


def codes(prog: Path, lib: Path) -> list[str]:
    return [d.code for d in analyse_program([prog], [lib]).diagnostics.sorted()
            if d.severity == "error"]


def count_front_ends(monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """Replaces the uncached front end and the library's name parse by counting wrappers."""
    seen: list[Path] = []
    real_front = units.front_end

    def front_end(path: Path, data: bytes) -> units.FileFront:
        seen.append(path)
        return real_front(path, data)

    def parse_source(path: Path, data: bytes, diags: Diagnostics) -> ParsedFile | None:
        seen.append(path)
        return real_parse(path, data, diags)

    monkeypatch.setattr(units, "front_end", front_end)
    monkeypatch.setattr(uses, "parse_source", parse_source)
    return seen


def test_an_unchanged_file_is_taken_from_the_cache(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, cache = files
    seen = count_front_ends(monkeypatch)
    assert codes(prog, lib) == []
    assert lib in seen and prog in seen  # a cold cache: both went through the front end
    assert list((cache / "units").glob("*.pickle"))
    seen.clear()
    assert codes(prog, lib) == []
    assert seen == []


def test_a_changed_library_file_is_read_again(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, _ = files
    assert codes(prog, lib) == []
    seen = count_front_ends(monkeypatch)
    lib.write_text(LIBRARY.replace("Twice", "Thrice"))  # the program's name is gone
    assert codes(prog, lib) != []
    assert seen == [lib]
    lib.write_text(LIBRARY)  # back as before: the first entry is valid again
    seen.clear()
    assert codes(prog, lib) == []
    assert seen == []


def test_a_changed_program_file_is_read_again(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, _ = files
    assert codes(prog, lib) == []
    prog.write_text(PROGRAM.replace("n := Twice(n + 1);", "n := Twice(n + 1) +;"))
    assert codes(prog, lib) == ["E0100"]


@pytest.mark.parametrize("garbage", [b"", b"not a pickle", pickle.dumps({"A": 1})[:5],
                                     pickle.dumps(["a list, not what was stored"])])
def test_a_corrupt_cache_entry_is_ignored_and_rewritten(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch,
        garbage: bytes) -> None:
    prog, lib, cache = files
    fresh = analyse_program([prog], [lib]).diagnostics.sorted()
    entries = sorted((cache / "units").glob("*.pickle"))
    assert len(entries) == 3  # the library's names, its front end, the program's front end
    good = {e: e.read_bytes() for e in entries}
    for entry in entries:
        entry.write_bytes(garbage)
    seen = count_front_ends(monkeypatch)
    assert analyse_program([prog], [lib]).diagnostics.sorted() == fresh
    assert sorted(seen) == sorted([prog, lib, lib])
    assert {e: e.read_bytes() for e in entries} == good
