"""The library by use (armbench.compiler.uses): which library declarations a program gets.

A small library written here pins the rules down (enumeration values, types, FUNCTIONs and
FBs, a file that does not even parse); the armbench library itself checks that what is taken
is exactly what is needed: the program checks with it, and without any one declaration of it
it does not (so nothing more and nothing less than the program's transitive uses).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from armbench.compiler import ast as A
from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.driver import analyse_program
from armbench.compiler.frontend import check_syntax, read_parse
from armbench.compiler.lower import lower
from armbench.compiler.parse import parse_text
from armbench.compiler.resolve import check
from armbench.compiler.strucpp import STRUCPP_CODES
from armbench.compiler.uses import Declaration, Library, LibraryUse

REPO = Path(__file__).resolve().parents[2]
ARMBENCH_LIBRARY = [*sorted((REPO / "st").glob("*.st")),
                    *sorted((REPO / "plc_project" / "controller").glob("*.st"))]

TYPES = """TYPE
  Color : (RED, GREEN, BLUE);
  Pair : STRUCT
    A : REAL;
    B : REAL;
  END_STRUCT;
  Unrelated : STRUCT
    Z : INT;
  END_STRUCT;
END_TYPE
"""
FUNCS = """FUNCTION PairSum : REAL
  VAR_IN_OUT
    P : Pair;
  END_VAR
  PairSum := P.A + P.B;
END_FUNCTION

FUNCTION_BLOCK Mixer
  VAR_INPUT
    C : Color;
  END_VAR
  VAR_OUTPUT
    Out : REAL;
  END_VAR
  VAR
    P : Pair;
  END_VAR
  P.A := 1.0;
  P.B := 2.0;
  IF C = GREEN THEN
    Out := PairSum(P);
  ELSE
    Out := 0.0;
  END_IF;
END_FUNCTION_BLOCK

FUNCTION Lonely : REAL
  VAR_INPUT
    X : REAL;
  END_VAR
  VAR
    U : Unrelated;
  END_VAR
  Lonely := X;
END_FUNCTION
"""
BROKEN = """FUNCTION Broken : REAL
  VAR_INPUT
    X : REAL;
  END_VAR
  Broken := ;
