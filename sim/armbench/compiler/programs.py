"""Whole compilations cached by content: files -> loaded Module without parsing, checking,
emitting or compiling anything when the same files were compiled before.

An entry is keyed by a hash of every file of the compilation (the program's and the library's,
each with its path, in order), of the target it was checked for (targets.py: which dialects'
rules are errors) and of the compiler (units.compiler_version: its sources, data and runtime
files, the grammar, Python) and cffi. The files are read once, for the key, and the
compilation reads them from there (units.UnitCache's contents), so an entry always describes
the bytes it is keyed by. An entry holds the checked program (what ffi.Module.program is: the
soft PLC and the CODESYS device read its syntax trees too), the library's C declarations and
the digest that names the library in the build cache.

An entry that cannot be read back, or whose library is gone from the build cache, is a miss:
the program is compiled again and the entry written anew (while its C compiles). Entries are
written under a temporary name and renamed, so concurrent compilations never read half an
entry.
"""

from __future__ import annotations

import copyreg
import hashlib
import io
import pickle
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .atomic import write_atomic
from .build import BuiltLibrary, cache_dir, cached_library
from .stdlib import STD_FUNCS, StdFunc
from .symbols import CheckedProgram
from .targets import Target
from .types import ELEMENTARY, ERROR_T, INT_LIT, REAL_LIT, ElemType, LiteralType
from .units import compiler_version, paused_gc

_FORMAT = b"armbench-programs-1"
_LITERAL_TYPES = {t.name: t for t in (INT_LIT, REAL_LIT, ERROR_T)}


def _elementary(name: str) -> ElemType:
    return ELEMENTARY[name]


def _literal_type(name: str) -> LiteralType:
    return _LITERAL_TYPES[name]


def _std_func(name: str) -> StdFunc:
    return STD_FUNCS[name]


def _by_name(lookup: Any) -> Any:
    def reduce(obj: Any) -> tuple[Any, tuple[str]]:
        return lookup, (obj.name,)
    return reduce


# The type and standard-function objects the compiler shares (and compares by identity) are
# pickled by name and loaded as themselves; a table of the pickler's, looked up by class in
# C: a per-object hook in Python would double the time to write an entry.
_SHARED = copyreg.dispatch_table | {ElemType: _by_name(_elementary),
                                    LiteralType: _by_name(_literal_type),
                                    StdFunc: _by_name(_std_func)}


@dataclass(frozen=True)
class Sources:
    """The bytes of a compilation's files, read once, and the key of its entry."""

    contents: dict[Path, bytes]
    key: str


@dataclass(frozen=True)
class CachedProgram:
    program: CheckedProgram
    decls: str  # CUnit.decls
    library: BuiltLibrary


@dataclass(frozen=True)
class _Entry:
    program: CheckedProgram
    decls: str
    digest: str


class ProgramCache:
    """Compilations keyed by their files' content, pickled under ``folder``/programs."""

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = (cache_dir() if folder is None else folder) / "programs"

    def read(self, files: Sequence[Path], library: Sequence[Path],
             target: Target) -> Sources | None:
        """The files' bytes and the entry's key; None when a file cannot be read (the
        compilation reports it)."""
        import cffi  # the declarations module is written for one cffi version

        h = hashlib.sha256(_FORMAT)
        h.update(compiler_version())
        h.update(cffi.__version__.encode())
        h.update(",".join(sorted(target.dialects)).encode() + b"\0")
        h.update(b"upload\0" if target.upload else b"soft PLC\0")  # an upload refuses more
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
                entry = pickle.loads(blob)
        except Exception:  # noqa: BLE001 - any unreadable entry is a miss, then rewritten
            return None
        if not isinstance(entry, _Entry) or not isinstance(entry.program, CheckedProgram):
            return None
        library = cached_library(entry.digest)
        if library is None:
            return None
        return CachedProgram(entry.program, entry.decls, library)

    def put(self, sources: Sources, prog: CheckedProgram, decls: str,
            library: BuiltLibrary) -> None:
        """Store the compilation whose library is (or is being built as) ``library``: an entry
        whose library never appears is a miss."""
        out = io.BytesIO()
        pickler = pickle.Pickler(out, protocol=pickle.HIGHEST_PROTOCOL)
        pickler.dispatch_table = _SHARED
        try:
            pickler.dump(_Entry(prog, decls, library.digest))
        except (pickle.PicklingError, RecursionError):
            return  # not cached: the next run compiles again
        target = self._path(sources)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(target, out.getvalue())
        except OSError:
            pass  # not cached: the next run compiles again
