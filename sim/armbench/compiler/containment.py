"""Containment: which TYPEs and FB/PROGRAM instances hold which, checked before types are built.

A STRUCT that contains itself (directly, through another STRUCT or through an ARRAY of
STRUCTs), or a FUNCTION_BLOCK that holds an instance of itself, would need infinite storage:
MatIEC rejects it and its C does not compile. Each such cycle is reported once (E0210), at the
declaration that starts it, and its members are left out of the build. Chains of types nested
deeper than NESTING_LIMIT (E0211) are rejected too, so the recursive walks over types (C
emission, FFI conversion) stay bounded. Everything here uses explicit stacks.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import ast as A
from .diagnostics import Diagnostics
from .limits import NESTING_LIMIT
from .source import SourcePos


@dataclass(frozen=True)
class Edge:
    target: str  # upper-cased name of the contained type or FB
    via: str  # the member holding it ('' for an alias `TYPE T1 : T2;`)
    weight: int  # levels of storage nesting down to the reference (0: `TYPE T1 : T2;` is T2)


@dataclass
class Holder:
    name: str
    kind: str  # "STRUCT", "TYPE", "FUNCTION_BLOCK", "PROGRAM"
    pos: SourcePos
    edges: list[Edge]


def type_holder(td: A.TypeDecl) -> Holder:
    kind = "STRUCT" if isinstance(td.definition, A.StructTypeRef) else "TYPE"
    edges: list[Edge] = []
    stack: list[tuple[A.TypeRef, str, int]] = [(td.definition, "", 0)]
    while stack:
        ref, via, depth = stack.pop()
        if isinstance(ref, A.NamedTypeRef):
            edges.append(Edge(ref.name.upper(), via, depth))
        elif isinstance(ref, A.ArrayTypeRef):
            stack.append((ref.element, via, depth + 1))
        elif isinstance(ref, A.StructTypeRef):
            for f in reversed(ref.fields):
                stack.append((f.type, f"{via}.{f.name}" if via else f.name, depth + 1))
    return Holder(td.name, kind, td.pos, edges)


def pou_holder(pou: A.Pou) -> Holder:
    edges: list[Edge] = []
    for blk in pou.blocks:
        # in-outs are pointers and externals live in the CONFIGURATION: neither is held
        if blk.kind in (A.VAR_IN_OUT, A.VAR_EXTERNAL):
            continue
        for decl in blk.decls:
            edges.extend(Edge(e.target, decl.name + (f".{e.via}" if e.via else ""), e.weight + 1)
                         for e in type_holder(A.TypeDecl(decl.pos, "", decl.type)).edges)
    return Holder(pou.name, pou.kind, pou.pos, edges)


def check_containment(holders: dict[str, Holder], diags: Diagnostics,
                      limit: int = NESTING_LIMIT) -> tuple[set[str], list[str]]:
    """Report containment cycles and over-deep nesting. Returns the keys not to build and the
    others in dependency order (what a holder contains comes before it)."""
    bad: set[str] = set()
    for scc in _cycles(holders):
        first = min(scc, key=lambda k: (holders[k].pos.file, holders[k].pos.line,
                                        holders[k].pos.col))
        h = holders[first]
        diags.error(h.pos, "E0210", f"{h.kind} {h.name} contains itself "
                    f"through {_describe(_cycle_from(first, scc, holders), holders)}: it would "
                    "need infinite storage (MatIEC rejects it)")
        bad |= scc
    order = _order_and_depth(holders, bad, diags, limit)
    return bad, order


def check_declaration_order(decls: dict[str, A.TypeDecl], skip: set[str],
                            diags: Diagnostics) -> None:
    """E0212: MatIEC resolves the types named inside a TYPE declaration (STRUCT fields, ARRAY
    elements, aliases) while it parses, even with -p, so each must be declared earlier in the
    file (measured: "invalid specification in structure element declaration"). POUs may use
    later types, FBs and FUNCTIONs. Reported once per file, at the first such declaration, with
    a count of the others. Types of another file are not checked: their order is the order of
    the files OpenPLC gets (the export puts the types file first)."""
    late: dict[str, list[tuple[A.TypeDecl, A.TypeDecl]]] = {}
    for key, td in decls.items():
        if key in skip:
            continue
        for e in type_holder(td).edges:
            target = decls.get(e.target)
            if target is None or e.target == key or target.pos.file != td.pos.file:
                continue
            if (target.pos.line, target.pos.col) > (td.pos.line, td.pos.col):
                late.setdefault(td.pos.file, []).append((td, target))
                break
    for pairs in late.values():
        pairs.sort(key=lambda p: (p[0].pos.line, p[0].pos.col))
        td, target = pairs[0]
        more = f" ({len(pairs) - 1} more such types in this file)" if len(pairs) > 1 else ""
        diags.error(td.pos, "E0212", f"type {td.name} uses {target.name}, which is declared "
                    f"later (line {target.pos.line}): MatIEC rejects a TYPE that names a "
                    f"later type, even with -p{more}; declare {target.name} first")


def _edges(holders: dict[str, Holder], k: str) -> list[Edge]:
    return [e for e in holders[k].edges if e.target in holders]


def _cycles(holders: dict[str, Holder]) -> list[set[str]]:
    """Strongly connected components that hold a cycle (Tarjan's algorithm, iteratively)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[set[str]] = []
    for root in holders:
        if root in index:
            continue
        work: list[tuple[str, int]] = [(root, 0)]
        while work:
            k, i = work.pop()
            if i == 0:
                index[k] = low[k] = len(index)
                stack.append(k)
                on_stack.add(k)
            edges = _edges(holders, k)
            if i < len(edges):
                work.append((k, i + 1))
                t = edges[i].target
                if t not in index:
                    work.append((t, 0))
                elif t in on_stack:
                    low[k] = min(low[k], index[t])
                continue
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[k])
            if low[k] == index[k]:
                scc: set[str] = set()
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    scc.add(m)
                    if m == k:
                        break
                if len(scc) > 1 or any(e.target == k for e in _edges(holders, k)):
                    out.append(scc)
    return out


