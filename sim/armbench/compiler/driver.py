"""The pipeline in one place: files -> diagnostics, or files -> loaded Module.

The files given are the program; ``library`` files are looked up by use (uses.py): only the
library declarations the program needs are compiled with it. ``target`` (targets.py) says
which dialects the check is for: a check defaults to all of them, as `armbench check` does;
compiling for the bench's soft PLC, which runs what OpenPLC runs, to ``SOFT_PLC`` (OpenPLC's
rules, the names its upload needs a warning), as `armbench build` and `run` do. Each file's
front end is cached (units.py), and so is each whole compilation to a Module (programs.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from . import ast as A
from .build import BuiltLibrary, build
from .diagnostics import CompileFailed, Diagnostic, Diagnostics
from .dialects import check_dialects
from .emit_c import CUnit, emit
from .resolve import check
from .rules import check_array_input_calls, check_names
from .symbols import CheckedProgram
from .targets import ALL, SOFT_PLC, Target
from .units import UnitCache, paused_gc
from .uses import Library, LibraryUse

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


@dataclass
class Analysis:
    """One check of a program: the checked program (None on errors), the diagnostics and
    what was taken from the library."""

    program: CheckedProgram | None
    diagnostics: Diagnostics
    library: LibraryUse = field(default_factory=LibraryUse)


def analyse_program(paths: Sequence[str | Path], library: Sequence[str | Path] = (),
                    target: Target = ALL, unit_cache: UnitCache | None = None) -> Analysis:
    """Check the program ``paths`` together with the declarations of ``library`` it uses, for
    the dialects of ``target`` (``unit_cache``: the front-end cache to use, e.g. one with the
    files already read)."""
    with paused_gc():
        return _analyse_program(paths, library, target, unit_cache)


def _analyse_program(paths: Sequence[str | Path], library: Sequence[str | Path],
                     target: Target, unit_cache: UnitCache | None) -> Analysis:
    diags = Diagnostics()
    cache = UnitCache() if unit_cache is None else unit_cache
    files = expand(paths)
    fronts = cache.fronts(files)
    for front in fronts:
        diags.extend(front.syntax)
    if diags.has_errors:
        return Analysis(None, diags)  # no semantic checks after a syntax error: no cascades
    units: list[A.SourceUnit] = []
    for front in fronts:
        assert front.unit is not None  # only a syntax error leaves a file unlowered
        diags.extend(front.lowering)
        units.append(front.unit)
    if diags.has_errors:
        return Analysis(None, diags)
    lib_files = library_files(files, library)
    use = LibraryUse()
    if lib_files:
        lib = Library(lib_files, diags, cache)
        use = lib.select(units)
        if diags.has_errors:
            return Analysis(None, diags, use)
        for file in use.files:
            unit = lib.units[file]
            assert unit is not None  # a file with errors stopped above
            units.append(use.prune(unit))
    prog = check(units, diags)
    check_names(prog, diags)
    check_array_input_calls(prog, diags)
    check_dialects(prog, diags, target)
    if use.replaced:
        _explain_replacements(diags, use)
    return Analysis(None if diags.has_errors else prog, diags, use)


def library_files(files: Sequence[Path], library: Sequence[str | Path]) -> list[Path]:
    """The library's files that are not among the program's ``files``."""
    given = {path.resolve() for path in files}
    return [p for p in expand(library) if p.resolve() not in given]


def _explain_replacements(diags: Diagnostics, use: LibraryUse) -> None:
    """Errors inside library declarations that got the program's declaration of a name: one
    E0213 at the program's declaration says why, instead of every error it caused."""
    files = set(use.files)
    inside = [d for d in diags.items if d.severity == "error" and d.pos.file in files]
    if not inside:
        return
    diags.keep(lambda d: d.severity != "error" or d.pos.file not in files)
    diags.error(use.replaced[0].mine.pos, "E0213", use.conflict())


def analyse(paths: Sequence[str | Path], library: Sequence[str | Path] = (),
            target: Target = ALL) -> tuple[CheckedProgram | None, Diagnostics]:
    a = analyse_program(paths, library, target)
    return a.program, a.diagnostics


def check_files(paths: Sequence[str | Path], library: Sequence[str | Path] = (),
                target: Target = ALL) -> list[Diagnostic]:
    return analyse(paths, library, target)[1].sorted()


def emit_files(paths: Sequence[str | Path], library: Sequence[str | Path] = (),
               target: Target = SOFT_PLC, unit_cache: UnitCache | None = None
               ) -> tuple[CheckedProgram, CUnit]:
    with paused_gc():
        a = analyse_program(paths, library, target, unit_cache)
        if a.program is None:
            raise CompileFailed(a.diagnostics.sorted())
        return a.program, emit(a.program)


def compile_files(paths: Sequence[str | Path], library: Sequence[str | Path] = (),
                  target: Target = SOFT_PLC) -> Module:
    """The program compiled and loaded: from the cache of compilations (programs.py) when
    these files were compiled before for ``target``."""
    with paused_gc():
        return _compile_files(paths, library, target)


def _compile_files(paths: Sequence[str | Path], library: Sequence[str | Path],
                   target: Target) -> Module:
    from .ffi import Module
    from .programs import ProgramCache

    files = expand(paths)
    programs = ProgramCache()
    sources = programs.read(files, library_files(files, library), target)
    if sources is None:  # a file cannot be read: the compilation reports it
        prog, unit = emit_files(files, library, target)
        return Module(prog, build(unit), unit.decls)
    hit = programs.get(sources)
    if hit is not None:
        return Module(hit.program, hit.library, hit.decls)
    # the files' front ends and the compilation are written to their caches while the C
    # compiles
    unit_cache = UnitCache(contents=sources.contents, deferred=True)
    try:
        prog, unit = emit_files(files, library, target, unit_cache)

        def meanwhile(lib: BuiltLibrary) -> None:
            unit_cache.flush()
            programs.put(sources, prog, unit.decls, lib)

        lib = build(unit, meanwhile=meanwhile)
    finally:
        unit_cache.flush()  # what is left: all of it when the files had errors
    return Module(prog, lib, unit.decls)
