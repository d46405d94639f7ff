"""Export sources: which ST files, their text, and a dependency-safe order.

Needs: the files already pass the checker (``driver.analyse`` returned a CheckedProgram); the
order is computed from that program's AST (``units``), one unit per file.

A file comes after every file that declares a name it uses (a type, a POU, an enumeration
value); among files that are free to go, those holding only TYPE declarations go first, then
the given order. A dependency cycle between files (legal: the checker resolves names over the
whole program) keeps the given order for the files in the cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..compiler import ast as A
from ..compiler.uses import references
from ..locate import Project, default_project


def default_sources(project: Project | None = None) -> list[Path]:
    """st/*.st (sorted) then plc_project/Controller.st, of ``project`` (default: the files
    the tools use, :func:`armbench.locate.default_project`)."""
    return (project or default_project()).sources()


def display_name(path: Path, project: Project | None = None) -> str:
    """The path as written in generated files: ``st/...`` / ``plc_project/...`` when it is
    one of the project's files (installed or in a checkout alike), else as given."""
    return (project or default_project()).relative(path) or path.as_posix()


@dataclass(frozen=True)
class Source:
    """One ST file: its path, the name shown in generated files, its text and its AST. A
    library file's AST holds only the declarations the program uses (the exports hold only
    those)."""

    path: Path
    name: str
    text: str
    unit: A.SourceUnit
    library: bool = False


def declared_names(unit: A.SourceUnit) -> set[str]:
    names = {t.name.upper() for t in unit.types} | {p.name.upper() for p in unit.pous}
    for t in unit.types:
        if isinstance(t.definition, A.EnumTypeRef):
            names |= {v.name.upper() for v in t.definition.values}
    return names


def used_names(unit: A.SourceUnit) -> set[str]:
    return set(references(unit))


def dependency_order(units: Sequence[A.SourceUnit]) -> list[int]:
    """Indices of units, each after the units declaring the names it uses (types first)."""
    n = len(units)
    decl = [declared_names(u) for u in units]
    deps: list[set[int]] = []
    for i, u in enumerate(units):
        use = used_names(u) - decl[i]
        deps.append({j for j in range(n) if j != i and use & decl[j]})

    def rank(i: int) -> tuple[int, int]:
        types_only = bool(units[i].types) and not units[i].pous and not units[i].configs
        return (0 if types_only else 1, i)

    done: list[int] = []
    left = set(range(n))
    while left:
        ready = [i for i in left if not (deps[i] & left)]
        if not ready:  # a cycle: keep the given order for what remains
            ready = [min(left, key=rank)]
        nxt = min(ready, key=rank)
        done.append(nxt)
        left.remove(nxt)
    return done
