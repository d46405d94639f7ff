"""STruC++ (OpenPLC v4's ST compiler: ST -> C++17 and a header-only runtime) as a reference
compiler of the library and the controller, as MatIEC and RuSTy are.

Runs where STRUCPP names STruC++ (tests/strucpp_tool.py finds it, docs/exports.md says how
to build it); skipped otherwise.

1. What STruC++ builds: the whole library (st/*.st in dependency order), each st/ file alone
   with what it uses of the others (as `armbench export` uploads it), and the controller's
   OpenPLC upload file plc_project/openplc/arm_controller.st (CONFIGURATION Config0 / Res0).
   STruC++ must accept each and g++ must compile its C++ against STruC++'s runtime headers,
   unmodified: the library and the controller to objects (`-std=c++17 -O1 -c`; the
   controller with the flags of OpenPLC v4's runtime build, scripts/Makefile.strucpp:
   `-O1 -pipe -fPIC -DSTRUCPP_THREADED`), each single file with `-fsyntax-only` (the same
   C++ is compiled to objects by the whole-library build; checking it again per file would
   triple the suite's time). With a checkout (STRUCPP = its dist/node/cli.js) also what
   STruC++'s compile API gives OpenPLC v4's editor: the same per-POU files as the CLI's
   output cut by split_units, and the debugger's generated_debug.cpp, which must compile for
   the controller and for a PROGRAM holding an instance of every FUNCTION_BLOCK of st/ and of
   the controller's blocks (STruC++ writes a 2-D array's elements there as X[i][j], which its
   runtime cannot index: E0511 keeps such arrays out of the blocks' state).
2. What STruC++ computes (strucpp_cases.py): library POUs called on many inputs by generated
   PROGRAMs; the same source runs on STruC++ (its C++ and a main of ours) and on the bench
   compiler. Integers and BOOLs must be equal, REAL and LREAL values within a few units in
   the last place at the output's scale (AGREE_ULPS), and both compilers' answers within the
   unit tests' tolerances of independent references. Run with -s for the figures.
3. No untyped decimal integer literal above 2^53 in the sources (needs no STruC++): STruC++
   passes it through a JavaScript double, so 2^61 and 2^63 - 1 came out wrong; the library
   writes LINT#... for those.

Builds run two at a time (STruC++'s node process and g++ are single-threaded) and are cached
for the session.
"""

from __future__ import annotations

import os
import re
import subprocess
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import strucpp_cases
from every_block import INSTANCE_PREFIX, every_block_source
from strucpp_values import (
    Values,
    agreement,
    bench_values,
    cpp_main,
    parse_printed,
    source_text,
)

from armbench.export.generate import load_sources
from armbench.export.openplc import upload_text
from armbench.locate import Project
from strucpp_tool import SKIP_REASON, V4_CXX_FLAGS, Result, Strucpp, find_strucpp, split_units

REPO = Path(__file__).resolve().parents[2]
PROJECT = Project(REPO)
CONTROLLER_UPLOAD = REPO / "plc_project" / "openplc" / "arm_controller.st"
# REAL (LREAL) answers of STruC++ and the bench agree within this many float32 (float64)
# units in the last place at the larger of the two values and the output's scale; measured
# worst 2.2 (the damped IK's converged joints), 1.5 (the Jacobian); Madgwick's quaternion,
# once 1.5, is bit-equal since the bench computes REAL literals in double as both compilers do
AGREE_ULPS = 4.0
# v4's runtime build defines this (its only execution model)
V4_THREADED = "-DSTRUCPP_THREADED"


def library_files() -> list[Path]:
    return PROJECT.library()


# ------------------------------------------------------------------ builds, two at a time
@dataclass(frozen=True)
class Build:
    """One STruC++ compile and the g++ run on its C++."""

    source: Path
    cpp: Path
    strucpp: Result
    gxx: Result | None

    @property
    def ok(self) -> bool:
        return self.strucpp.ok and self.gxx is not None and self.gxx.ok

    def report(self) -> str:
        if not self.strucpp.ok:
            return f"STruC++ refuses {self.source.name}:\n{self.strucpp.output[-6000:]}"
        assert self.gxx is not None
        return f"g++ fails on STruC++'s C++ of {self.source.name}:\n{self.gxx.output[-6000:]}"