END_FUNCTION
"""


@pytest.fixture()
def library(tmp_path: Path) -> list[Path]:
    out = []
    for name, text in (("types.st", TYPES), ("funcs.st", FUNCS), ("broken.st", BROKEN)):
        (tmp_path / "lib").mkdir(exist_ok=True)
        p = tmp_path / "lib" / name
        p.write_text(text)
        out.append(p)
    return out


def fb_program(decls: str = "", body: str = "", before: str = "") -> str:
    return (f"{before}FUNCTION_BLOCK Main\n  VAR\n    Res : REAL;\n{decls}  END_VAR\n"
            f"  Res := 1.0;\n{body}END_FUNCTION_BLOCK\n")


def run(tmp_path: Path, text: str, library: list[Path]) -> tuple[list[str], list[str],
                                                                 list[str]]:
    """(kept names, replaced names, rendered diagnostics) for a program in one file."""
    src = tmp_path / "prog.st"
    src.write_text(text)
    a = analyse_program([src], library)
    # what OpenPLC v4's STruC++ refuses (Color#GREEN) is not what these tests are about
    return ([d.name for d in a.library.kept], [r.mine.name for r in a.library.replaced],
            [d.render() for d in a.diagnostics.sorted() if d.code not in STRUCPP_CODES])


def test_nothing_used_nothing_taken(tmp_path: Path, library: list[Path]) -> None:
    assert run(tmp_path, fb_program(), library) == ([], [], [])


def test_a_bare_enumeration_value_takes_its_type(tmp_path: Path,
                                                  library: list[Path]) -> None:
    assert run(tmp_path, fb_program("    K : INT;\n", "  IF GREEN = GREEN THEN K := 1; "
                                    "END_IF;\n"), library)[:2] == (["Color"], [])


def test_a_block_takes_what_it_uses_transitively(tmp_path: Path,
                                                 library: list[Path]) -> None:
    # spelled in other cases: ST names are case-insensitive
    kept, replaced, diags = run(tmp_path, fb_program("    M : mixer;\n", "  M(C := Color#GREEN);"
                                                     "\n  Res := M.OUT;\n"), library)
    assert (kept, replaced, diags) == (["Color", "Pair", "PairSum", "Mixer"], [], [])


def test_own_declaration_replaces_the_librarys_for_what_uses_it(
        tmp_path: Path, library: list[Path]) -> None:
    own_pair = "TYPE\n  Pair : STRUCT\n    A : REAL;\n    B : REAL;\n  END_STRUCT;\nEND_TYPE\n"
    text = fb_program("    M : Mixer;\n", "  M(C := GREEN);\n", before=own_pair)
    kept, replaced, diags = run(tmp_path, text, library)
    assert (kept, replaced, diags) == (["Color", "PairSum", "Mixer"], ["Pair"], [])
    src = tmp_path / "prog.st"
    note = analyse_program([src], library).library.note()
    assert note == ("your TYPE Pair replaces the armbench library's (types.st) in the library "
                    "declarations you use: Mixer, PairSum")


def test_incompatible_replacement_is_one_e0213(tmp_path: Path, library: list[Path]) -> None:
    own_pair = "TYPE\n  Pair : STRUCT\n    C : REAL;\n  END_STRUCT;\nEND_TYPE\n"
    _, replaced, diags = run(tmp_path, fb_program("    M : Mixer;\n", "  M(C := GREEN);\n",
                                                  before=own_pair), library)
    assert replaced == ["Pair"]
    assert len(diags) == 1 and diags[0].startswith(f"{tmp_path / 'prog.st'}:2:3: error[E0213]: "
                                                   "your TYPE Pair replaces"), diags


def test_own_name_no_used_declaration_needs_is_no_conflict(
        tmp_path: Path, library: list[Path]) -> None:
    # Lonely needs the library's Unrelated, but the program does not use Lonely
    own = "TYPE\n  Unrelated : (ONE, TWO);\nEND_TYPE\n"
    assert run(tmp_path, fb_program("    M : Mixer;\n    U : Unrelated;\n", "  U := TWO;\n",
                                    before=own), library) == (
        ["Color", "Pair", "PairSum", "Mixer"], [], [])


def test_a_local_variable_is_not_a_use(tmp_path: Path, library: list[Path]) -> None:
    assert run(tmp_path, fb_program("    Lonely : REAL;\n", "  Lonely := Res;\n"),
               library) == ([], [], [])


def test_a_library_file_counts_only_when_used(tmp_path: Path, library: list[Path]) -> None:
    assert run(tmp_path, fb_program(), library)[2] == []
    _, _, diags = run(tmp_path, fb_program(body="  Res := Broken(Res);\n"), library)
    assert diags and all("broken.st" in d and "E0100" in d for d in diags), diags


def test_lowering_needs_the_nesting_guard(tmp_path: Path) -> None:
    d = Diagnostics()
    pf = parse_text("x.st", fb_program(), d)
    with pytest.raises(ValueError, match="nesting guard"):
        lower(pf, d)
    check_syntax(pf, d)
    assert lower(pf, d).pous[0].name == "Main" and not d.items


# ------------------------------------------------------------------ the armbench library
def _units(paths: list[Path]) -> list[A.SourceUnit]:
    d = Diagnostics()
    out = []
    for p in paths:
        pf = read_parse(p, d)
        assert pf is not None
        check_syntax(pf, d)
        out.append(lower(pf, d))
    assert not d.has_errors, d.render()
    return out


def _errors(user: list[A.SourceUnit], lib: Library, kept: list[Declaration]) -> list[str]:
    use = LibraryUse(tuple(kept))
    units = [*user]
    for f in use.files:
        unit = lib.units[f]
        assert unit is not None
        units.append(use.prune(unit))
    d = Diagnostics()
    check(units, d)
    return [x.render() for x in d.items if x.severity == "error"]


@pytest.mark.parametrize(("decls", "body"), [
    ("", "Res := ArcTan2(Res, 1.0);"),
    ("A : ArmAngles; P : Coordinates; G : ArmGeometry;", "A := InverseKinematik_V1(P, G);"),
    ("Pwm : PCA9685_Channels;", ""),
    ("Line : MotionLinear;", ""),
    ("Rate : ChainResolvedRateFixed;", ""),
], ids=["ArcTan2", "InverseKinematik_V1", "PCA9685_Channels", "MotionLinear",
        "ChainResolvedRateFixed"])
def test_exactly_what_is_used(tmp_path: Path, decls: str, body: str) -> None:
    src = tmp_path / "prog.st"
    src.write_text(fb_program(f"    {decls}\n", f"  {body}\n"))
    user = _units([src])
    lib = Library(ARMBENCH_LIBRARY, Diagnostics())
    kept = list(lib.select(user).kept)
    assert kept
    assert _errors(user, lib, kept) == []  # enough
    for d in kept:  # and nothing more: without any one of them the program does not check
        assert _errors(user, lib, [k for k in kept if k is not d]), f"{d.name} is not needed"
