"""The openplc-v4 rules of `armbench check` against the real STruC++ (OpenPLC v4's compiler).

Every corpus case of a STruC++ code (tests/corpus/diagnostics/E0109_*, ...; the codes are
armbench.compiler.strucpp.STRUCPP_CODES) goes through STruC++ the way OpenPLC v4 builds it:
STruC++ turns the ST into C++, g++ checks that C++ against STruC++'s runtime headers with the
v4 runtime's flags (-std=c++17 -O1 -pipe -fPIC -DSTRUCPP_THREADED), and where the file has
`(* CHECK: name = value *)` comments (st_corpus.py's syntax: the values the source means,
which OpenPLC v3 computes) its C++ is built and run for one scan and the values compared.
STruC++'s verdict is "refused" when STruC++ rejects the file, g++ fails, or a CHECK does not
hold; the checker must report the file's code for --target openplc-v4 exactly then. A case
of E0311, E0312, E0413 or E0508 is refused by the wrong values it shows.

Where g++ fails on E0310 and E0412 cases, it fails on exactly the ST lines the checker
flags (STruC++ writes #line directives with --line-directives): the C++ type model of
armbench.compiler.cxxtypes is checked construct by construct, not only file by file.

OpenPLC v4's editor also uploads the debugger's table generated_debug.cpp, which STruC++'s
compile API writes (not its command line): for every case with a CONFIGURATION, where STRUCPP
names a checkout, that table is built too, and E0511 must be reported exactly where g++ fails
on it: for an E0511 case that is its verdict, and the declarations the failing table entries
lead to (through FB instances) must be the lines E0511 flags.

The bench, which computes what MatIEC computes, must satisfy every CHECK (test_checks_hold_
in_the_bench): the CHECKs are the OpenPLC v3 values, not STruC++'s.

STruC++ is found through tests/strucpp_tool.py (STRUCPP, STRUCPP_RUNTIME); skipped without.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest
from st_corpus import (
    DIAGNOSTICS,
    INSTANCE,
    Check,
    compare,
    instance_types,
    parse_checks,
    split_path,
    walk,
)

from armbench.compiler import check_files, compile_files
from armbench.compiler.driver import analyse_program
from armbench.compiler.strucpp import STRUCPP_CODES
from armbench.compiler.symbols import CheckedProgram, PouSym
from armbench.compiler.targets import OPENPLC_V4_ONLY, Target
from armbench.compiler.types import PouType
from strucpp_tool import SKIP_REASON, V4_CXX_FLAGS, Strucpp, find_strucpp

FILES = sorted(f for f in DIAGNOSTICS.glob("E*.st") if f.stem.split("_")[0] in STRUCPP_CODES)
# the v4 runtime compiles every program with the threaded code generation (its
# Makefile.strucpp: -DSTRUCPP_THREADED is unconditional)
FLAGS = (*V4_CXX_FLAGS, "-DSTRUCPP_THREADED")
# prints a value of the program instance by its C++ type
SHOW = """#include <cstdio>
#include <type_traits>
template <typename V> void show(const char* name, const V& v) {
  auto x = strucpp::iec_unwrap(v);
  using T = decltype(x);
  if constexpr (std::is_floating_point_v<T>) std::printf("%s=%.17g\\n", name, (double)x);
  else if constexpr (std::is_same_v<T, bool>) std::printf("%s=%s\\n", name, x ? "TRUE" : "FALSE");
  else if constexpr (std::is_signed_v<T>) std::printf("%s=%lld\\n", name, (long long)x);
  else std::printf("%s=%llu\\n", name, (unsigned long long)x);
}
"""


@pytest.fixture(scope="module")
def strucpp() -> Strucpp:
    tool = find_strucpp()
    if tool is None:
        pytest.skip(SKIP_REASON)
    return tool


# codes whose every flagged construct is one statement g++ reports by its ST line
LINE_EXACT = frozenset({"E0310", "E0412"})


@dataclass(frozen=True)
class Verdict:
    refused: bool
    why: str
    lines: frozenset[int] = frozenset()  # the ST lines g++ fails on


def cxx_path(path: str) -> str:
    """A CHECK path of the program instance in STruC++'s C++: names upper-cased, subscripts
    through the arrays' at()."""
    out = []
    for seg in split_path(path):
        if isinstance(seg, tuple):
            out[-1] += f".at({', '.join(seg)})"
        else:
            out.append(seg.upper())
    return ".".join(out)