@dataclass(frozen=True)
class ValueRun:
    """The value programs (by name) and their outputs on both compilers, by instance and
    output name."""

    build: Build
    cases: dict[str, strucpp_cases.ValueCase]
    strucpp: dict[str, Values]
    bench: dict[str, Values]


class Builds:
    """The session's builds in a pool of two workers, each started once and kept."""

    def __init__(self, tool: Strucpp, root: Path, prefetch: bool) -> None:
        self.tool = tool
        self.root = root
        # start builds before a test asks for them: in one process only (pytest-xdist's
        # workers each run a share of the tests and would all build everything)
        self.prefetch = prefetch
        self.pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="strucpp")
        self.jobs: dict[str, Future[Any]] = {}
        # the armbench front end in one thread at a time (it is Python: nothing to gain)
        self.armbench = threading.Lock()

    def _job(self, key: str, work: Callable[[], Any]) -> Future[Any]:
        if key not in self.jobs:
            self.jobs[key] = self.pool.submit(work)
        return self.jobs[key]

    def _build(self, name: str, text: str, *gxx: str) -> Build:
        folder = self.root / name
        folder.mkdir()
        source = folder / f"{name}.st"
        source.write_text(text, encoding="utf-8")
        cpp = folder / f"{name}.cpp"
        compiled = self.tool.compile(source, cpp)
        if not compiled.ok:
            return Build(source, cpp, compiled, None)
        return Build(source, cpp, compiled, self.tool.cxx(*gxx, str(cpp)))

    # the whole library, each file, the controller: what the tests below ask for
    def library(self) -> Future[Build]:
        def work() -> Build:
            with self.armbench:
                _, sources = load_sources(library_files(), PROJECT, library=[],
                                          need_config=False)
            text = "\n".join(s.text for s in sources)
            return self._build("library", text, "-O1", "-c", "-o",
                               str(self.root / "library.o"))
        return self._job("library", work)

    def single_file(self, path: Path) -> Future[Build]:
        def work(path: Path = path) -> Build:
            with self.armbench:
                _, sources = load_sources([path], PROJECT, library=library_files(),
                                          need_config=False)
            text = "\n".join(upload_text(s) for s in sources)
            return self._build(f"file_{path.stem}", text, "-O1", "-fsyntax-only")
        # all of them at once, so that both workers stay busy while the tests wait in turn
        for other in library_files() if self.prefetch else []:
            self._job(f"file:{other.name}", lambda other=other: work(other))
        return self._job(f"file:{path.name}", lambda: work(path))

    def controller(self) -> Future[Build]:
        def work() -> Build:
            return self._build("arm_controller", CONTROLLER_UPLOAD.read_text(encoding="utf-8"),
                               *V4_CXX_FLAGS[1:], V4_THREADED, "-c", "-o",
                               str(self.root / "arm_controller.o"))
        return self._job("controller", work)

    def editor_files(self) -> Future[tuple[Result, Path]]:
        """The controller through STruC++'s compile API, as the v4 editor gets it."""
        def work() -> tuple[Result, Path]:
            folder = self.root / "editor"
            return self.tool.api_files(CONTROLLER_UPLOAD, folder), folder
        return self._job("editor", work)

    def every_block(self) -> Future[tuple[Result, Path]]:
        """A PROGRAM holding one instance of every FUNCTION_BLOCK of st/ and
        plc_project/controller/ (every_block.py), with the whole library, in a CONFIGURATION,
        through STruC++'s compile API as the v4 editor gets it."""
        def work() -> tuple[Result, Path]:
            folder = self.root / "every_block"
            with self.armbench:
                source = every_block_source(folder)
            return self.tool.api_files(source, folder / "api"), folder / "api"
        return self._job("every_block", work)

    def values(self) -> Future[ValueRun]:
        def work() -> ValueRun:
            from armbench.compiler import compile_files

            cases = strucpp_cases.available_cases()
            programs = [c.program for c in cases.values()]
            folder = self.root / "values_st"
            folder.mkdir()
            probe = folder / "programs.st"
            probe.write_text(source_text("", programs), encoding="utf-8")
            # the programs with what they use of the library, in dependency order
            with self.armbench:
                _, sources = load_sources([probe], PROJECT, library=library_files(),
                                          need_config=False)
            text = "\n".join(upload_text(s) if s.library else s.text for s in sources)
            main = self.root / "values_main.cpp"
            main.write_text(cpp_main("values.hpp", programs), encoding="utf-8")
            exe = self.root / "values_run"
            build = self._build("values", text, "-O1", "-I", str(self.root / "values"),
                                str(main), "-o", str(exe))
            if not build.ok:
                return ValueRun(build, cases, {}, {})
            run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300,
                                 check=False)
            assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
            with self.armbench:
                bench = bench_values(compile_files([build.source]), programs)
            return ValueRun(build, cases, parse_printed(run.stdout, programs), bench)
        return self._job("values", work)


