"""STruC++, OpenPLC v4's ST compiler, as a reference tool for the tests.

Found through the environment only (never vendored, never built by the repository):

- ``STRUCPP`` names its command line: a ``strucpp`` executable, or ``dist/node/cli.js`` of a
  checkout built with ``npm ci --ignore-scripts && npm run build`` (run with node);
- ``STRUCPP_RUNTIME`` names its C++ runtime headers (the folder holding ``iec_types.hpp``),
  default ``src/runtime/include`` of the checkout around ``STRUCPP``.

Tests that need it skip with :data:`SKIP_REASON` where it is unset.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

SKIP_REASON = ("STRUCPP not set: point it at STruC++'s dist/node/cli.js (a checkout of "
               "Autonomy-Logic/STruCpp built with `npm ci --ignore-scripts && npm run build`) "
               "or a strucpp executable; docs/exports.md says how")

# what OpenPLC v4's runtime compiles each POU's C++ with on the device
V4_CXX_FLAGS = ("-std=c++17", "-O1", "-pipe", "-fPIC")


@dataclass(frozen=True)
class Result:
    ok: bool
    output: str


@dataclass(frozen=True)
class Strucpp:
    command: tuple[str, ...]
    runtime: Path

    def compile(self, source: Path, output: Path, *extra: str,
                timeout: float = 600.0) -> Result:
        """ST -> C++ (``output`` and its header beside it)."""
        p = subprocess.run([*self.command, str(source), "-o", str(output), *extra],
                           capture_output=True, text=True, timeout=timeout, check=False)
        return Result(p.returncode == 0 and output.is_file(), p.stdout + p.stderr)

    def cxx(self, *args: str, timeout: float = 900.0) -> Result:
        """g++ with the runtime headers on the include path."""
        gxx = shutil.which("g++") or "g++"
        p = subprocess.run([gxx, "-std=c++17", f"-I{self.runtime}", *args],
                           capture_output=True, text=True, timeout=timeout, check=False)
        return Result(p.returncode == 0, p.stdout + p.stderr)


def find_strucpp() -> Strucpp | None:
    """STruC++ as the environment names it, or None where ``STRUCPP`` is unset. A set but
    wrong ``STRUCPP``/``STRUCPP_RUNTIME`` raises ValueError saying what is missing."""
    named = os.environ.get("STRUCPP", "")
    if not named:
        return None
    path = Path(named)
    if not path.is_file():
        raise ValueError(f"STRUCPP={named} is no file: point it at STruC++'s dist/node/cli.js "
                         "or a strucpp executable")
    if path.suffix == ".js":
        node = shutil.which("node")
        if node is None:
            raise ValueError(f"STRUCPP={named} is a node script, and no node is on the PATH")
        command: tuple[str, ...] = (node, str(path))
        default_runtime = path.resolve().parents[2] / "src" / "runtime" / "include"
    else:
        command = (str(path),)
        default_runtime = path.resolve().parent / "runtime" / "include"
    runtime = Path(os.environ.get("STRUCPP_RUNTIME", default_runtime))
    if not (runtime / "iec_types.hpp").is_file():
        raise ValueError(f"no iec_types.hpp in {runtime}: set STRUCPP_RUNTIME to STruC++'s "
                         "runtime headers (src/runtime/include of its checkout)")
    return Strucpp(command, runtime)
