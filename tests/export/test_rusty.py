"""RuSTy (PLC-lang's LLVM compiler for IEC 61131-3 ST) as a second compiler of the library and
of the controller, against its own standard library, unmodified.

Runs when RUSTY_PLC names RuSTy's `plc` binary and RUSTY_STDLIB its packaged standard library
(`include/*.st` and `lib/libiec61131std.so`, the layout of RuSTy's `scripts/build.sh
--package`); skipped otherwise. How to build both outside this repository: docs/exports.md.

What RuSTy cannot take is set aside explicitly, never silently:

- the CONFIGURATION at the end of plc_project/Controller.st (OpenPLC glue): RuSTy's grammar
  has no CONFIGURATION / RESOURCE / TASK. The tests blank those lines (line numbers stay) and
  check that they are the only lines RuSTy refuses.
- nothing else: no POU of the library or the controller may share a name with a POU of RuSTy's
  standard library (names are case-insensitive; the library's arc tangent is ArcTan2, not
  Atan2, for this reason). test_rusty_stdlib_clashes_are_the_known_ones keeps it so.

RuSTy is also the evidence for `armbench check --target codesys` (docs/diagnostics.md,
Targets): every POU of its standard library is a name armbench.compiler.reserved reserves, it
warns E067 exactly where the checker's E0309 says TRUNC narrows (the corpus cases), refuses the
E0214 corpus case's GET and SET, and builds what E0411 refuses only for OpenPLC. The library
has no TRUNC narrowing left (RuSTy's other E067 warnings are on literals, where nothing
narrows: docs/exports.md).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

from armbench.compiler import ast as A
from armbench.compiler import check_files
from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.frontend import check_syntax
from armbench.compiler.lower import lower
from armbench.compiler.parse import parse_text
from armbench.compiler.reserved import reserved_anywhere
from armbench.compiler.targets import CODESYS_ONLY
from armbench.locate import Project

REPO = Path(__file__).resolve().parents[2]
PROJECT = Project(REPO)
CORPUS = REPO / "tests" / "corpus" / "diagnostics"
RUSTY_TIMEOUT_S = 600

# Upper-cased POU name -> why RuSTy cannot generate it next to its standard library: none.
KNOWN_CLASHES: dict[str, str] = {}

# `path:line:col:{span}: error[E007]: message` (--error-format clang)
DIAGNOSTIC = re.compile(r"^(?P<file>[^:\n]+):(?P<line>\d+):(?P<col>\d+):\{[^}]*\}: "
                        r"(?P<level>error|warning|info)\[(?P<code>E\d+)\]: (?P<msg>.*)$", re.M)
CONFIGURATION = re.compile(r"^CONFIGURATION\b.*?^END_CONFIGURATION\b[^\n]*", re.S | re.M)
# A POU header in RuSTy's standard library: `FUNCTION ATAN2<T : ANY_REAL> : T`.
STDLIB_POU = re.compile(r"^\s*(?:FUNCTION_BLOCK|FUNCTION|PROGRAM|CLASS)\s+([A-Za-z_]\w*)",
                        re.M | re.I)


@dataclass(frozen=True)
class Pou:
    """One POU of the sources, as our parser sees it: where it is and how it is called."""

    file: Path
    kind: str
    name: str
    first_line: int
    last_line: int

    @property
    def id(self) -> str:
        return f"{self.file.relative_to(REPO).as_posix()}::{self.name}"


def library_files() -> list[Path]:
    return PROJECT.library()


def controller_files() -> list[Path]:
    """What the controller needs: the library, its blocks, then Controller.st."""
    return PROJECT.sources()


def pous_of(files: Sequence[Path]) -> list[Pou]:
    out = []
    for f in files:
        diags = Diagnostics()
        parsed = parse_text(str(f), f.read_text(encoding="utf-8"), diags)
        check_syntax(parsed, diags)  # the nesting guard lower() requires
        unit: A.SourceUnit = lower(parsed, diags)
        if diags.has_errors:
            raise AssertionError(f"{f} does not parse: {diags.sorted()}")
        out += [Pou(f, p.kind, p.name, p.pos.line, p.end_pos.line) for p in unit.pous]
    return out


def blank_lines(text: str, first: int, last: int) -> str:
    """``text`` with lines first..last (1-based) emptied: RuSTy's line numbers stay ours."""
    lines = text.split("\n")
    for i in range(first - 1, last):
        lines[i] = ""
    return "\n".join(lines)


