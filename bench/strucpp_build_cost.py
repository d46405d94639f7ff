"""What OpenPLC v4 spends building the arm controller on the device (prints figures; not a
test), and what the library and the controller could do about it.

OpenPLC v4's path: the editor compiles the program with STruC++ on the PC and uploads its C++
(generated.hpp, configuration.cpp and one pou_<NAME>.cpp per PROGRAM, FUNCTION_BLOCK and
FUNCTION: STruC++'s codegen splits it so; tests/strucpp_tool.py's split_units cuts the CLI's
joined output into exactly those files); the runtime builds them on the device, one g++ per
file (scripts/Makefile.strucpp of Autonomy-Logic/openplc-runtime: `g++ -std=c++17 -O1 -pipe
-fPIC -DSTRUCPP_THREADED ...`, `make -j` with min(cores - 1, GB of RAM) jobs: 2 on a 2 GB
Pi 4, 3 on a 4 or 8 GB one; ccache when installed), and links them into one shared object.

1. STruC++ on plc_project/openplc/arm_controller.st (the editor's part, on the PC).
2. Every file compiled as v4's runtime compiles it: CPU (user + sys of that g++) and wall
   seconds per file, the slowest files, totals, and the wall time of the whole set on
   --jobs workers here. Peak memory per g++ too (v4 caps its jobs by RAM for that reason).
3. The shared headers' share: an empty file that includes only the runtime headers
   generated.hpp includes, and one that includes generated.hpp itself, compiled alike; their
   CPU times the number of files, against the total.
4. What else the v4 path allows, measured: the same C++ as ONE file (what the per-POU split
   costs); the library's POUs in one file with configuration.cpp and the controller's own
   POUs one per file -- the layout STruC++ gives a program whose library comes as an .stlib
   archive (`strucpp --compile-lib`: a library's reachable code goes into configuration.cpp,
   codegen.ts generateImplementation), with one concern per POU kept in the sources; and
   whether STruC++ accepts the controller against st/ compiled into such an archive.
5. With MATIEC_CHECK set (README, "Checking against the real MatIEC"): OpenPLC v3's build of
   the same upload file (MatIEC's iec2c, the runtime's C/C++ build and link), side by side.
6. A Raspberry Pi 4 estimate: SCALED, not measured. This machine's CPU seconds times
   --pi-factor (the assumed ratio of a Cortex-A72 at 1.5 GHz to this machine's core for
   cc1plus; default 4, and the lines for 3 and 6), spread over v4's 2 or 3 jobs, never below
   the slowest single file.

Not included: generated_debug.cpp (the debugger's tables, which STruC++'s compile API emits
and the editor uploads, but its CLI does not write) and the runtime's own
runtime_v4_entry.cpp: two more files on v4.

Run: STRUCPP=/path/to/STruCpp/dist/node/cli.js PYTHONPATH=sim .venv/bin/python
     bench/strucpp_build_cost.py [--jobs N] [--pi-factor F] [--top N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT / "tests"))  # the one locator of STruC++ (never a second one)

from strucpp_tool import (  # noqa: E402
    V4_CXX_FLAGS,
    CppUnit,
    Strucpp,
    find_strucpp,
    split_units,
)

CONTROLLER = ROOT / "plc_project" / "openplc" / "arm_controller.st"
# v4's runtime compiles every generated file with these on top of V4_CXX_FLAGS
V4_EXTRA = ("-DSTRUCPP_THREADED", "-fno-gnu-unique")
INCLUDE = re.compile(r'^#include "([^"]+)"', re.M)


@dataclass(frozen=True)
class Cost:
    """One g++ run: its own CPU (user + sys), wall and peak memory."""

    name: str
    cpu: float
    wall: float
    max_rss_mb: float
    ok: bool
    output: str = ""


def run_measured(cmd: Sequence[str], name: str, cwd: Path | None = None) -> Cost:
    """Run ``cmd`` and take its own resource usage from wait4 (exact per process, also
    when several run at once)."""
    start = time.perf_counter()
    proc = subprocess.Popen(list(cmd), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            cwd=cwd)
    assert proc.stdout is not None
    output = proc.stdout.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - start
    return Cost(name, usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024.0,
                proc.returncode == 0, output)


class Compiler:
    """g++ as v4's runtime calls it, with STruC++'s runtime headers."""

    def __init__(self, tool: Strucpp, folder: Path) -> None:
        self.tool = tool
        self.folder = folder

    def command(self, source: Path) -> list[str]:
        gxx = shutil.which("g++") or "g++"
        return [gxx, *V4_CXX_FLAGS, *V4_EXTRA, f"-I{self.folder}", f"-I{self.tool.runtime}",
                "-c", str(source), "-o", str(source.with_suffix(".o"))]

    def compile(self, source: Path) -> Cost:
        return run_measured(self.command(source), source.name)

    def compile_all(self, sources: Sequence[Path], jobs: int) -> tuple[list[Cost], float]:
        """Every file, ``jobs`` at a time (make -jN); the costs and the wall time of all."""
        start = time.perf_counter()
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            costs = list(pool.map(self.compile, sources))
        return costs, time.perf_counter() - start

    def best_of(self, source: Path, repeats: int = 3) -> Cost:
        """The cheapest of a few runs (a shared machine's load only ever adds)."""
        return min((self.compile(source) for _ in range(repeats)), key=lambda c: c.cpu)


def write_units(folder: Path, header: Path, units: Sequence[CppUnit]) -> list[Path]:
    """The files as v4's upload holds them: generated.hpp and the .cpp files beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    text = header.read_text(encoding="utf-8")
    (folder / "generated.hpp").write_text(text, encoding="utf-8")
    paths = []
    for u in units:
        path = folder / u.name
        # the CLI's units include the header by its output name; v4's include generated.hpp
        path.write_text(u.text.replace(f'#include "{header.name}"', '#include "generated.hpp"'),
                        encoding="utf-8")
        paths.append(path)
    return paths


def library_pou_names() -> set[str]:
    """Upper-case names of the POUs st/*.st declares (the library's part of the upload)."""
    names: set[str] = set()
    pou = re.compile(r"^\s*(?:FUNCTION_BLOCK|FUNCTION|PROGRAM)\s+(\w+)", re.M | re.I)
    comment = re.compile(r"\(\*.*?\*\)", re.S)
    for f in sorted((ROOT / "st").glob("*.st")):
        names |= {n.upper() for n in pou.findall(comment.sub("", f.read_text(encoding="utf-8")))}
    return names


def joined(units: Sequence[CppUnit], name: str) -> CppUnit:
    """Several translation units as one (each includes generated.hpp once: #pragma once)."""
    return CppUnit(name, "\n".join(u.text for u in units))


def strucpp_against_stlib(tool: Strucpp, work: Path) -> str:
    """Compile st/ into an .stlib archive and the controller's own sources against it: what
    STruC++ says (its first errors), or that it accepts them."""
    lib_src = work / "stlib_src"
    shutil.copytree(ROOT / "st", lib_src)
    out = work / "stlib"
    # the bundled standard FB library: libs/ of a checkout (runtime in src/runtime/include)
    # or of a release (runtime/include beside libs/)
    rt = Path(tool.runtime).resolve()
    libs = next((p for p in (rt.parents[2] / "libs", rt.parents[1] / "libs") if p.is_dir()),
                rt.parents[2] / "libs")
    cmd = [*tool.command, "--compile-lib", str(lib_src), "-o", str(out),
           "--lib-name", "armbench", "-L", str(libs)]
    made = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    if made.returncode != 0:
        return "STruC++ --compile-lib refuses st/: " + (made.stdout + made.stderr)[-800:]
    plc = ROOT / "plc_project"
    files = [plc / "Controller.st", *sorted((plc / "controller").glob("*.st"))]
    res = subprocess.run([*tool.command, *map(str, files), "-o", str(work / "ctl_lib.cpp"),
                          "-L", str(out)], capture_output=True, text=True, timeout=600,
                         check=False)
    if res.returncode == 0:
        return "STruC++ accepts the controller against st/ as an .stlib archive"
    errors = [ln.strip() for ln in (res.stdout + res.stderr).splitlines() if ": error:" in ln]
    kinds = sorted({re.sub(r"^.*?error: ", "", e) for e in errors})
    return (f"STruC++ refuses the controller against st/ as an .stlib archive: {len(errors)} "
            f"errors, e.g. {'; '.join(kinds[:4])}")


def matiec_build(check: Path, source: Path) -> tuple[bool, float, float]:
    """OpenPLC v3's build of ``source`` ($MATIEC_CHECK): ok, wall, CPU of all children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    res = subprocess.run([shutil.which("bash") or "/bin/bash", str(check), str(source)],
                         capture_output=True, text=True, timeout=1800, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return res.returncode == 0, wall, cpu


def pi_wall(cpu_total: float, slowest: float, factor: float, jobs: int) -> float:
    """Scaled wall time of a build on ``jobs`` cores: the work spread evenly, but never
    shorter than its slowest file."""
    return max(cpu_total * factor / jobs, slowest * factor)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--jobs", type=int, default=2, help="files compiled at once here")
    ap.add_argument("--pi-factor", type=float, default=4.0,
                    help="assumed cc1plus slowdown of a Pi 4 core against this machine's")
    ap.add_argument("--top", type=int, default=12, help="slowest files to list")
    ap.add_argument("--keep", type=Path, help="keep the generated files in this folder")
    args = ap.parse_args(argv)

    try:
        tool = find_strucpp()
    except ValueError as exc:
        print(f"strucpp_build_cost: {exc}")
        return 2
    if tool is None:
        print("strucpp_build_cost: skipped, STRUCPP not set (docs/exports.md says how to "
              "build STruC++ and where to point STRUCPP)")
        return 0
    work = args.keep or Path(tempfile.mkdtemp(prefix="strucpp_cost_"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}; CPU seconds are "
          "user + sys of each g++ (what load cannot change), wall seconds what it took here")

    # 1. the editor's part
    cli_out = work / "controller.cpp"
    st = run_measured([*tool.command, str(CONTROLLER), "-o", str(cli_out)], "strucpp")
    if not st.ok:
        print(st.output[-3000:])
        return 1
    units = split_units(cli_out.read_text(encoding="utf-8"))
    print(f"\n1. STruC++ (on the PC, in the editor): {st.wall:.1f} s wall, {st.cpu:.1f} s CPU "
          f"-> {len(units)} files ({len(units) - 1} POUs + configuration.cpp)")

    # 2. the device's part, file by file
    v4 = work / "v4"
    sources = write_units(v4, cli_out.with_suffix(".hpp"), units)
    gxx = Compiler(tool, v4)
    costs, wall_all = gxx.compile_all(sources, args.jobs)
    failed = [c for c in costs if not c.ok]
    if failed:
        print(f"g++ fails on {failed[0].name}:\n{failed[0].output[-3000:]}")
        return 1
    cpu_total = sum(c.cpu for c in costs)
    slowest = max(costs, key=lambda c: c.cpu)
    print(f"\n2. v4's build here, one g++ per file ({' '.join(V4_CXX_FLAGS + V4_EXTRA)}):")
    print(f"   {len(costs)} files: {cpu_total:.1f} s CPU in all, {wall_all:.1f} s wall on "
          f"{args.jobs} workers; per file median "
          f"{sorted(c.cpu for c in costs)[len(costs) // 2]:.2f} s CPU, peak memory "
          f"{max(c.max_rss_mb for c in costs):.0f} MB")
    print(f"   slowest {args.top} (CPU s, wall s, MB):")
    for c in sorted(costs, key=lambda c: -c.cpu)[:args.top]:
        print(f"     {c.name:40} {c.cpu:6.2f} {c.wall:6.2f} {c.max_rss_mb:6.0f}")

    # 3. the headers' share
    header_text = (v4 / "generated.hpp").read_text(encoding="utf-8")
    runtime_only = v4 / "probe_runtime_headers.cpp"
    runtime_only.write_text("".join(f'#include "{h}"\n' for h in INCLUDE.findall(header_text)),
                            encoding="utf-8")
    with_header = v4 / "probe_generated_hpp.cpp"
    with_header.write_text('#include "generated.hpp"\n', encoding="utf-8")
    rt, gen = gxx.best_of(runtime_only), gxx.best_of(with_header)
    shared = gen.cpu * len(costs)
    print(f"\n3. an empty file with the runtime headers alone: {rt.cpu:.2f} s CPU; with "
          f"generated.hpp (those + the controller's declarations): {gen.cpu:.2f} s CPU")
    print(f"   x {len(costs)} files = {shared:.1f} s of {cpu_total:.1f} s: the shared headers "
          f"are {100 * shared / cpu_total:.0f} % of the build "
          f"(the runtime's headers alone {100 * rt.cpu * len(costs) / cpu_total:.0f} %), "
          f"the POUs' own code {cpu_total - shared:.1f} s")
    small = [c for c in costs if c.cpu < gen.cpu + 0.15]
    print(f"   {len(small)} of {len(costs)} files cost less than 0.15 s CPU more than that "
          "empty file: their POU's own code is next to nothing")

    # 4. other layouts of the same C++
    library = library_pou_names()
    lib_units = [u for u in units[1:] if u.name[4:-4] in library]
    own_units = [u for u in units[1:] if u.name[4:-4] not in library]
    one = write_units(work / "one_file", cli_out.with_suffix(".hpp"),
                      [joined(units, "controller_all.cpp")])
    lib_layout = write_units(work / "stlib_layout", cli_out.with_suffix(".hpp"),
                             [joined([units[0], *lib_units], "configuration.cpp"), *own_units])
    one_cost = Compiler(tool, one[0].parent).compile(one[0])
    lib_costs, lib_wall = Compiler(tool, lib_layout[0].parent).compile_all(lib_layout,
                                                                           args.jobs)
    for c in (one_cost, *lib_costs):
        if not c.ok:
            print(f"g++ fails on {c.name}:\n{c.output[-3000:]}")
            return 1
    lib_cpu = sum(c.cpu for c in lib_costs)
    lib_slowest = max(lib_costs, key=lambda c: c.cpu)
    print(f"\n4. the same C++ laid out otherwise (files of the upload: {len(lib_units)} "
          f"library POUs, {len(own_units)} controller POUs, configuration.cpp):")
    print(f"   all in one file: {one_cost.cpu:.1f} s CPU ({one_cost.max_rss_mb:.0f} MB) -- "
          f"the split costs {cpu_total - one_cost.cpu:.1f} s CPU more, and buys parallel "
          "jobs and ccache reuse")
    print(f"   the library's POUs in configuration.cpp, the controller's {len(own_units)} one "
          f"per file (the .stlib layout): {len(lib_costs)} files, {lib_cpu:.1f} s CPU, "
          f"{lib_wall:.1f} s wall on {args.jobs} workers; slowest {lib_slowest.name} "
          f"{lib_slowest.cpu:.1f} s CPU, {lib_slowest.max_rss_mb:.0f} MB")
    print(f"   {strucpp_against_stlib(tool, work)}")

    # 5. OpenPLC v3, side by side
    check = os.environ.get("MATIEC_CHECK", "")
    v3: tuple[bool, float, float] | None = None
    if check and Path(check).is_file():
        v3 = matiec_build(Path(check), CONTROLLER)
        print(f"\n5. OpenPLC v3's build of the same file ($MATIEC_CHECK: iec2c, the runtime's "
              f"C/C++, link): {'ok' if v3[0] else 'FAILED'}, {v3[1]:.1f} s wall, "
              f"{v3[2]:.1f} s CPU; v4 per file: {cpu_total:.1f} s CPU "
              f"({cpu_total / max(v3[2], 1e-9):.1f} x)")
    else:
        print("\n5. OpenPLC v3 side by side: skipped, MATIEC_CHECK not set (README, "
              "'Checking against the real MatIEC')")

    # 6. a Pi 4, scaled
    print(f"\n6. Raspberry Pi 4, SCALED (not measured): this machine's CPU seconds x "
          f"{args.pi_factor:g} (assumed), spread over v4's jobs (compile.sh: 2 on a 2 GB Pi 4,"
          f" 3 on 4/8 GB), never below the slowest file:")
    for factor in sorted({3.0, args.pi_factor, 6.0}):
        line = []
        for label, cpu, slow in (("v4 per POU", cpu_total, slowest.cpu),
                                 (".stlib layout", lib_cpu, lib_slowest.cpu),
                                 ("one file", one_cost.cpu, one_cost.cpu)):
            line.append(f"{label} {pi_wall(cpu, slow, factor, 2):4.0f}/"
                        f"{pi_wall(cpu, slow, factor, 3):4.0f} s")
        extra = f", v3 {v3[2] * factor:4.0f} s (one job)" if v3 else ""
        print(f"   x{factor:g}: " + "; ".join(line) + f" (-j2/-j3){extra}")
    print(f"   peak g++ memory here: {max(c.max_rss_mb for c in costs):.0f} MB per file "
          f"(the runtime allows one job per GB)")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