@pytest.fixture(scope="session")
def strucpp() -> Strucpp:
    try:
        tool = find_strucpp()
    except ValueError as exc:  # STRUCPP set but wrong: say so, do not skip
        pytest.fail(str(exc))
    if tool is None:
        pytest.skip(SKIP_REASON)
    return tool


@pytest.fixture(scope="session")
def builds(strucpp: Strucpp, tmp_path_factory: pytest.TempPathFactory,
           request: pytest.FixtureRequest) -> Iterator[Builds]:
    b = Builds(strucpp, tmp_path_factory.mktemp("strucpp"),
               prefetch=os.environ.get("PYTEST_XDIST_WORKER") is None)
    # start what the selected tests will ask for, the longest first, so that both workers
    # stay busy while the tests wait for their builds in turn
    selected = {item.name.split("[")[0] for item in request.session.items
                if item.path == Path(__file__)} if b.prefetch else set()
    for test, start in (("test_strucpp_computes_as_the_bench_and_the_references", b.values),
                        ("test_strucpp_builds_the_controller", b.controller),
                        ("test_strucpp_output_splits_one_unit_per_pou", b.controller),
                        ("test_strucpp_debug_table_of_the_controller_builds",
                         b.editor_files),
                        ("test_strucpp_debug_table_of_every_block_builds", b.every_block),
                        ("test_strucpp_builds_the_library", b.library)):
        if test in selected:
            start()
    yield b
    b.pool.shutdown(wait=True, cancel_futures=True)


# ------------------------------------------------------------------ 1. what STruC++ builds
def test_strucpp_builds_the_library(builds: Builds) -> None:
    build = builds.library().result()
    assert build.ok, build.report()


@pytest.mark.parametrize("path", library_files(), ids=lambda p: p.name)
def test_strucpp_builds_each_file_with_what_it_uses(builds: Builds, path: Path) -> None:
    build = builds.single_file(path).result()
    assert build.ok, build.report()


def test_strucpp_builds_the_controller(builds: Builds) -> None:
    build = builds.controller().result()
    assert build.ok, build.report()
    header = build.cpp.with_suffix(".hpp").read_text(encoding="utf-8")
    units = split_units(build.cpp.read_text(encoding="utf-8"))
    # the OpenPLC runtime runs CONFIGURATION Config0 / RESOURCE Res0 and its periodic task
    assert "class Configuration_CONFIG0 : public ConfigurationInstance" in header
    assert 'ResourceInstance("RES0", "PLC"' in units[0].text, units[0].text[-2000:]
    assert re.search(r'TaskInstance\("\w+", \d+LL', units[0].text), units[0].text[-2000:]


def test_strucpp_output_splits_one_unit_per_pou(builds: Builds) -> None:
    """The controller's C++ as v4's runtime receives it (bench/strucpp_build_cost.py times
    these files): configuration.cpp and one pou_NAME.cpp per PROGRAM, FUNCTION_BLOCK and
    FUNCTION of the upload file, as our parser sees them."""
    from armbench.compiler import ast as A
    from armbench.compiler.diagnostics import Diagnostics
    from armbench.compiler.frontend import check_syntax
    from armbench.compiler.lower import lower
    from armbench.compiler.parse import parse_text

    build = builds.controller().result()
    assert build.strucpp.ok, build.report()
    diags = Diagnostics()
    parsed = parse_text(str(CONTROLLER_UPLOAD), CONTROLLER_UPLOAD.read_text(encoding="utf-8"),
                        diags)
    check_syntax(parsed, diags)
    unit: A.SourceUnit = lower(parsed, diags)
    assert not diags.has_errors, diags.sorted()
    names = [u.name for u in split_units(build.cpp.read_text(encoding="utf-8"))]
    assert names[0] == "configuration.cpp"
    assert sorted(names[1:]) == sorted(f"pou_{p.name.upper()}.cpp" for p in unit.pous)


