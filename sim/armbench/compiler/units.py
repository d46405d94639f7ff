"""The front end of a file (parse, nesting guard, lexical rules, lowering), cached by content.

The result for a file depends only on its path (positions name it) and its bytes, and on the
compiler itself (its Python sources, its data and runtime files, the grammar and the Python it
runs on): it is pickled under the build cache folder (build.cache_dir) with a key hashing all
three, so an unchanged library file is never parsed or lowered twice. A cache
entry that cannot be read back (truncated, corrupt, from another Python) is ignored and
written anew; a cache folder that cannot be written to only costs the time saved.
"""

from __future__ import annotations

import gc
import hashlib
import pickle
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from . import ast as A
from .atomic import write_atomic
from .build import cache_dir
from .diagnostics import Diagnostic, Diagnostics
from .front_split import compute_all
from .frontend import check_syntax, drop_syntax_cascades, parse_source
from .lower import lower
from .source import SourcePos

_COMPILER_DIR = Path(__file__).parent
_FORMAT = b"armbench-units-1"


@dataclass
class FileFront:
    """One file through the front end."""

    syntax: list[Diagnostic]  # reading, parsing, nesting, lexical rules (cascades dropped)
    unit: A.SourceUnit | None  # lowered; None after a syntax error
    lowering: list[Diagnostic] = field(default_factory=list)

    @property
    def syntax_errors(self) -> bool:
        return any(d.severity == "error" for d in self.syntax)


@contextmanager
def paused_gc() -> Iterator[None]:
    """The cyclic garbage collector off while a compilation builds its trees: it would scan
    them (and everything else the process holds) again and again as they grow, and they hold
    no garbage cycles worth collecting before the compilation ends. Back on afterwards, unless
    it was off before (e.g. paused by an enclosing compilation)."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


def compiler_version() -> bytes:
    """A digest of the compiler's own sources, data and runtime files (the name lists of
    rules.py, the C runtime header) and of the grammar and Python it runs on: a cache entry
    written by another compiler is never read."""
    import tree_sitter_iec61131_3_st as st_grammar

    h = hashlib.sha256(_FORMAT)
    h.update(sys.version.encode())
    h.update(str(Path(st_grammar.__file__).stat().st_mtime_ns).encode())
    sources = [*_COMPILER_DIR.glob("*.py"), *(_COMPILER_DIR / "data").iterdir(),
               *(_COMPILER_DIR / "runtime").iterdir()]
    for source in sorted(sources):
        if source.is_file():
            h.update(str(source.relative_to(_COMPILER_DIR)).encode())
            data = source.read_bytes()
            h.update(len(data).to_bytes(8, "little"))
            h.update(data)
    return h.digest()


@dataclass(frozen=True)
class _Pickled:
    """An entry's value already pickled (by the process that computed it)."""

    blob: bytes


class UnitCache:
    """Per-file front-end results and declared names, pickled under ``folder``.

    ``contents``: files already read (path -> bytes), taken from there instead of the disk,
    so that a compilation reads each file once (see programs.py). ``deferred``: entries are
    written by ``flush``, not when made (a build writes them while the C compiler runs)."""

    def __init__(self, folder: Path | None = None,
                 contents: Mapping[Path, bytes] | None = None, deferred: bool = False) -> None:
        self.folder = (cache_dir() if folder is None else folder) / "units"
        self._version = compiler_version()
        self._contents = {} if contents is None else contents
        self._deferred = deferred
        self._pending: list[tuple[Path, object]] = []

    def read(self, path: Path) -> bytes:
        """The file's bytes (OSError when it cannot be read)."""
        data = self._contents.get(path)
        return path.read_bytes() if data is None else data

    def _key(self, kind: str, path: Path, data: bytes) -> Path:
        h = hashlib.sha256(self._version)
        for part in (kind.encode(), str(path).encode(), data):
            h.update(len(part).to_bytes(8, "little"))
            h.update(part)
        return self.folder / f"{kind}_{h.hexdigest()[:32]}.pickle"

    def get(self, kind: str, path: Path, data: bytes, want: type) -> object | None:
        try:
            with open(self._key(kind, path, data), "rb") as f:
                blob = f.read()
        except OSError:
            return None
        try:
            with paused_gc():
                value = pickle.loads(blob)
        except Exception:  # noqa: BLE001 - any unreadable entry is a miss, then rewritten
            return None
        return value if isinstance(value, want) else None

    def put(self, kind: str, path: Path, data: bytes, value: object,
            pickled: bytes | None = None) -> None:
        """Store ``value`` (``pickled``: its bytes, when already pickled)."""
        target = self._key(kind, path, data)
        entry = value if pickled is None else _Pickled(pickled)
        if self._deferred:
            self._pending.append((target, entry))
        else:
            self._write(target, entry)

    def flush(self) -> None:
        """Write the entries ``put`` deferred."""
        pending, self._pending = self._pending, []
        for target, value in pending:
            self._write(target, value)

    def _write(self, target: Path, value: object) -> None:
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            blob = value.blob if isinstance(value, _Pickled) else pickle.dumps(
                value, protocol=pickle.HIGHEST_PROTOCOL)
            write_atomic(target, blob)
        except (OSError, pickle.PicklingError, RecursionError):
            pass  # not cached: the next run does the work again

    def fronts(self, paths: Sequence[Path]) -> list[FileFront]:
        """Each file through the front end, in order: from the cache, else computed, the
        files missing from the cache shared with a second process where that pays
        (front_split.py)."""
        out: list[FileFront | None] = []
        missing: list[tuple[int, Path, bytes]] = []
        for path in paths:
            try:
                data = self.read(path)
            except OSError:
                out.append(self.front(path))  # says it cannot be read
                continue
            hit = self.get("front", path, data, FileFront)
            out.append(hit if isinstance(hit, FileFront) else None)
            if hit is None:
                missing.append((len(out) - 1, path, data))
        computed = compute_all([(path, data) for _, path, data in missing], front_end,
                               FileFront)
        for (i, path, data), result in zip(missing, computed, strict=True):
            out[i] = result.value
            self.put("front", path, data, result.value, result.pickled)
        return [front for front in out if front is not None]

    def front(self, path: Path, data: bytes | None = None) -> FileFront:
        """The file through the front end (``data``: its bytes when already read)."""
        if data is None:
            try:
                data = self.read(path)
            except OSError as exc:
                return FileFront([Diagnostic(SourcePos(str(path), 1, 1), "E0001",
                                             f"cannot read {path}: {exc}")], None)
        hit = self.get("front", path, data, FileFront)
        if isinstance(hit, FileFront):
            return hit
        result = front_end(path, data)
        self.put("front", path, data, result)
        return result


def front_end(path: Path, data: bytes) -> FileFront:
    """The file through the front end, uncached."""
    diags = Diagnostics()
    pf = parse_source(path, data, diags)
    if pf is None:
        return FileFront(diags.items, None)
    check_syntax(pf, diags)
    drop_syntax_cascades(diags)
    if diags.has_errors:
        return FileFront(diags.items, None)
    lowering = Diagnostics()
    unit = lower(pf, lowering)
    return FileFront(diags.items, unit, lowering.items)
