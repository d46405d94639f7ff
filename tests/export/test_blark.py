"""blark (PyPI: a lark grammar of TwinCAT 3's Structured Text) parses every source file of the
library and of the controller: a second, independent reading of the sources in the CODESYS
dialect family, next to our tree-sitter grammar.

Set aside, each for a stated reason:

- the CONFIGURATION at the end of plc_project/Controller.st (OpenPLC glue): TwinCAT's grammar
  has none (a TwinCAT project declares its tasks outside the ST). Its lines are blanked.
- st/KinematicsFixedTables.st and the generated upload plc_project/openplc/arm_controller.st
  (which holds it): see TOO_SLOW.

Files with more than one declaration in one TYPE ... END_TYPE block are refused by TwinCAT's
grammar, which takes one per block. They are strict xfails, and only while blark stops exactly
at the second declaration of such a block: a file that parses then turns red (XPASS) and must
leave KNOWN_MULTI_TYPE_BLOCKS; a file refused elsewhere fails.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from blark.parse import new_parser, parse_source_code
from lark import Lark

from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.frontend import check_syntax
from armbench.compiler.lower import lower
from armbench.compiler.parse import parse_text
from armbench.locate import Project

REPO = Path(__file__).resolve().parents[2]
PROJECT = Project(REPO)

# Measured with blark 0.8.3 (Earley parser): one ARRAY[0..128] initialiser alone takes 25 s and
# 330 MB, ARRAY[0..256] 123 s of CPU and 3.4 GB; the file holds three of those.
TOO_SLOW = {
    "st/KinematicsFixedTables.st": "three ARRAY[0..256] OF UINT initialisers: blark's Earley "
                                   "parser needs about 2 min of CPU and 3.4 GB for each",
    "plc_project/openplc/arm_controller.st": "the generated upload holds "
                                             "st/KinematicsFixedTables.st (and every file "
                                             "parsed here)",
}
KNOWN_MULTI_TYPE_BLOCKS = {
    "st/ArmAngles.st", "st/Kinematics5Axis.st", "st/KinematicsChain.st",
    "st/KinematicsChainFixed.st", "st/KinematicsFixed.st", "st/MG996R.st", "st/MotionJoint.st",
    "st/MotionLine.st", "st/MotionProfiles.st", "st/MotionTypes.st",
    "st/OrientationFilters.st", "st/PCA9685.st", "st/Quaternion.st",
}
TYPE_BLOCK = re.compile(r"^TYPE\b.*?^END_TYPE\b", re.S | re.M)
CONFIGURATION = re.compile(r"^CONFIGURATION\b.*?^END_CONFIGURATION\b[^\n]*", re.S | re.M)


def rel(path: Path) -> str:
    return path.relative_to(REPO).as_posix()


def files() -> list[str]:
    return [rel(p) for p in PROJECT.sources() if rel(p) not in TOO_SLOW]


def second_type_declaration(text: str, path: str) -> tuple[int, str] | None:
    """Line and name of the first declaration that is not the first of its TYPE block."""
    diags = Diagnostics()
    parsed = parse_text(path, text, diags)
    check_syntax(parsed, diags)  # the nesting guard lower() requires
    unit = lower(parsed, diags)
    assert not diags.has_errors, diags.sorted()
    for block in TYPE_BLOCK.finditer(text):
        first = text.count("\n", 0, block.start()) + 1
        last = first + block.group(0).count("\n")
        inside = sorted((t.pos.line, t.name) for t in unit.types if first <= t.pos.line <= last)
        if len(inside) > 1:
            return inside[1]
    return None


def without_configuration(text: str) -> str:
    """The CONFIGURATION's lines emptied, so blark's line numbers stay ours."""
    return CONFIGURATION.sub(lambda m: "\n" * m.group(0).count("\n"), text)


@pytest.fixture(scope="module")
def blark_parser() -> Lark:
    return new_parser()


def _params() -> list[object]:
    out = []
    for f in files():
        marks = []
        if f in KNOWN_MULTI_TYPE_BLOCKS:
            marks = [pytest.mark.xfail(
                strict=True, raises=AssertionError,
                reason="more than one declaration in one TYPE ... END_TYPE block: TwinCAT's "
                       "grammar (blark) takes one per block")]
        out.append(pytest.param(f, id=f, marks=marks))
    return out


@pytest.mark.parametrize("path", _params())
def test_blark_parses(blark_parser: Lark, path: str) -> None:
    text = without_configuration((REPO / path).read_text(encoding="utf-8"))
    res = parse_source_code(text, fn=path, parser=blark_parser)
    if res.exception is not None and path in KNOWN_MULTI_TYPE_BLOCKS:
        known = second_type_declaration(text, path)
        at = getattr(res.exception, "line", None)
        if known is None or at != known[0]:
            pytest.fail(f"blark refuses {path} at line {at}, not at a second declaration of a "
                        f"TYPE block ({known}): {res.exception}")
    assert res.exception is None, f"blark refuses {path}: {res.exception}"


def test_known_multi_type_files_exist() -> None:
    """KNOWN_MULTI_TYPE_BLOCKS names files that are parsed here (no stale names)."""
    assert KNOWN_MULTI_TYPE_BLOCKS <= set(files())
