"""Build: emitted C -> shared library, cached by content hash. Needs: a CUnit from emit_c.

An unchanged rebuild finds the library in the cache and never runs the C compiler.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .emit_c import CUnit

RUNTIME_DIR = Path(__file__).parent / "runtime"
CFLAGS = ["-O2", "-fPIC", "-shared", "-fwrapv", "-fno-strict-aliasing", "-std=gnu11",
          "-w"]


class BuildError(Exception):
    """The C compiler is missing or rejected the generated C."""


@dataclass(frozen=True)
class BuiltLibrary:
    path: Path
    cached: bool
    c_path: Path


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


def build(unit: CUnit, extra_flags: tuple[str, ...] = ()) -> BuiltLibrary:
    runtime = (RUNTIME_DIR / "iec_runtime.h").read_bytes()
    h = hashlib.sha256()
    for part in (unit.code.encode(), runtime, " ".join(CFLAGS + list(extra_flags)).encode()):
        h.update(part)
        h.update(b"\0")
    digest = h.hexdigest()[:24]
    out_dir = cache_dir()
    out_dir.mkdir(parents=True, exist_ok=True)
    so = out_dir / f"plc_{digest}.so"
    c_path = out_dir / f"plc_{digest}.c"
    if so.exists():
        return BuiltLibrary(so, True, c_path)
    # Written under a temporary name and renamed, like the library: a concurrent build of the
    # same program (pytest-xdist workers on a cold cache) must never truncate the file while
    # this one's compiler reads it.
    fd, tmp_c = tempfile.mkstemp(suffix=".c", dir=out_dir)
    with os.fdopen(fd, "w") as f:
        f.write(unit.code)
    os.replace(tmp_c, c_path)
    cc = find_cc()
    # compile to a temporary name, then rename: concurrent builds never see a partial file
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=out_dir)
    os.close(fd)
    cmd = [cc, *CFLAGS, *extra_flags, "-I", str(RUNTIME_DIR), str(c_path), "-o", tmp, "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        Path(tmp).unlink(missing_ok=True)
        raise BuildError(f"the C compiler rejected the generated code ({c_path}):\n"
                         f"{proc.stderr[:4000]}")
    os.replace(tmp, so)
    return BuiltLibrary(so, False, c_path)