def configuration_lines(text: str) -> tuple[int, int]:
    """First and last line of the one CONFIGURATION block of ``text``."""
    found = list(CONFIGURATION.finditer(text))
    assert len(found) == 1, f"expected one CONFIGURATION block, found {len(found)}"
    first = text.count("\n", 0, found[0].start()) + 1
    return first, first + found[0].group(0).count("\n")


@dataclass(frozen=True)
class Rusty:
    """RuSTy's `plc` and its packaged standard library."""

    plc: Path
    stdlib: Path

    @property
    def includes(self) -> str:
        return str(self.stdlib / "include" / "*.st")  # plc expands the glob itself

    def stdlib_pou_names(self) -> set[str]:
        names: set[str] = set()
        for f in sorted((self.stdlib / "include").glob("*.st")):
            names |= {m.upper() for m in STDLIB_POU.findall(f.read_text(encoding="utf-8"))}
        return names

    def run(self, files: Sequence[Path], *args: str) -> subprocess.CompletedProcess[str]:
        cmd = [str(self.plc), *map(str, files), "-i", self.includes,
               "--error-format", "clang", *args]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=RUSTY_TIMEOUT_S)

    def shared_object(self, files: Sequence[Path], out: Path) -> subprocess.CompletedProcess[str]:
        """Generate code for ``files`` and link it with the standard library into ``out``;
        `cc` links, so RuSTy needs no ld.lld on the PATH."""
        return self.run(files, "--shared", "-o", str(out), "-L", str(self.stdlib / "lib"),
                        "-l", "iec61131std", "--linker", "cc")


def errors(res: subprocess.CompletedProcess[str]) -> list[re.Match[str]]:
    return [m for m in DIAGNOSTIC.finditer(res.stdout + res.stderr) if m["level"] == "error"]


def defined_symbols(shared_object: Path) -> set[str]:
    nm = subprocess.run(["nm", "--defined-only", str(shared_object)], capture_output=True,
                        text=True, check=True)
    return {line.split()[-1] for line in nm.stdout.splitlines() if line.strip()}


@pytest.fixture(scope="module")
def rusty() -> Rusty:
    plc = os.environ.get("RUSTY_PLC", "")
    if not plc:
        pytest.skip("RUSTY_PLC not set: RuSTy's `plc` binary, built as docs/exports.md says "
                    "(with RUSTY_STDLIB, its packaged standard library)")
    stdlib = Path(os.environ.get("RUSTY_STDLIB", ""))
    if not Path(plc).is_file():
        pytest.fail(f"RUSTY_PLC={plc} is no file: point it at RuSTy's `plc` binary")
    if not os.environ.get("RUSTY_STDLIB") or not (stdlib / "lib" / "libiec61131std.so").is_file() \
            or not list((stdlib / "include").glob("*.st")):
        pytest.fail(f"RUSTY_STDLIB={os.environ.get('RUSTY_STDLIB', '')!r} is not RuSTy's "
                    "packaged standard library: it needs include/*.st and "
                    "lib/libiec61131std.so (docs/exports.md)")
    return Rusty(Path(plc), stdlib)


@pytest.fixture(scope="module")
def sources_for_rusty(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Path]]:
    """The sources as RuSTy gets them: Controller.st's CONFIGURATION blanked, all else as in
    the repository."""
    out = tmp_path_factory.mktemp("rusty_sources")
    text = PROJECT.controller.read_text(encoding="utf-8")
    controller = out / PROJECT.controller.name
    controller.write_text(blank_lines(text, *configuration_lines(text)), encoding="utf-8")
    return {"library": library_files(), "controller": [*controller_files()[:-1], controller]}