def parse_shown(text: str) -> object:
    if text in ("TRUE", "FALSE"):
        return text == "TRUE"
    return int(text) if re.fullmatch(r"-?\d+", text) else float(text)


def strucpp_verdict(tool: Strucpp, st: Path, work: Path) -> Verdict:
    src = work / st.name
    shutil.copy(st, src)
    cpp = work / "program.cpp"
    made = tool.compile(src, cpp, "--line-directives")
    if not made.ok:
        return Verdict(True, f"STruC++ refuses it:\n{made.output}")
    syntax = tool.cxx(*FLAGS, "-fsyntax-only", str(cpp))
    if not syntax.ok:
        lines = {int(m) for m in re.findall(rf"{re.escape(st.name)}:(\d+):\d+: error",
                                            syntax.output)}
        return Verdict(True, f"g++ fails on its C++:\n{syntax.output}", frozenset(lines))
    _, checks = parse_checks(st)
    if not checks:
        return Verdict(False, "STruC++ and g++ build it")
    return run_checks(tool, cpp, checks, work)


def run_checks(tool: Strucpp, cpp: Path, checks: list[Check], work: Path) -> Verdict:
    main = work / "main.cpp"
    lines = [f'#include "{cpp.with_suffix(".hpp").name}"', SHOW,
             "int main() {", "  static strucpp::Configuration_CONFIG0 config;",
             f"  auto& prog = config.{INSTANCE.upper()};", "  prog.run();"]
    lines += [f'  show("{c.path}", prog.{cxx_path(c.path)});' for c in checks]
    main.write_text("\n".join([*lines, "}"]) + "\n")
    binary = work / "program"
    built = tool.cxx(*FLAGS, "-w", f"-I{work}", str(cpp), str(main), "-o", str(binary))
    assert built.ok, f"the C++ that g++ checked does not build:\n{built.output}"
    ran = subprocess.run([str(binary)], capture_output=True, text=True, timeout=60,
                         check=False)
    assert ran.returncode == 0, f"the STruC++ build stopped: {ran.returncode}\n{ran.stderr}"
    shown = dict(line.split("=", 1) for line in ran.stdout.splitlines())
    wrong = [msg for c in checks
             if (msg := compare(c, parse_shown(shown[c.path]))) is not None]
    if wrong:
        return Verdict(True, "its build computes other values:\n" + "\n".join(wrong))
    return Verdict(False, "STruC++'s build satisfies every CHECK")


# the code of the debugger's table, which STruC++'s compile API writes
DEBUG_TABLE_CODE = "E0511"


@dataclass(frozen=True)
class TableVerdict:
    fails: bool
    why: str
    paths: frozenset[str] = frozenset()  # the variable paths of the failing entries


def debug_table_verdict(tool: Strucpp, st: Path, work: Path) -> TableVerdict | None:
    """generated_debug.cpp of ``st`` as the v4 editor gets it, compiled with g++ as the v4
    runtime does; None where STruC++'s compile API is not at hand, the file has no
    CONFIGURATION (no table then) or STruC++ refuses it."""
    if tool.dist is None or "CONFIGURATION" not in st.read_text(encoding="utf-8"):
        return None
    folder = work / "api"
    made = tool.api_files(st, folder)
    table = folder / "generated_debug.cpp"
    if not made.ok or not table.is_file():
        return None
    res = tool.cxx(*FLAGS, f"-I{folder}", "-fsyntax-only", str(table))
    if res.ok:
        return TableVerdict(False, "g++ builds its debug table")
    lines = table.read_text(encoding="utf-8").splitlines()
    paths = {lines[int(n) - 1].rsplit("// ", 1)[-1]
             for n in re.findall(r"generated_debug\.cpp:(\d+):\d+: error", res.output)}
    return TableVerdict(True, f"g++ fails on its debug table:\n{res.output[-3000:]}",
                        frozenset(paths))


def declaration_lines(prog: CheckedProgram, paths: frozenset[str]) -> set[int]:
    """The lines of the declarations that the debug table's paths (INSTANCE.FB.MEMBER[i]...
    or GLOBAL[i]...) lead to: through FB instances to the variable of the block that holds
    the array (or a STRUCT around it)."""
    assert prog.config is not None
    instances = {i.name.upper(): i.pou for i in prog.config.instances}
    found = set()
    for path in paths:
        names = [re.sub(r"\[.*", "", seg) for seg in path.split(".")]
        if names[0] not in instances:
            found.add(prog.config.globals[names[0]].pos.line)
            continue
        sym: PouSym = instances[names[0]]
        for name in names[1:]:
            var = next(v for k, v in sym.vars.items() if k.upper() == name)
            if isinstance(var.type, PouType) and isinstance(var.type.symbol, PouSym):
                sym = var.type.symbol
                continue
            found.add(var.pos.line)
            break
    return found


