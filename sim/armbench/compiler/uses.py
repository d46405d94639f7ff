"""The library by use: which of a library's declarations a program needs.

A program is compiled with exactly the library TYPEs and POUs it refers to, directly or
through other library declarations (names compared upper-cased: ST is case-insensitive).
A name the program declares itself is the program's: the library's declaration of that name
is left out, and so is every library declaration only it would have needed. A library
declaration the program does need that refers to such a name gets the program's declaration
instead (a modified copy of a library type or block replaces the library's); when the result
does not check, the driver reports one E0213 instead of the errors inside the library.

What a library file declares is read from the top level of its syntax tree; the file is
guarded, checked and lowered only when the program needs one of its names. Both results are
cached by the file's content (units.py): an unchanged library file is parsed once, not once
per run.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import tree_sitter as ts

from . import ast as A
from .diagnostics import Diagnostics
from .frontend import parse_source
from .parse import ParsedFile
from .source import SourcePos
from .units import UnitCache

Node = A.TypeDecl | A.Pou | A.Configuration


@dataclass(frozen=True, eq=False)
class Declaration:
    """One top-level declaration of a file: a TYPE, a POU or a CONFIGURATION."""

    name: str  # as spelled
    kind: str  # "TYPE", "FUNCTION", "FUNCTION_BLOCK", "PROGRAM", "CONFIGURATION"
    pos: SourcePos
    declares: frozenset[str]  # upper-cased global names: its own, its enumeration values
    uses: frozenset[str]  # upper-cased global names it refers to (its own locals left out)
    node: Node = field(repr=False)

    def describe(self) -> str:
        """``TYPE Vec3``, ``FUNCTION_BLOCK MotionJog``."""
        return f"{self.kind} {self.name}"


def references(node: object, local: frozenset[str] = frozenset()) -> frozenset[str]:
    """Upper-cased names below ``node`` that may name a global declaration: types, POUs,
    enumeration values. Names of ``local`` variables are not global references; their types
    are."""
    out: set[str] = set()
    for n in A.walk(node):
        if isinstance(n, A.Name):
            key = n.name.upper()
            if key not in local:
                out.add(key)
        elif isinstance(n, A.NamedTypeRef):
            out.add(n.name.upper())
        elif isinstance(n, A.Literal) and n.type_prefix:
            out.add(n.type_prefix.upper())
        elif isinstance(n, A.ProgramInst):
            out.add(n.type_name.upper())
        elif isinstance(n, A.SubrangeTypeRef):
            out.add(n.base.upper())
    return frozenset(out)


def declarations(unit: A.SourceUnit) -> list[Declaration]:
    """The file's declarations, in the order TYPEs, POUs, CONFIGURATIONs."""
    out: list[Declaration] = []
    for t in unit.types:
        names = {t.name.upper()}
        if isinstance(t.definition, A.EnumTypeRef):
            names |= {v.name.upper() for v in t.definition.values}
        out.append(Declaration(t.name, "TYPE", t.pos, frozenset(names),
                               references(t, frozenset()) - names, t))
    for p in unit.pous:
        local = frozenset({p.name.upper()} | {d.name.upper() for b in p.blocks for d in b.decls})
        out.append(Declaration(p.name, p.kind, p.pos, frozenset({p.name.upper()}),
                               references(p, local) - {p.name.upper()}, p))
    for c in unit.configs:
        local = frozenset(d.name.upper() for b in [*c.globals, *(g for r in c.resources
                                                                 for g in r.globals)]
                          for d in b.decls)
        out.append(Declaration(c.name, "CONFIGURATION", c.pos, frozenset(),
                               references(c, local), c))
    return out


def _name_of(node: ts.Node) -> str | None:
    name = node.child_by_field_name("name")
    return None if name is None or name.text is None else name.text.decode("utf-8", "replace")


def top_level_names(pf: ParsedFile) -> dict[str, str]:
    """Upper-cased name -> spelling of what a parsed file declares globally (TYPEs, their
    enumeration values, POUs), read from the top of the syntax tree without lowering it."""
    out: dict[str, str] = {}
    for child in pf.tree.root_node.named_children:
        if child.type == "type_declaration":
            for td in child.named_children:
                if td.type != "type_definition":
                    continue
                name = _name_of(td)
                if name is not None:
                    out.setdefault(name.upper(), name)
                definition = td.child_by_field_name("definition")
                if definition is not None and definition.type == "enumerated_type_inline":
                    for e in definition.named_children:
                        value = _name_of(e) if e.type == "enumerator" else None
                        if value is not None:
                            out.setdefault(value.upper(), value)
        elif child.type in ("function_declaration", "function_block_declaration",
                            "program_declaration"):
            name = _name_of(child)
            if name is not None:
                out.setdefault(name.upper(), name)
    return out


@dataclass(frozen=True)
class Replacement:
    """A name the program declares that library declarations it uses refer to: they get the
    program's declaration, not the library's."""

    mine: Declaration  # the program's declaration
    library_name: str  # the library's spelling
    library_file: str
    needed_by: tuple[Declaration, ...]  # the library declarations referring to it


