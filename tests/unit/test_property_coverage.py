"""Every public POU of the motion, servo-slew, chain, 4-/5-axis and orientation libraries has
a property test: a hypothesis-driven module under tests/unit that calls it by name
(tests/unit/pou_inventory.py says what counts). A new POU without one turns this red."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from pou_inventory import (
    PouEntry,
    called_pous,
    is_property_module,
    property_coverage,
    public_pous,
    scope_files,
)

pytest.importorskip("armbench.docgen")


def test_inventory_is_the_reference_list() -> None:
    """The inventory holds every FUNCTION / FUNCTION_BLOCK declared in the scope's files (a
    plain regex over the ST, independent of docgen's reader), each once."""
    pous = public_pous()
    declared = []
    for path in scope_files():
        declared += re.findall(r"^\s*FUNCTION(?:_BLOCK)?\s+(\w+)", path.read_text("utf-8"),
                               re.MULTILINE)
    assert sorted(p.name for p in pous) == sorted(declared)
    assert len({p.name for p in pous}) == len(pous)
    assert len(pous) >= 80  # the scope: 14 files of the motion/chain/orientation libraries


def test_every_public_pou_has_a_property_test() -> None:
    cover = property_coverage(public_pous())
    missing = sorted(name for name, files in cover.items() if not files)
    assert not missing, (f"{len(missing)} public POU(s) without a property test (a "
                         f"hypothesis module that calls them by name): {', '.join(missing)}")


def test_the_check_sees_a_missing_pou(tmp_path: Path) -> None:
    """The check can fail: a test directory where one POU's only property test is gone."""
    pous = [PouEntry("QuatNorm", "FUNCTION", "Quaternion.st"),
            PouEntry("QuatConjugate", "FUNCTION", "Quaternion.st"),
            PouEntry("MotionHalt", "FUNCTION_BLOCK", "MotionJoint.st")]
    (tmp_path / "test_a.py").write_text(
        "from hypothesis import given, strategies as st\n"
        "@given(st.floats())\n"
        "def test_x(st_module, v):\n"
        "    st_module.call('QuatNorm', v)\n"
        "    fb = st_module.new_fb('MotionHalt')\n")
    (tmp_path / "test_b.py").write_text(  # no hypothesis: not a property test
        "def test_y(st_module):\n"
        "    st_module.call('QuatConjugate', 1.0)\n")
    cover = property_coverage(pous, tmp_path)
    assert cover == {"QuatNorm": ["test_a.py"], "QuatConjugate": [], "MotionHalt": ["test_a.py"]}


def test_names_passed_through_a_variable_count() -> None:
    tree = ast.parse("from hypothesis import given\n"
                     "NAMES = ['QuatNorm', 'a QuatConjugate in a sentence']\n"
                     "@given()\n"
                     "def test_z(st_module):\n"
                     "    for n in NAMES:\n"
                     "        st_module.call(n)\n")
    assert is_property_module(tree)
    assert called_pous(tree, ["QuatNorm", "QuatConjugate"]) == {"QuatNorm"}

