"""Whole compilations cached by content: files -> loaded Module without parsing, checking,
emitting or compiling anything when the same files were compiled before.

An entry is keyed by a hash of every file of the compilation (the program's and the library's,
each with its path, in order) and of the compiler (units.compiler_version: its sources, data
and runtime files, the grammar, Python) and cffi. The files are read once, for the key, and the
compilation reads them from there (units.UnitCache's contents), so an entry always describes
the bytes it is keyed by. An entry holds what ffi.Module needs: the checked program's interface
(its types, its POUs with their variables, its configuration; the POUs' bodies, the syntax
trees and the expression types are left out: loading them would cost what the entry saves),
the library's C declarations and the digest that names the library in the build cache.

An entry that cannot be read back, or whose library is gone from the build cache, is a miss:
the program is compiled again and the entry written anew. Entries are written under a
temporary name and renamed, so concurrent compilations never read half an entry.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import os
import pickle
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import ast as A
from .build import BuiltLibrary, cache_dir, cached_library
from .emit_c import CUnit
from .symbols import CheckedProgram
from .types import ELEMENTARY, ERROR_T, INT_LIT, REAL_LIT
from .units import compiler_version, paused_gc

_FORMAT = b"armbench-programs-1"
# shared type objects the checker compares by identity: pickled by name, loaded as themselves
_SHARED_TYPES: dict[str, object] = {
    **{f"elem:{name}": t for name, t in ELEMENTARY.items()},
    "literal:int": INT_LIT, "literal:real": REAL_LIT, "literal:error": ERROR_T,
}
_SHARED_IDS = {id(t): key for key, t in _SHARED_TYPES.items()}


@dataclass(frozen=True)
class Sources:
    """The bytes of a compilation's files, read once, and the key of its entry."""

    contents: dict[Path, bytes]
    key: str


@dataclass(frozen=True)
class CachedProgram:
    program: CheckedProgram  # the interface (see the module's docstring)
    decls: str  # CUnit.decls
    library: BuiltLibrary


@dataclass(frozen=True)
class _Entry:
    program: CheckedProgram
    decls: str
    digest: str


class _Pickler(pickle.Pickler):
    def persistent_id(self, obj: Any) -> str | None:
        if isinstance(obj, A.Pou):
            return "pou"  # a POU's syntax tree: left out
        return _SHARED_IDS.get(id(obj))


class _Unpickler(pickle.Unpickler):
    def persistent_load(self, pid: Any) -> object:
        if pid == "pou":
            return None
        try:
            return _SHARED_TYPES[pid]
        except KeyError:
            raise pickle.UnpicklingError(f"unknown shared object {pid!r}") from None


def _dumps(prog: CheckedProgram, decls: str = "", digest: str = "") -> bytes:
    slim = dataclasses.replace(prog, expr_types={}, names={}, calls={}, units=[])
    out = io.BytesIO()
    _Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump(_Entry(slim, decls, digest))
    return out.getvalue()


def _loads(blob: bytes) -> CheckedProgram:
    entry = _Unpickler(io.BytesIO(blob)).load()
    if not isinstance(entry, _Entry) or not isinstance(entry.program, CheckedProgram):
        raise pickle.UnpicklingError("not a program entry")
    return entry.program


class ProgramCache:
    """Compilations keyed by their files' content, pickled under ``folder``/programs."""

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = (cache_dir() if folder is None else folder) / "programs"

    def read(self, files: Sequence[Path], library: Sequence[Path]) -> Sources | None:
        """The files' bytes and the entry's key; None when a file cannot be read (the
        compilation reports it)."""
        import cffi  # the declarations module is written for one cffi version

        h = hashlib.sha256(_FORMAT)
        h.update(compiler_version())
        h.update(cffi.__version__.encode())
        contents: dict[Path, bytes] = {}
        for kind, group in ((b"program", files), (b"library", library)):
            h.update(kind + len(group).to_bytes(8, "little"))
            for path in group:
                try:
                    data = contents[path] if path in contents else path.read_bytes()
                except OSError:
                    return None
                contents[path] = data
                for part in (str(path).encode(), data):
                    h.update(len(part).to_bytes(8, "little"))
                    h.update(part)
        return Sources(contents, h.hexdigest()[:32])

    def _path(self, sources: Sources) -> Path:
        return self.folder / f"program_{sources.key}.pickle"

    def get(self, sources: Sources) -> CachedProgram | None:
        try:
            blob = self._path(sources).read_bytes()
        except OSError:
            return None
        try:
            with paused_gc():
                entry = _Unpickler(io.BytesIO(blob)).load()
        except Exception:  # noqa: BLE001 - any unreadable entry is a miss, then rewritten
            return None
        if not isinstance(entry, _Entry) or not isinstance(entry.program, CheckedProgram):
            return None
        library = cached_library(entry.digest)
        if library is None:
            return None
        return CachedProgram(entry.program, entry.decls, library)

    def put(self, sources: Sources, prog: CheckedProgram, unit: CUnit,
            library: BuiltLibrary) -> CheckedProgram:
        """Store the compilation; returns the program's interface, as ``get`` would."""
        try:
            blob = _dumps(prog, unit.decls, library.digest)
        except (pickle.PicklingError, RecursionError):
            return prog  # not cached: the next run compiles again
        target = self._path(sources)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(suffix=".tmp", dir=target.parent)
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(blob)
                os.replace(tmp, target)
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
        except OSError:
            pass  # not cached: the next run compiles again
        return _loads(blob)