@dataclass(frozen=True)
class LibraryUse:
    """What the program takes from the library."""

    kept: tuple[Declaration, ...] = ()  # in library order: file, then place in the file
    replaced: tuple[Replacement, ...] = ()

    @property
    def files(self) -> list[str]:
        """The library files something is taken from, in library order."""
        return list(dict.fromkeys(d.pos.file for d in self.kept))

    def prune(self, unit: A.SourceUnit) -> A.SourceUnit:
        """The unit with only the kept declarations."""
        keep = {id(d.node) for d in self.kept}
        return A.SourceUnit(unit.pos, [t for t in unit.types if id(t) in keep],
                            [p for p in unit.pous if id(p) in keep])

    def _replacing(self) -> tuple[str, str, str, int]:
        mine = _listed([r.mine.describe() for r in self.replaced])
        files = ", ".join(dict.fromkeys(Path(r.library_file).name for r in self.replaced))
        users = sorted({d.name for r in self.replaced for d in r.needed_by})
        return mine, files, _listed(users), len(users)

    def note(self) -> str | None:
        """One line saying which of the program's declarations the library declarations it
        uses get instead of the library's own (None: none)."""
        if not self.replaced:
            return None
        mine, files, users, _ = self._replacing()
        return (f"your {mine} replace{'s' if len(self.replaced) == 1 else ''} the armbench "
                f"library's ({files}) in the library declarations you use: {users}")

    def conflict(self) -> str:
        """The E0213 message: one line for all the errors the replacements caused inside the
        library."""
        mine, files, users, n_users = self._replacing()
        one = len(self.replaced) == 1
        return (f"your {mine} replace{'s' if one else ''} the armbench library's "
                f"declaration{'' if one else 's'} of the same name ({files}), but the library's "
                f"{users}, which your program uses, need{'s' if n_users == 1 else ''} the "
                "library's own: rename yours, or check with --no-library and pass the library "
                "files you need")


def _listed(items: Sequence[str], most: int = 3) -> str:
    if len(items) <= most:
        return ", ".join(items)
    return f"{', '.join(items[:most])} and {len(items) - most} more"


class Library:
    """The library files a program's names are looked up in (one compilation's worth).

    Diagnostics of a library file (its nesting, lexical rules, lowering) go to ``diags``,
    only for the files that are loaded."""

    def __init__(self, paths: Sequence[Path], diags: Diagnostics,
                 cache: UnitCache | None = None) -> None:
        self.diags = diags
        self.cache = UnitCache() if cache is None else cache
        self.order: dict[str, int] = {}  # the library's readable files, in library order
        self.index: dict[str, tuple[str, str]] = {}  # NAME -> (file, spelling); first wins
        self._files: dict[str, tuple[Path, bytes]] = {}
        for path in paths:
            try:
                data = self.cache.read(path)
            except OSError:
                continue
            names = self.cache.get("names", path, data, dict)
            if not isinstance(names, dict):
                pf = parse_source(path, data, Diagnostics())
                if pf is None:
                    continue
                names = top_level_names(pf)
                self.cache.put("names", path, data, names)
            file = str(path)
            self._files[file] = (path, data)
            self.order[file] = len(self.order)
            for key, spelled in names.items():
                self.index.setdefault(key, (file, spelled))
        self.units: dict[str, A.SourceUnit | None] = {}
        self._declared: dict[str, Declaration] = {}

    def file_of(self, name: str) -> str | None:
        hit = self.index.get(name.upper())
        return None if hit is None else hit[0]

    def load(self, file: str) -> A.SourceUnit | None:
        """The file lowered (None: it has errors, now in diags)."""
        if file in self.units:
            return self.units[file]
        path, data = self._files[file]
        front = self.cache.front(path, data)
        mine = Diagnostics()
        mine.extend(front.syntax)
        mine.extend(front.lowering)
        self.diags.extend(mine.items)
        unit = None if mine.has_errors else front.unit
        self.units[file] = unit
        for d in declarations(unit) if unit is not None else []:
            for key in d.declares:
                self._declared.setdefault(key, d)
        return unit

    def declaration(self, name: str) -> Declaration | None:
        file = self.file_of(name)
        if file is None:
            return None
        self.load(file)
        return self._declared.get(name.upper())

    def select(self, program: Sequence[A.SourceUnit]) -> LibraryUse:
        """The library declarations ``program`` needs, transitively."""
        mine: dict[str, Declaration] = {}
        roots: set[str] = set()
        for unit in program:
            for d in declarations(unit):
                for key in d.declares:
                    mine.setdefault(key, d)
                roots |= d.uses
        kept: dict[int, Declaration] = {}
        replaced: dict[str, tuple[Declaration, list[Declaration]]] = {}
        queue = deque(sorted(roots - mine.keys()))
        while queue:
            found = self.declaration(queue.popleft())
            if found is None or id(found) in kept:
                continue
            kept[id(found)] = found
            for key in sorted(found.uses - found.declares):
                if key in mine:  # the program's own: the library's is not taken
                    if key in self.index:
                        replaced.setdefault(key, (mine[key], []))[1].append(found)
                else:
                    queue.append(key)
        return LibraryUse(
            tuple(sorted(kept.values(), key=lambda d: (self.order[d.pos.file], d.pos.line,
                                                        d.pos.col))),
            tuple(Replacement(m, self.index[k][1], self.index[k][0], tuple(users))
                  for k, (m, users) in sorted(replaced.items())))
