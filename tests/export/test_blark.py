"""blark (PyPI: a lark grammar of TwinCAT 3's Structured Text) parses every source file of the
library and of the controller: a second, independent reading of the sources in the CODESYS
dialect family, next to our tree-sitter grammar.

Set aside, each for a stated reason:

- the CONFIGURATION at the end of plc_project/Controller.st (OpenPLC glue): TwinCAT's grammar
  has none (a TwinCAT project declares its tasks outside the ST). Its lines are blanked.
- st/KinematicsFixedTables.st and the generated upload plc_project/openplc/arm_controller.st
  (which holds it): see TOO_SLOW.

TwinCAT's grammar takes one declaration per TYPE ... END_TYPE block (a CODESYS DUT holds one
type), and refuses a file at the second declaration of a block. Every source declares one type
per block; test_one_type_per_type_block checks it with our parser, fast and for every file,
including the ones too slow for blark.
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
TYPE_BLOCK = re.compile(r"^TYPE\b.*?^END_TYPE\b", re.S | re.M)
CONFIGURATION = re.compile(r"^CONFIGURATION\b.*?^END_CONFIGURATION\b[^\n]*", re.S | re.M)


def rel(path: Path) -> str:
    return path.relative_to(REPO).as_posix()


def files() -> list[str]:
    return [rel(p) for p in PROJECT.sources() if rel(p) not in TOO_SLOW]


def second_type_declaration(path: Path) -> tuple[int, str] | None:
    """Line and name of the first declaration that is not the first of its TYPE block."""
    text = path.read_text(encoding="utf-8")
    diags = Diagnostics()
    parsed = parse_text(str(path), text, diags)
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


@pytest.mark.parametrize("path", files())
def test_blark_parses(blark_parser: Lark, path: str) -> None:
    text = without_configuration((REPO / path).read_text(encoding="utf-8"))
    res = parse_source_code(text, fn=path, parser=blark_parser)
    assert res.exception is None, f"blark refuses {path}: {res.exception}"


@pytest.mark.parametrize("path", PROJECT.sources(), ids=rel)
def test_one_type_per_type_block(path: Path) -> None:
    second = second_type_declaration(path)
    assert second is None, (
        f"{rel(path)}:{second[0] if second else 0}: {second[1] if second else ''} is the second "
        "declaration of its TYPE ... END_TYPE block; TwinCAT and CODESYS take one per block: "
        "give it a TYPE block of its own")
