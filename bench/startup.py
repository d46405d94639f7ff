"""Start-up figures of the bench (prints figures; not a test).

1. `armbench check small.st` (a small program using one library function), cached caches;
2. `armbench run small.st --cycles 100`, cached build;
3. the library checked alone (st/*.st), in-process, cached caches;
4. a cold build of st/ (empty cache folder), in-process: front end (on Linux shared with a
   forked child, front_split.py), check, C, the C compiler (as many translation units at once
   as there are usable CPUs, build.plan_units) and cffi's declarations module;
5. a cached build of st/, in-process: the cache of compilations (compiler/programs.py) loads
   the checked program, the declarations module and the library, and nothing else runs.

Each line gives the best wall time of R runs and the CPU time (user+sys, the C compiler
included) of that run: the machine may be shared, and CPU time says what load cannot.
Machines differ by a factor of three here, so the first lines time two fixed workloads, a
Python loop and gcc on a fixed C file: compare figures of different machines through them.
An installed package has its bytecode compiled; with PYTHONDONTWRITEBYTECODE set every
`armbench` start compiles the modules it imports again (the header line says which).
Goals: check/run <= 0.5 s, cached build of st/ <= 0.2 s, cold build of st/ <= 2 s.
Run: PYTHONPATH=sim .venv/bin/python bench/startup.py [repeats]
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parent

SMALL = """
PROGRAM Main
VAR
  n : DINT;
  angle : REAL;
END_VAR
  n := n + 1;
  angle := DegToRad(DINT_TO_REAL(n));
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


@dataclass(frozen=True)
class Figure:
    wall: float
    cpu: float  # user+sys of this process's work and of its children


def _cpu() -> float:
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def measure(fn: Callable[[], object]) -> Figure:
    c0, t0 = _cpu(), time.perf_counter()
    fn()
    return Figure(time.perf_counter() - t0, _cpu() - c0)


def best(fn: Callable[[], object], repeat: int) -> Figure:
    return min((measure(fn) for _ in range(repeat)), key=lambda f: f.wall)


def cli(*args: str) -> Callable[[], object]:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "sim")}

    def run() -> None:
        subprocess.run([sys.executable, "-m", "armbench.cli", *args], env=env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return run


def python_reference() -> None:
    total = 0
    for i in range(5_000_000):
        total += i


def gcc_reference(folder: Path) -> Callable[[], object]:
    """gcc -O1 of 400 small C functions (a fixed file, not the library's C)."""
    from armbench.compiler.build import find_cc

    src = folder / "reference.c"
    src.write_text("".join(f"double f{k}(double x, int n) {{ double s = x; "
                           f"for (int i = 0; i < n; i++) s = s * 0.5 + i * {k}.0; "
                           f"return s > {k} ? s : -s; }}\n" for k in range(400)))

    def run() -> None:
        subprocess.run([find_cc(), "-O1", "-c", str(src), "-o", str(folder / "reference.o")],
                       check=True)
    return run


def line(what: str, fig: Figure, goal: float | None) -> None:
    goal_text = "" if goal is None else f" (goal <= {goal:g} s)"
    print(f"{what:<48} wall {fig.wall:6.3f} s  cpu {fig.cpu:6.3f} s{goal_text}", flush=True)


def main(repeat: int) -> None:
    sys.path.insert(0, str(ROOT / "sim"))
    from armbench.compiler import compile_files
    from armbench.compiler.build import plan_units, usable_cpus
    from armbench.compiler.driver import analyse_program, emit_files

    st_files = sorted((ROOT / "st").glob("*.st"))
    lines = sum(len(f.read_text().splitlines()) for f in st_files)
    bytecode = "not written (PYTHONDONTWRITEBYTECODE)" if os.environ.get(
        "PYTHONDONTWRITEBYTECODE") else "cached"
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; best of {repeat}; "
          f"Python bytecode {bytecode}")
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        os.environ["ARMBENCH_CACHE"] = str(cache)
        line("reference: a Python loop (5e6 additions)", best(python_reference, repeat), None)
        line("reference: gcc -O1 of a fixed C file", best(gcc_reference(Path(tmp)), repeat),
             None)
        small = Path(tmp) / "small.st"
        small.write_text(SMALL)
        cli("run", str(small))()  # fills the caches
        line("armbench check small.st", best(cli("check", str(small)), repeat), 0.5)
        line("armbench run small.st --cycles 100 (cached)",
             best(cli("run", str(small), "--cycles", "100"), repeat), 0.5)
        analyse_program(st_files)  # fills the caches of this process's cache folder

        def check_library() -> None:
            assert analyse_program(st_files).program is not None
        line(f"library check, st/ ({len(st_files)} files, {lines} lines)",
             best(check_library, repeat), None)

        def cold() -> None:
            with tempfile.TemporaryDirectory() as empty:
                os.environ["ARMBENCH_CACHE"] = empty
                compile_files(st_files)
        units = len(plan_units(emit_files(st_files)[1].pieces, usable_cpus()))
        line(f"cold build of st/ (empty cache, {units} C units)", best(cold, repeat), 2.0)
        os.environ["ARMBENCH_CACHE"] = str(cache)
        compile_files(st_files)
        line("cached build of st/", best(lambda: compile_files(st_files), repeat), 0.2)
        del os.environ["ARMBENCH_CACHE"]


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
