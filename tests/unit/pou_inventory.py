"""Inventory of the public POUs of the motion, servo-slew, chain, 4-/5-axis and orientation
libraries, and of the hypothesis-driven test modules that call each of them.

"Public" is every FUNCTION / FUNCTION_BLOCK that the block reference publishes: docgen
(sim/armbench/docgen.py) writes a page in docs/reference/ for every POU of st/*.st, and no
header in these files marks a POU as internal, so every POU they declare is public. The names
are read with docgen's own reader, so the inventory is exactly the reference's list.

A POU counts as property-tested when a test module under tests/unit

- imports hypothesis and has at least one ``@given`` test, and
- calls the POU by name: ``<module>.call("Name", ...)``, ``.call_full("Name", ...)`` or
  ``.new_fb("Name")``. When the name is passed through a variable (a parametrised list of
  names), the module's string literals that equal a POU name count too.

Run ``python tests/unit/pou_inventory.py`` for the table (POU -> test modules).
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ST_DIR = REPO / "st"
TEST_DIR = REPO / "tests" / "unit"

# The files the property suite covers (glob patterns under st/).
SCOPE = ("Motion*.st", "ServoSlew.st", "KinematicsChain*.st", "Kinematics4Axis.st",
         "Kinematics5Axis.st", "Quaternion.st", "OrientationFilters.st", "ToolOrientation*.st")

CALLERS = frozenset({"call", "call_full", "new_fb"})


@dataclass(frozen=True)
class PouEntry:
    """One public POU: its name, FUNCTION or FUNCTION_BLOCK, and the ST file."""

    name: str
    kind: str
    file: str


def scope_files(st_dir: Path = ST_DIR, patterns: Sequence[str] = SCOPE) -> list[Path]:
    files: set[Path] = set()
    for pattern in patterns:
        files.update(st_dir.glob(pattern))
    return sorted(files)


def public_pous(st_dir: Path = ST_DIR, patterns: Sequence[str] = SCOPE) -> list[PouEntry]:
    """Every POU of the scope's files, read by docgen's reader (the reference's own list)."""
    from armbench.docgen import read_st

    out: list[PouEntry] = []
    for path in scope_files(st_dir, patterns):
        out += [PouEntry(p.name, p.kind, path.name) for p in read_st(path).pous]
    return out


def _imports_hypothesis(tree: ast.AST) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(
                a.name.split(".")[0] == "hypothesis" for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "hypothesis":
            return True
    return False


def _has_given(tree: ast.AST) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for deco in node.decorator_list:
                target = deco.func if isinstance(deco, ast.Call) else deco
                name = target.attr if isinstance(target, ast.Attribute) else (
                    target.id if isinstance(target, ast.Name) else "")
                if name == "given":
                    return True
    return False


def is_property_module(tree: ast.AST) -> bool:
    """Imports hypothesis and has at least one @given test."""
    return _imports_hypothesis(tree) and _has_given(tree)


def called_pous(tree: ast.AST, names: Iterable[str]) -> set[str]:
    """The POU names a module calls through call / call_full / new_fb."""
    known = set(names)
    found: set[str] = set()
    indirect = False
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in CALLERS and node.args):
            continue
        first = node.args[0]
        if isinstance(first, ast.Constant) and isinstance(first.value, str):
            if first.value in known:
                found.add(first.value)
        else:
            indirect = True
    if indirect:  # a name passed through a variable: the module's literal POU names
        found |= {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)
                  and isinstance(n.value, str) and n.value in known}
    return found


def property_coverage(pous: Sequence[PouEntry],
                      test_dir: Path = TEST_DIR) -> dict[str, list[str]]:
    """POU name -> the property test modules (file names) that call it; [] when none."""
    names = [p.name for p in pous]
    cover: dict[str, list[str]] = {n: [] for n in names}
    for path in sorted(test_dir.glob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        if not is_property_module(tree):
            continue
        for name in sorted(called_pous(tree, names)):
            cover[name].append(path.name)
    return cover


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--missing", action="store_true", help="list only untested POUs")
    args = parser.parse_args(argv)
    pous = public_pous()
    cover = property_coverage(pous)
    missing = [p for p in pous if not cover[p.name]]
    for p in pous:
        if args.missing and cover[p.name]:
            continue
        where = ", ".join(cover[p.name]) or "-- none --"
        print(f"{p.file:26} {p.name:30} {where}")
    print(f"{len(pous)} public POUs, {len(pous) - len(missing)} with a property test, "
          f"{len(missing)} without")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO / "sim"))
    sys.exit(main())
