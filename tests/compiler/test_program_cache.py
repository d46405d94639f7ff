"""The cache of whole compilations (armbench.compiler.programs) and the cffi declarations module
beside each library (declarations.py): an unchanged set of files is loaded without parsing,
checking, emitting, compiling or parsing C declarations; any change of a file's bytes, of the
compiler (its sources, data or runtime files) or a damaged or missing cache file makes it
compile again, never load something stale or fail."""

from __future__ import annotations

import gc
import pickle
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cffi
import pytest

from armbench.compiler import build as build_mod
from armbench.compiler import driver, emit_c, programs, resolve, units
from armbench.compiler.diagnostics import CompileFailed
from armbench.compiler.driver import analyse_program, compile_files
from armbench.compiler.symbols import CheckedProgram
from armbench.compiler.targets import CODESYS_ONLY, OPENPLC_ONLY
from armbench.compiler.types import ELEMENTARY
from armbench.export.codesys import located

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
  r : REAL;
END_VAR
VAR
  out AT %QW0 : WORD;
END_VAR
  n := Twice(n + 1);
  r := DINT_TO_REAL(n);
  out := DINT_TO_WORD(n);
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


def count_stages(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Wraps each stage of a compilation (front end, check, emit, C compiler) and the C
    declarations parser in a wrapper that records its name."""
    seen: list[str] = []

    def counting(name: str, real: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            seen.append(name)
            return real(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(units, "front_end", counting("front end", units.front_end))
    # the names the driver calls them by
    monkeypatch.setattr(driver, "check", counting("check", resolve.check))
    monkeypatch.setattr(driver, "emit", counting("emit", emit_c.emit))
    monkeypatch.setattr(build_mod, "_compile", counting("cc", build_mod._compile))
    monkeypatch.setattr(cffi.FFI, "cdef", counting("cdef", cffi.FFI.cdef))
    return seen


def run_twice(prog: Path, lib: Path) -> int:
    """n after two scans: Twice(0 + 1) = 2, then Twice(2 + 1) = 6 (with the library above)."""
    mod = compile_files([prog], [lib])
    mod.config_init()
    mod.run_task_index(0, 0)
    mod.run_task_index(0, 10_000_000)
    n: int = mod.instance("inst0").get("n")
    return n


def test_an_unchanged_compilation_runs_no_stage(files: tuple[Path, Path, Path],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, cache = files
    seen = count_stages(monkeypatch)
    assert run_twice(prog, lib) == 6
    assert sorted(set(seen)) == ["cc", "cdef", "check", "emit", "front end"]
    assert len(list((cache / "programs").glob("*.pickle"))) == 1
    seen.clear()
    assert run_twice(prog, lib) == 6
    assert seen == []


@pytest.mark.parametrize("which", ["library", "program"])
def test_a_changed_file_is_compiled_again(files: tuple[Path, Path, Path],
                                          monkeypatch: pytest.MonkeyPatch, which: str) -> None:
    prog, lib, _ = files
    assert run_twice(prog, lib) == 6
    seen = count_stages(monkeypatch)
    if which == "library":
        lib.write_text(LIBRARY.replace("X * 2", "X * 3"))
        expected = 3 * (3 * 1 + 1)
    else:
        prog.write_text(PROGRAM.replace("Twice(n + 1)", "Twice(n + 2)"))
        expected = 2 * (2 * 2 + 2)
    assert run_twice(prog, lib) == expected  # a stale entry would still give 6
    assert "emit" in seen and "cc" in seen
    prog.write_text(PROGRAM)
    lib.write_text(LIBRARY)
    seen.clear()
    assert run_twice(prog, lib) == 6  # the first entry is valid again
    assert seen == []


def test_another_compiler_version_is_compiled_again(files: tuple[Path, Path, Path],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, _ = files
    assert run_twice(prog, lib) == 6
    seen = count_stages(monkeypatch)
    monkeypatch.setattr(programs, "compiler_version", lambda: b"another compiler")
    assert run_twice(prog, lib) == 6
    assert "check" in seen and "emit" in seen


def test_a_compilation_for_another_target_is_checked_again(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    monkeypatch.setenv("ARMBENCH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "bump.st"
    # a CODESYS keyword: a warning when compiling for OpenPLC, an error for CODESYS
    path.write_text("FUNCTION Bump : DINT\nVAR_INPUT\n  Cal : DINT;\nEND_VAR\n"
                    "  Bump := Cal + 1;\nEND_FUNCTION\n")
    assert compile_files([path]).call("Bump", 41) == 42
    assert compile_files([path], target=OPENPLC_ONLY).call("Bump", 1) == 2  # from the cache
    with pytest.raises(CompileFailed, match="E0214"):
        compile_files([path], target=CODESYS_ONLY)


@pytest.mark.parametrize("changed", ["runtime/iec_runtime.h", "data/stdlib-pou-names.txt",
                                     "emit_c.py"])
def test_the_compiler_version_covers_its_runtime_and_data_files(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, changed: str) -> None:
    copy = tmp_path / "compiler"
    shutil.copytree(Path(units.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(units, "_COMPILER_DIR", copy)
    before = units.compiler_version()
    assert units.compiler_version() == before
    target = copy / changed
    target.write_bytes(target.read_bytes() + b"\n")
    assert units.compiler_version() != before


@pytest.mark.parametrize("garbage", [b"", b"not a pickle", b"\x80\x05\x95",
                                     pickle.dumps(["a list, not an entry"])])
def test_a_corrupt_entry_is_compiled_again_and_rewritten(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch, garbage: bytes) -> None:
    prog, lib, cache = files
    assert run_twice(prog, lib) == 6
    (entry,) = (cache / "programs").glob("*.pickle")
    entry.write_bytes(garbage)
    seen = count_stages(monkeypatch)
    assert run_twice(prog, lib) == 6
    assert "emit" in seen
    seen.clear()
    assert run_twice(prog, lib) == 6  # rewritten: read back
    assert seen == []


def test_a_library_gone_from_the_cache_is_built_again(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, cache = files
    assert run_twice(prog, lib) == 6
    for so in cache.glob("plc_*.so"):
        so.unlink()
    seen = count_stages(monkeypatch)
    assert run_twice(prog, lib) == 6
    assert "cc" in seen


@pytest.mark.parametrize("damage", ["missing", "garbage", "truncated"])
def test_a_damaged_declarations_module_is_written_again(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch, damage: str) -> None:
    prog, lib, cache = files
    assert run_twice(prog, lib) == 6
    (module,) = cache.glob("plc_*_ffi.py")
    good = module.read_text()
    if damage == "missing":
        module.unlink()
    else:
        module.write_text("ffi = 'not an FFI'\n" if damage == "garbage" else good[:200])
    seen = count_stages(monkeypatch)
    assert run_twice(prog, lib) == 6
    assert seen == ["cdef"]  # the declarations parsed again, nothing else
    assert module.read_text() == good


def test_the_module_gets_the_whole_checked_program(files: tuple[Path, Path, Path]) -> None:
    prog, lib, _ = files
    fresh = analyse_program([prog], [lib], OPENPLC_ONLY).program
    assert fresh is not None

    def shape(p: CheckedProgram) -> list[tuple[str, str, list[tuple[str, str, str]], int]]:
        return [(pou.name, pou.kind, [(v.name, v.kind, v.type.name) for v in pou.vars.values()],
                 0 if pou.node is None else len(pou.node.body))
                for pou in p.pous.values()]

    for _ in ("compiled", "from the cache"):
        mod = compile_files([prog], [lib])
        assert shape(mod.program) == shape(fresh)
        assert len(mod.program.expr_types) == len(fresh.expr_types) > 0
        assert len(mod.program.units) == len(fresh.units) == 2
        # what the CODESYS device reads of it: the located variables, from the syntax trees
        assert [(p.name, d.name, w) for p, d, w in located(mod.program)] == \
            [(p.name, d.name, w) for p, d, w in located(fresh)] == [("Main", "out", True)]
        n = mod.program.pous["MAIN"].vars["N"]
        assert n.type is ELEMENTARY["DINT"]  # the shared type objects stay themselves
        config = mod.program.config
        assert config is not None and [i.name for i in config.instances] == ["inst0"]


def test_errors_are_reported_again_and_front_ends_cached(
        files: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    prog, lib, cache = files
    prog.write_text(PROGRAM.replace("Twice(n + 1)", "Thrice(n + 1)"))
    with pytest.raises(CompileFailed, match="Thrice"):
        compile_files([prog], [lib])
    seen = count_stages(monkeypatch)
    with pytest.raises(CompileFailed, match="Thrice"):
        compile_files([prog], [lib])
    assert seen == ["check"]  # the second time: no front end, only the check that fails
    assert not (cache / "programs").exists()


@pytest.mark.parametrize("enabled", [True, False])
def test_the_collector_is_as_it_was_after_a_compilation(
        files: tuple[Path, Path, Path], enabled: bool) -> None:
    prog, lib, _ = files
    (gc.enable if enabled else gc.disable)()
    try:
        compile_files([prog], [lib])
        assert gc.isenabled() is enabled
    finally:
        gc.enable()