def test_strucpp_api_gives_the_files_the_cli_split_gives(builds: Builds) -> None:
    """What the v4 editor gets from STruC++'s compile API (cppFiles) is what split_units cuts
    from the CLI's output, file by file."""
    if builds.tool.dist is None:
        pytest.skip("STRUCPP names no checkout: its compile API is not at hand")
    made, folder = builds.editor_files().result()
    assert made.ok, made.output[-4000:]
    cli = builds.controller().result()
    assert cli.strucpp.ok, cli.report()
    units = split_units(cli.cpp.read_text(encoding="utf-8"))
    api = sorted(p.name for p in folder.glob("*.cpp") if p.name != "generated_debug.cpp")
    assert api == sorted(u.name for u in units)
    for u in units:
        want = u.text.replace(f'#include "{cli.cpp.with_suffix(".hpp").name}"',
                              '#include "generated.hpp"', 1)
        assert (folder / u.name).read_text(encoding="utf-8") == want, u.name


def test_strucpp_debug_table_of_the_controller_builds(builds: Builds) -> None:
    """generated_debug.cpp, which the v4 editor uploads and the runtime compiles with the
    rest (scripts/Makefile.strucpp), must compile too. STruC++ 0.6.1 writes a 2-D array's
    element as X[i][j] there, which the runtime's IEC_ARRAY_2D cannot index: the controller
    held Mat3 and ARRAY[0..64, 1..3] members (435 g++ errors) before E0511 kept them out."""
    if builds.tool.dist is None:
        pytest.skip("STRUCPP names no checkout: its compile API is not at hand")
    made, folder = builds.editor_files().result()
    assert made.ok, made.output[-4000:]
    table = folder / "generated_debug.cpp"
    assert table.is_file(), "STruC++ wrote no debug table for the controller"
    res = builds.tool.cxx(*V4_CXX_FLAGS[1:], V4_THREADED, f"-I{folder}", "-fsyntax-only",
                          str(table))
    failures = debug_table_failures(table, res.output)
    assert res.ok, (f"g++ fails on the controller's debug table: {failures}\n"
                    + "\n".join(ln for ln in res.output.splitlines()
                                if ": error: " in ln)[:3000])


def debug_table_failures(table: Path, gxx_output: str) -> dict[str, dict[str, int]]:
    """g++'s errors on a generated_debug.cpp, by the variable path each failing line's
    comment names: {instance: {member: errors}} (member without its subscripts, nested
    members joined by '.'); an error on a line without a variable path counts under ''."""
    lines = table.read_text(encoding="utf-8").splitlines()
    found: dict[str, dict[str, int]] = {}
    for m in re.finditer(rf"{re.escape(table.name)}:(\d+):\d+: error: ", gxx_output):
        line = lines[int(m[1]) - 1]
        path = line.rsplit("// ", 1)[1] if "// " in line else ""
        parts = path.split(".")
        instance = parts[1] if len(parts) > 1 else ""
        member = re.sub(r"\[[^]]*\]", "", ".".join(parts[2:]))
        per = found.setdefault(instance, {})
        per[member] = per.get(member, 0) + 1
    return found


def test_strucpp_debug_table_of_every_block_builds(builds: Builds) -> None:
    """Users instantiate the library's blocks in their own PROGRAMs, and the debugger's table
    of such a program names every member of every instance (VAR, VAR_INPUT, VAR_OUTPUT,
    VAR_IN_OUT, through STRUCTs and FB instances): it must compile for every
    FUNCTION_BLOCK of st/ and of the controller's blocks. A 2-D array there is written
    X[i][j], which IEC_ARRAY_2D cannot index (E0511). Run with -s for the table's size."""
    if builds.tool.dist is None:
        pytest.skip("STRUCPP names no checkout: its compile API is not at hand")
    made, folder = builds.every_block().result()
    assert made.ok, made.output[-4000:]
    table = folder / "generated_debug.cpp"
    assert table.is_file(), "STruC++ wrote no debug table for the every-block program"
    entries = table.read_text(encoding="utf-8").count("// EVERY.")
    print(f"\ngenerated_debug.cpp of every block: {entries} entries")
    res = builds.tool.cxx(*V4_CXX_FLAGS[1:], V4_THREADED, f"-I{folder}", "-fsyntax-only",
                          str(table))
    failures = debug_table_failures(table, res.output)
    report = "\n".join(
        f"  {inst.removeprefix(INSTANCE_PREFIX)}: {sum(m.values())} errors in "
        + ", ".join(f"{k} ({v})" for k, v in sorted(m.items()))
        for inst, m in sorted(failures.items()))
    assert res.ok and not failures, (
        f"g++ fails on the debug table of {len(failures)} blocks' instances:\n{report}\n"
        + "\n".join(ln for ln in res.output.splitlines() if ": error: " in ln)[:3000])


