"""The pipeline in one place: files -> diagnostics, or files -> loaded Module."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from . import ast as A
from .build import build
from .diagnostics import CompileFailed, Diagnostic, Diagnostics
from .emit_c import CUnit, emit
from .nesting import check_nesting
from .lower import lower
from .parse import parse_text
from .resolve import check
from .rules import check_names, check_rules
from .source import SourcePos, read_source
from .symbols import CheckedProgram

if TYPE_CHECKING:
    from .ffi import Module


def expand(paths: Sequence[str | Path]) -> list[Path]:
    out: list[Path] = []
    for p in paths:
        path = Path(p)
        if path.is_dir():
            out.extend(sorted(path.glob("*.st")))
        else:
            out.append(path)
    return out


def analyse(paths: Sequence[str | Path]) -> tuple[CheckedProgram | None, Diagnostics]:
    diags = Diagnostics()
    units: list[A.SourceUnit] = []
    parsed = []
    for path in expand(paths):
        try:
            src = read_source(path)
        except (OSError, UnicodeDecodeError) as exc:
            diags.error(SourcePos(str(path), 1, 1), "E0001", f"cannot read {path}: {exc}")
            continue
        if src.assumed:
            diags.note(SourcePos(str(path), 1, 1), "N0001", "not valid UTF-8: read as "
                       "Windows-1252 (cp1252), as CODESYS V2 writes it")
        text = src.text
        pf = parse_text(str(path), text, diags)
        parsed.append(pf)
        check_rules(pf, diags)
        check_nesting(pf, diags)
    _drop_syntax_cascades(diags)
    if diags.has_errors:
        return None, diags  # no semantic checks after a syntax error: no cascades
    for pf in parsed:
        units.append(lower(pf, diags))
    if diags.has_errors:
        return None, diags
    prog = check(units, diags)
    check_names(prog, diags)
    return (None if diags.has_errors else prog), diags


def _drop_syntax_cascades(diags: Diagnostics) -> None:
    """A lexical rule (E0101-E0104) already explains the line: drop generic syntax errors there."""
    explained = {(d.pos.file, d.pos.line) for d in diags.items
                 if d.code in ("E0101", "E0102", "E0103", "E0104", "E0107")}
    diags.items = [d for d in diags.items
                   if not (d.code == "E0100" and (d.pos.file, d.pos.line) in explained)]


def check_files(paths: Sequence[str | Path]) -> list[Diagnostic]:
    return analyse(paths)[1].sorted()


def emit_files(paths: Sequence[str | Path]) -> tuple[CheckedProgram, CUnit]:
    prog, diags = analyse(paths)
    if prog is None:
        raise CompileFailed(diags.sorted())
    return prog, emit(prog)


def compile_files(paths: Sequence[str | Path]) -> Module:
    from .ffi import Module
    prog, unit = emit_files(paths)
    lib = build(unit)
    return Module(prog, unit, lib.path)