def _cycle_from(start: str, scc: set[str], holders: dict[str, Holder]) -> list[tuple[str, Edge]]:
    """A shortest cycle start -> ... -> start inside one component (breadth first)."""
    came: dict[str, tuple[str, Edge]] = {}
    frontier = [start]
    while frontier:
        nxt: list[str] = []
        for k in frontier:
            for e in _edges(holders, k):
                if e.target not in scc or e.target in came:
                    continue
                came[e.target] = (k, e)
                if e.target == start:
                    path: list[tuple[str, Edge]] = []
                    node = start
                    while True:
                        prev, edge = came[node]
                        path.append((prev, edge))
                        node = prev
                        if node == start:
                            return path[::-1]
                nxt.append(e.target)
        frontier = nxt
    raise AssertionError("a cycle component without a cycle")


def _describe(path: list[tuple[str, Edge]], holders: dict[str, Holder]) -> str:
    return " -> ".join(f"{holders[k].name}.{e.via}" if e.via else holders[k].name
                       for k, e in path)


def _order_and_depth(holders: dict[str, Holder], bad: set[str], diags: Diagnostics,
                     limit: int) -> list[str]:
    """Post-order of the acyclic rest, with the longest containment chain below each holder;
    holders nested deeper than the limit join `bad` (reported once, at the first found)."""
    depth: dict[str, int] = {}
    reported = False
    for root in holders:
        if root in depth or root in bad:
            continue
        work: list[tuple[str, bool]] = [(root, False)]
        while work:
            k, expanded = work.pop()
            if k in depth:
                continue
            edges = [e for e in _edges(holders, k) if e.target not in bad]
            if not expanded:
                work.append((k, True))
                work.extend((e.target, False) for e in edges if e.target not in depth)
                continue
            depth[k] = max((e.weight + depth[e.target] for e in edges), default=0)
            if depth[k] > limit:
                bad.add(k)
                if not reported:
                    reported = True
                    h = holders[k]
                    diags.error(h.pos, "E0211", f"{h.kind} {h.name} nests "
                                f"types or instances {depth[k]} levels deep, more than "
                                f"the bench's limit of {limit} (MatIEC takes more): flatten "
                                "the data structure")
    return [k for k in depth if k not in bad]