# ---------------------------------------------------------------- what RuSTy refuses
def test_rusty_refuses_only_the_configuration(rusty: Rusty) -> None:
    res = rusty.run(controller_files(), "--check")
    first, last = configuration_lines(PROJECT.controller.read_text(encoding="utf-8"))
    found = errors(res)
    assert res.returncode != 0 and found, res.stdout + res.stderr
    outside = [m.group(0) for m in found
               if Path(m["file"]).resolve() != PROJECT.controller.resolve()
               or not first <= int(m["line"]) <= last]
    assert not outside, "\n".join(outside)


@pytest.mark.parametrize("which", ["library", "controller"])
def test_rusty_checks_the_sources(rusty: Rusty, sources_for_rusty: dict[str, list[Path]],
                                  which: str) -> None:
    res = rusty.run(sources_for_rusty[which], "--check")
    assert res.returncode == 0 and not errors(res), res.stdout + res.stderr


def test_rusty_stdlib_clashes_are_the_known_ones(rusty: Rusty) -> None:
    ours = {p.name.upper() for p in pous_of(controller_files())}
    assert ours & rusty.stdlib_pou_names() == set(KNOWN_CLASHES)


def test_rusty_stdlib_pous_are_reserved(rusty: Rusty) -> None:
    """The one list of reserved names (armbench.compiler.reserved) holds every POU of RuSTy's
    standard library but the type-mangled ones (TRUNC__REAL: no identifier has '__')."""
    names = {n for n in rusty.stdlib_pou_names() if "__" not in n}
    assert len(names) > 400
    assert sorted(n for n in names if not reserved_anywhere(n)) == []


# ---------------------------------------------------------------- the checker's CODESYS rules
def _rusty_view(path: Path, out: Path) -> Path:
    """A corpus file as RuSTy takes it: its CONFIGURATION blanked (line numbers stay)."""
    text = path.read_text(encoding="utf-8")
    dest = out / path.name
    dest.write_text(blank_lines(text, *configuration_lines(text)), encoding="utf-8")
    return dest


def _checker_lines(path: Path, code: str) -> set[int]:
    return {d.pos.line for d in check_files([path], target=CODESYS_ONLY) if d.code == code}


@pytest.mark.parametrize("path", sorted(CORPUS.glob("E0309_*.st")), ids=lambda p: p.stem)
def test_rusty_warns_where_trunc_narrows(rusty: Rusty, path: Path, tmp_path: Path) -> None:
    res = rusty.run([_rusty_view(path, tmp_path)], "--check")
    assert not errors(res), res.stdout + res.stderr
    narrowed = {int(m["line"]) for m in DIAGNOSTIC.finditer(res.stdout + res.stderr)
                if m["code"] == "E067" and "from 'LINT'" in m["msg"]}
    assert narrowed == _checker_lines(path, "E0309"), res.stdout + res.stderr


def test_rusty_refuses_get_and_set(rusty: Rusty, tmp_path: Path) -> None:
    path = CORPUS / "E0214_get_set_codesys.st"
    res = rusty.run([_rusty_view(path, tmp_path)], "--check")
    refused = {int(m["line"]) for m in errors(res)}
    ours = _checker_lines(path, "E0214")
    # RuSTy stops at the first: one parse error spans both declarations (lines 6-7)
    assert len(ours) == 2 and min(ours) in refused, res.stdout + res.stderr


@pytest.mark.parametrize("path", sorted(CORPUS.glob("E0411_*.st")), ids=lambda p: p.stem)
def test_rusty_builds_array_elements_as_in_outs(rusty: Rusty, path: Path,
                                                tmp_path: Path) -> None:
    res = rusty.run([_rusty_view(path, tmp_path)], "--check")
    assert res.returncode == 0 and not errors(res), res.stdout + res.stderr