# ------------------------------------------------------------------ 2. what STruC++ computes
@pytest.mark.parametrize("spec", strucpp_cases.SPECS, ids=[s.name for s in strucpp_cases.SPECS])
def test_strucpp_computes_as_the_bench_and_the_references(builds: Builds,
                                                          spec: strucpp_cases.CaseSpec) -> None:
    if spec.missing():
        pytest.skip(f"the reference needs {', '.join(spec.missing())}")
    run = builds.values().result()
    assert run.build.ok, run.build.report()
    case = run.cases[spec.name]
    inst = case.program.instance.upper()
    ours, bench = run.strucpp[inst], run.bench[inst]
    lines = [f"\n{case.title}: STruC++ vs bench"]
    problems = []
    for agr in agreement(case.program, ours, bench, case.scales):
        lines.append(f"  {agr.line()}")
        if agr.mismatches or agr.worst_ulps > AGREE_ULPS:
            problems.append(f"{agr.out.name}: {agr.line()} {agr.mismatches[:5]}")
    for who, values in (("STruC++", ours), ("bench", bench)):
        for check in case.reference(values):
            lines.append(f"  {who:8} {check.line()}")
            if not check.ok:
                problems.append(f"{who}: {check.line()} {list(check.failures[:5])}")
    print("\n".join(lines))
    assert not problems, "\n".join(problems)


# ------------------------------------------------------------------ 3. literals above 2^53
COMMENT = re.compile(r"\(\*.*?\*\)", re.S)
# a decimal integer literal without a type prefix: not after '#' (16#FF, LINT#5, T#20ms),
# not part of a real literal or a name, not a range bound's neighbour of '.'
UNTYPED_INT = re.compile(r"(?<![\w#.])(\d[\d_]*)(?![\w.#])")


def _sources_with_literals() -> list[Path]:
    plc = REPO / "plc_project"
    return [*library_files(), *sorted((plc / "controller").glob("*.st")),
            plc / "Controller.st", CONTROLLER_UPLOAD]


def untyped_literals_above_2_53(text: str) -> list[tuple[int, str]]:
    """(line, literal) of every untyped decimal integer literal above 2^53 in ``text``."""
    code = COMMENT.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    found = []
    for m in UNTYPED_INT.finditer(code):
        if int(m[1].replace("_", "")) > 2**53:
            found.append((code.count("\n", 0, m.start()) + 1, m[1]))
    return found


def test_the_literal_scan_finds_what_strucpp_gets_wrong() -> None:
    text = ("X := 2305843009213693952; (* 9223372036854775807 *)\n"
            "Y := LINT#2305843009213693952; Z := 16#7FFFFFFFFFFFFFFF; W := 9007199254740992;\n"
            "V := 9007199254740993 + 1.0E300;")
    assert untyped_literals_above_2_53(text) == [(1, "2305843009213693952"),
                                                 (3, "9007199254740993")]


@pytest.mark.parametrize("path", _sources_with_literals(), ids=lambda p: p.name)
def test_no_untyped_integer_literal_above_2_53(path: Path) -> None:
    found = untyped_literals_above_2_53(path.read_text(encoding="utf-8"))
    assert not found, (f"{path.name}: untyped literals above 2^53 (STruC++ rounds them "
                       f"through a double; write LINT#...): {found}")


def test_strucpp_tool_is_found_only_through_the_environment(monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path) -> None:
    monkeypatch.delenv("STRUCPP", raising=False)
    assert find_strucpp() is None
    monkeypatch.setenv("STRUCPP", str(tmp_path / "missing.js"))
    with pytest.raises(ValueError, match="no file"):
        find_strucpp()