def test_corpus_has_both_kinds_for_every_code() -> None:
    for code in STRUCPP_CODES:
        cases = [f for f in FILES if f.stem.split("_")[0] == code]
        assert any("_ok_" not in f.stem for f in cases), f"no case {code} flags"
        assert any("_ok_" in f.stem for f in cases), f"no case {code} passes"


@pytest.mark.parametrize("path", [pytest.param(f, id=f.stem) for f in FILES])
def test_strucpp_agrees(strucpp: Strucpp, path: Path, tmp_path: Path) -> None:
    code = path.stem.split("_")[0]
    diags = check_files([path], target=OPENPLC_V4_ONLY)
    ours = [d.render() for d in diags]
    reported = any(d.code == code for d in diags)
    verdict = strucpp_verdict(strucpp, path, tmp_path)
    if code == DEBUG_TABLE_CODE:
        # its command line's C++ builds (and satisfies the CHECKs): the table decides
        assert not verdict.refused, verdict.why
        table = debug_table_verdict(strucpp, path, tmp_path)
        assert table is not None, "an E0511 case needs STruC++'s compile API (a checkout)"
        verdict = Verdict(table.fails, table.why)
    assert reported == verdict.refused, (
        f"--target openplc-v4 {'reports' if reported else 'does not report'} {code}, and "
        f"{verdict.why}\n" + "\n".join(ours))
    if code in LINE_EXACT and verdict.lines:
        flagged = {d.pos.line for d in diags if d.code == code}
        assert flagged == verdict.lines, (
            f"g++ fails on lines {sorted(verdict.lines)}, {code} flags {sorted(flagged)}\n"
            + verdict.why)


@pytest.mark.parametrize("path", [pytest.param(f, id=f.stem) for f in FILES])
def test_the_debug_table_agrees(strucpp: Strucpp, path: Path, tmp_path: Path) -> None:
    """E0511 is reported where g++ fails on the debugger's table, on the declarations its
    failing entries lead to; an E0511 case's verdict is its table's."""
    table = debug_table_verdict(strucpp, path, tmp_path)
    if table is None:
        if path.stem.startswith(DEBUG_TABLE_CODE):
            assert strucpp.dist is not None, "an E0511 case needs STruC++'s compile API"
            pytest.fail(f"STruC++'s compile API wrote no debug table for {path.name}")
        pytest.skip("no debug table: no CONFIGURATION, STruC++ refuses the file, or STRUCPP "
                    "names no checkout")
    diags = check_files([path], target=OPENPLC_V4_ONLY)
    flagged = {d.pos.line for d in diags if d.code == DEBUG_TABLE_CODE}
    assert bool(flagged) == table.fails, (
        f"--target openplc-v4 {'reports' if flagged else 'does not report'} E0511, and "
        f"{table.why}\n" + "\n".join(d.render() for d in diags))
    if table.fails:
        # E0511 is the rule of openplc-v4 alone: for openplc it is not reported, and the
        # program resolves
        prog = analyse_program([path], target=Target.named("openplc")).program
        assert prog is not None, f"{path.name} does not resolve"
        lines = declaration_lines(prog, table.paths)
        assert lines == flagged, (f"the failing entries lead to lines {sorted(lines)}, E0511 "
                                  f"flags {sorted(flagged)}:\n" + "\n".join(sorted(table.paths)))


@pytest.mark.parametrize("path", [pytest.param(f, id=f.stem) for f in FILES
                                  if parse_checks(f)[1]])
def test_checks_hold_in_the_bench(path: Path) -> None:
    """The CHECK values are what OpenPLC v3 computes: the bench's MatIEC semantics agree."""
    _, checks = parse_checks(path)
    mod = compile_files([path])
    mod.config_init()
    mod.run_task_index(0, 0)
    values, types = mod.instance(INSTANCE).vars(), instance_types(mod)
    wrong = [msg for c in checks if (msg := compare(c, walk(values, types, c.path)[0]))]
    assert not wrong, "\n".join(wrong)