def test_rusty_finds_no_trunc_narrowing_in_the_library(rusty: Rusty) -> None:
    res = rusty.run(library_files(), "--check")
    lines = {f: f.read_text(encoding="utf-8").split("\n") for f in library_files()}
    narrowed = []
    for m in DIAGNOSTIC.finditer(res.stdout + res.stderr):
        if m["code"] == "E067":
            src = lines.get(Path(m["file"]), [""] * int(m["line"]))[int(m["line"]) - 1]
            if "TRUNC(" in src.upper():
                narrowed.append(m.group(0))
    assert narrowed == []


# ---------------------------------------------------------------- code generation
@pytest.mark.parametrize("which", ["library", "controller"])
def test_rusty_generates_every_pou(rusty: Rusty, sources_for_rusty: dict[str, list[Path]],
                                   which: str, tmp_path: Path) -> None:
    files = sources_for_rusty[which]
    out = tmp_path / f"{which}.so"
    res = rusty.shared_object(files, out)
    assert res.returncode == 0 and out.is_file(), res.stdout + res.stderr
    missing = {p.name for p in pous_of(files)} - defined_symbols(out)
    assert not missing, f"no code for {sorted(missing)}"


@pytest.fixture(scope="module")
def set_aside_build(rusty: Rusty, sources_for_rusty: dict[str, list[Path]],
                    tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Library + controller linked into one shared object, with the POUs that clash with
    RuSTy's standard library blanked (their callers then call the standard library's)."""
    out = tmp_path_factory.mktemp("rusty_set_aside")
    clashes = rusty.stdlib_pou_names()
    files = []
    for f in sources_for_rusty["controller"]:
        aside = [p for p in pous_of([f]) if p.name.upper() in clashes]
        if aside:
            text = f.read_text(encoding="utf-8")
            for p in aside:
                text = blank_lines(text, p.first_line, p.last_line)
            f = out / f.name
            f.write_text(text, encoding="utf-8")
        files.append(f)
    so = out / "libarm.so"
    res = rusty.shared_object(files, so)
    assert res.returncode == 0 and so.is_file(), res.stdout + res.stderr
    assert not errors(res), res.stdout + res.stderr
    return so


def _pou_params() -> list[object]:
    return [pytest.param(p.name, id=p.id) for p in pous_of(controller_files())]


@pytest.mark.parametrize("name", _pou_params())
def test_rusty_generates_pou(set_aside_build: Path, name: str) -> None:
    assert name in defined_symbols(set_aside_build), f"RuSTy generated no code for {name}"


def test_rusty_code_runs_with_its_stdlib(rusty: Rusty, set_aside_build: Path) -> None:
    """The shared object loads with all its symbols bound, and plain functions of it called
    from C (ctypes), SQRT from RuSTy's standard library, give closed forms."""
    script = textwrap.dedent(f"""
        import ctypes, math, os
        # RTLD_NOW: every symbol, the standard library's too, is bound here or the load fails
        lib = ctypes.CDLL({str(set_aside_build)!r}, mode=os.RTLD_NOW)
        f = ctypes.c_float
        def fn(name, n):
            g = getattr(lib, name)
            g.restype, g.argtypes = f, [f] * n
            return g
        length, wrap, rad = fn("MotionVecLength", 3), fn("WrapDeg180", 1), fn("DegToRad", 1)
        assert math.isclose(length(3.0, 4.0, 12.0), 13.0, rel_tol=1e-6)
        assert math.isclose(length(1e20, -1e20, 0.0), math.hypot(1e20, 1e20), rel_tol=1e-6)
        assert math.isclose(wrap(540.0), 180.0, rel_tol=1e-6)
        assert math.isclose(wrap(-190.0), 170.0, rel_tol=1e-6)
        assert math.isclose(rad(90.0), math.pi / 2, rel_tol=1e-6)
        print("ok")
    """)
    env = {**os.environ, "LD_LIBRARY_PATH": str(rusty.stdlib / "lib")}
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env=env, timeout=60)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stdout + res.stderr
