"""Build: emitted C -> shared library, cached by content hash. Needs: a CUnit from emit_c.

An unchanged rebuild finds the library in the cache and never runs the C compiler. A large
program is compiled as several translation units at once, as many as there are CPUs to run
them (`plan_units`), and linked into one library: gcc's time grows with the amount of code, and
one compiler process uses one CPU. Beside each library lies its cffi declarations module
(declarations.py), written while the C compiles.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .atomic import write_atomic
from .emit_c import CUnit

RUNTIME_DIR = Path(__file__).parent / "runtime"
# -Og with -O2's inlining of small functions. -Og leaves out the -O1 passes that cost gcc most
# (points-to analysis, scalar replacement of aggregates, dead store elimination, ...): gcc
# compiles st/ in about 70 % of the CPU time of -O1 with the same inlining, -O1 in 55 % of -O2's.
# Measured interleaved in one run (bench/startup.py has the build figures): the IK kernel of
# bench/compiler_bench.py within 1 %, a 6-joint jerk-limited plan 11-13 % slower (a few
# microseconds, under 0.2 % of a 10 ms scan); without that inlining, code ran up to 45 % slower.
# -fcaller-saves (an -O2 pass: values live across a call may sit in registers the call
# clobbers, saved around it): without it -Og kept LREALs live across calls in integer
# registers, moving them to and from the FPU's at every use; the jerk-limited planner plans
# 6 joints 10-15 % faster with it (bench/jerk_timing.py), for about 3 % more gcc CPU time on
# st/. clang ignores it (and -finline-small-functions), with a warning.
# -ffp-contract=off: OpenPLC v3 compiles MatIEC's C with g++ at -O0, which fuses no
# multiply-add; gcc at -O2 on aarch64 (and clang by default) would fuse `x * y + z` into one
# rounding. No code change on x86-64 (no FMA without -mfma).
CFLAGS = ["-Og", "-finline-small-functions", "-fcaller-saves", "-ffp-contract=off", "-fPIC",
          "-shared", "-fwrapv", "-fno-strict-aliasing", "-std=gnu11", "-w"]
# POU code per translation unit below which another compiler process costs more (its start,
# the shared declarations parsed again) than it saves
MIN_UNIT_BYTES = 64_000


class BuildError(Exception):
    """The C compiler is missing or rejected the generated C."""


@dataclass(frozen=True)
class BuiltLibrary:
    path: Path
    cached: bool
    c_path: Path  # the program as one C file (the units of a split build are its parts)
    declarations: Path  # cffi's out-of-line module of the library's C declarations
    digest: str  # names the files in the cache folder (library_digest)
    units: int = 0  # translation units compiled (0: taken from the cache)


def _library(digest: str, units: int) -> BuiltLibrary:
    out_dir = cache_dir()
    return BuiltLibrary(out_dir / f"plc_{digest}.so", units == 0, out_dir / f"plc_{digest}.c",
                        out_dir / f"plc_{digest}_ffi.py", digest, units)


def cached_library(digest: str) -> BuiltLibrary | None:
    """The library built before under ``digest``, if it is still in the cache folder (its
    declarations module may not be: ffi.Module writes it anew then)."""
    lib = _library(digest, 0)
    return lib if lib.path.exists() else None


def cache_dir() -> Path:
    env = os.environ.get("ARMBENCH_CACHE")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "armbench"


def find_cc() -> str:
    for cand in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if cand and shutil.which(cand):
            return cand
    raise BuildError("no C compiler found: install one (Debian: apt-get install gcc) or set CC")


def usable_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def plan_units(pieces: Sequence[str], jobs: int, min_unit_bytes: int = MIN_UNIT_BYTES
               ) -> list[list[str]]:
    """The pieces (CUnit.pieces) in at most ``jobs`` translation units of about equal size
    and at least ``min_unit_bytes`` each, each a run of consecutive pieces (callees first: a
    POU's callees often land in its unit, where the C compiler can inline them)."""
    total = sum(len(p) for p in pieces)
    n = max(1, min(jobs, total // max(1, min_unit_bytes), len(pieces)))
    if n == 1:
        return [list(pieces)]
    groups: list[list[str]] = [[] for _ in range(n)]
    done = 0
    for piece in pieces:
        # the unit whose share of the bytes holds the middle of this piece
        groups[min(n - 1, (2 * done + len(piece)) * n // (2 * total))].append(piece)
        done += len(piece)
    return [g for g in groups if g]


def library_digest(unit: CUnit, flags: Sequence[str]) -> str:
    """What the library and its declarations module depend on: the C, its declarations, the
    runtime header, the flags and cffi (whose version the declarations module is written for).
    Not how the C is split into units: that changes the build's speed, not the program."""
    import cffi

    h = hashlib.sha256()
    for part in (unit.code.encode(), unit.decls.encode(),
                 (RUNTIME_DIR / "iec_runtime.h").read_bytes(), " ".join(flags).encode(),
                 cffi.__version__.encode()):
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:24]


def build(unit: CUnit, extra_flags: tuple[str, ...] = (), jobs: int | None = None,
          meanwhile: Callable[[BuiltLibrary], None] = lambda lib: None,
          min_unit_bytes: int = MIN_UNIT_BYTES) -> BuiltLibrary:
    """The library of ``unit``, from the cache or compiled as up to ``jobs`` translation
    units at once (default: one per usable CPU; see plan_units). ``meanwhile``: the caller's
    work, given the library to be, done while the C compiles (at once when nothing is)."""
    from .declarations import write_declarations  # cffi: imported by builds only

    flags = [*CFLAGS, *extra_flags]
    digest = library_digest(unit, flags)
    cached = _library(digest, 0)
    so, c_path, declarations = cached.path, cached.c_path, cached.declarations
    out_dir = so.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    if so.exists():
        meanwhile(cached)
        if not declarations.exists():  # written before the library: removed since
            write_declarations(unit.decls, declarations)
        return cached
    # Written under a temporary name and renamed, like the library: a concurrent build of the
    # same program (pytest-xdist workers on a cold cache) must never truncate the file while
    # this one's compiler reads it.
    write_atomic(c_path, unit.code, suffix=c_path.suffix)
    cc = find_cc()
    groups = plan_units(unit.pieces, usable_cpus() if jobs is None else jobs, min_unit_bytes)
    built = _library(digest, len(groups))
    # compile to a temporary name, then rename: concurrent builds never see a partial file
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=out_dir)
    os.close(fd)

    def while_compiling() -> None:
        meanwhile(built)
        write_declarations(unit.decls, declarations)

    try:
        if len(groups) == 1:
            _compile([(c_path, [cc, *flags, "-I", str(RUNTIME_DIR), str(c_path), "-o", tmp,
                                "-lm"])], while_compiling)
        else:
            _build_split(unit, groups, cc, flags, tmp, digest, while_compiling)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    os.replace(tmp, so)
    return built


def _build_split(unit: CUnit, groups: list[list[str]], cc: str, flags: list[str], out: str,
                 digest: str, meanwhile: Callable[[], None]) -> None:
    """Compile each group as a translation unit of its own (the first also holds the program's
    storage and entry points, CUnit.main), all at once, then link them into ``out``. The units'
    folder is removed after a good build and kept for the error message of a bad one."""
    folder = Path(tempfile.mkdtemp(prefix=f"plc_{digest}_units_", dir=Path(out).parent))
    jobs: list[tuple[Path, list[str]]] = []
    for i, group in enumerate(groups):
        src = folder / f"unit{i}.c"
        src.write_text("#include \"iec_runtime.h\"\n" + unit.shared + "".join(group) +
                       (unit.main if i == 0 else ""))
        defines = ["-DARMBENCH_SPLIT", *(["-DARMBENCH_SPLIT_MAIN"] if i == 0 else [])]
        jobs.append((src, [cc, *flags, *defines, "-I", str(RUNTIME_DIR), "-c", str(src),
                           "-o", str(src.with_suffix(".o"))]))
    try:
        _compile(jobs, meanwhile)
        objects = [str(src.with_suffix(".o")) for src, _ in jobs]
        _compile([(folder, [cc, *flags, *objects, "-o", out, "-lm"])], lambda: None)
    except BuildError:
        raise
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    shutil.rmtree(folder, ignore_errors=True)


def _compile(jobs: list[tuple[Path, list[str]]], meanwhile: Callable[[], None]) -> None:
    """Run the compiler commands at once, ``meanwhile`` while they run; a BuildError names the
    file of the first that failed."""
    procs: list[tuple[Path, subprocess.Popen[str]]] = []
    try:
        for src, cmd in jobs:
            procs.append((src, subprocess.Popen(cmd, stdout=subprocess.PIPE,
                                                stderr=subprocess.STDOUT, text=True)))
        meanwhile()
        failed = None
        for src, proc in procs:
            output, _ = proc.communicate()
            if proc.returncode != 0 and failed is None:
                failed = (src, output)
    finally:
        for _, proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    if failed is not None:
        src, output = failed
        raise BuildError(f"the C compiler rejected the generated code ({src}):\n"
                         f"{output[:4000]}")
