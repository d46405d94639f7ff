"""The AST: plain dataclasses lowered from the tree-sitter syntax tree, each with a SourcePos.

Names keep the user's spelling; resolution compares them upper-cased (ST is case-insensitive).
Resolved types live beside the AST (keyed by node id) in the resolver, not here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cache

from .source import SourcePos


@dataclass(eq=False)
class Node:
    pos: SourcePos


# ---------------------------------------------------------------- expressions
@dataclass(eq=False)
class Expr(Node):
    pass


@dataclass(eq=False)
class Literal(Expr):
    kind: str  # "int" | "real" | "bool" | "time" | "enum" | "string" (value: its C bytes)
    value: int | float | bool | str
    text: str
    type_prefix: str | None = None  # REAL#1.0 -> "REAL", Mode#RUN -> "Mode"


@dataclass(eq=False)
class Name(Expr):
    name: str


@dataclass(eq=False)
class Member(Expr):
    obj: Expr
    member: str


@dataclass(eq=False)
class Index(Expr):
    obj: Expr
    indices: list[Expr]


@dataclass(eq=False)
class Unary(Expr):
    op: str  # "-", "+", "NOT"
    operand: Expr
    # the operand is written in parentheses right after the operator, `NOT (a AND b)`:
    # STruC++ parses that NOT as a call of its NOT function, with C++ typing rules of its own
    parenthesised: bool = False


@dataclass(eq=False)
class Binary(Expr):
    op: str  # upper-cased: + - * / MOD ** AND OR XOR = <> < <= > >=
    left: Expr
    right: Expr


@dataclass(eq=False)
class Arg(Node):
    name: str | None
    value: Expr
    is_output: bool = False  # "=>"


@dataclass(eq=False)
class Call(Expr):
    callee: Expr  # a Name for every call MatIEC accepts
    args: list[Arg]


# ---------------------------------------------------------------- statements
@dataclass(eq=False)
class Stmt(Node):
    pass


@dataclass(eq=False)
class Assign(Stmt):
    target: Expr
    value: Expr


@dataclass(eq=False)
class CallStmt(Stmt):
    call: Call


@dataclass(eq=False)
class If(Stmt):
    branches: list[tuple[Expr, list[Stmt]]]
    orelse: list[Stmt] | None


@dataclass(eq=False)
class CaseLabel(Node):
    low: Expr
    high: Expr | None


@dataclass(eq=False)
class CaseClause(Node):
    labels: list[CaseLabel]
    body: list[Stmt]


@dataclass(eq=False)
class Case(Stmt):
    subject: Expr
    clauses: list[CaseClause]
    orelse: list[Stmt] | None


@dataclass(eq=False)
class For(Stmt):
    var: Name
    start: Expr
    end: Expr
    step: Expr | None
    body: list[Stmt]


@dataclass(eq=False)
class While(Stmt):
    cond: Expr
    body: list[Stmt]


@dataclass(eq=False)
class Repeat(Stmt):
    body: list[Stmt]
    cond: Expr


@dataclass(eq=False)
class Exit(Stmt):
    pass


@dataclass(eq=False)
class Continue(Stmt):
    pass


@dataclass(eq=False)
class Return(Stmt):
    pass


# ---------------------------------------------------------------- types and declarations
@dataclass(eq=False)
class TypeRef(Node):
    pass


@dataclass(eq=False)
class NamedTypeRef(TypeRef):
    name: str


@dataclass(eq=False)
class ArrayTypeRef(TypeRef):
    ranges: list[tuple[Expr, Expr]]
    element: TypeRef


@dataclass(eq=False)
class StructField(Node):
    name: str
    type: TypeRef
    init: Init | None


@dataclass(eq=False)
class StructTypeRef(TypeRef):
    fields: list[StructField]


@dataclass(eq=False)
class EnumValue(Node):
    name: str
    value: Expr | None


@dataclass(eq=False)
class EnumTypeRef(TypeRef):
    values: list[EnumValue]


@dataclass(eq=False)
class SubrangeTypeRef(TypeRef):
    base: str
    low: Expr
    high: Expr


@dataclass(eq=False)
class ArrayInit(Node):
    items: list[tuple[Expr | None, Init]]  # (repeat count, value); count None = once


@dataclass(eq=False)
class StructInit(Node):
    fields: list[tuple[str, Init]]


Init = Expr | ArrayInit | StructInit


@dataclass(eq=False)
class VarDecl(Node):
    name: str
    type: TypeRef
    init: Init | None
    address: str | None = None


# block kinds
VAR, VAR_INPUT, VAR_OUTPUT, VAR_IN_OUT = "VAR", "VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT"
VAR_TEMP, VAR_EXTERNAL, VAR_GLOBAL = "VAR_TEMP", "VAR_EXTERNAL", "VAR_GLOBAL"


@dataclass(eq=False)
class VarBlock(Node):
    kind: str
    constant: bool
    decls: list[VarDecl]


@dataclass(eq=False)
class TypeDecl(Node):
    name: str
    definition: TypeRef
    init: Init | None = None


@dataclass(eq=False)
class Pou(Node):
    kind: str  # "FUNCTION" | "FUNCTION_BLOCK" | "PROGRAM"
    name: str
    return_type: TypeRef | None
    blocks: list[VarBlock]
    body: list[Stmt]
    end_pos: SourcePos
    # {pragmas} in the body holding C (OpenPLC v3 pastes it into its build; the bench cannot)
    c_pragmas: tuple[SourcePos, ...] = ()
    # lone ';' statements (not the ';' after END_IF, END_CASE...): MatIEC refuses them
    empty_statements: tuple[SourcePos, ...] = ()


@dataclass(eq=False)
class TaskDecl(Node):
    name: str
    params: dict[str, Expr]  # upper-cased keys: INTERVAL, PRIORITY, SINGLE


@dataclass(eq=False)
class ProgramInst(Node):
    name: str
    task: str | None
    type_name: str


@dataclass(eq=False)
class Resource(Node):
    name: str
    globals: list[VarBlock]
    tasks: list[TaskDecl]
    programs: list[ProgramInst]


@dataclass(eq=False)
class Configuration(Node):
    name: str
    globals: list[VarBlock]
    resources: list[Resource]


@dataclass(eq=False)
class SourceUnit(Node):
    """One parsed file."""

    types: list[TypeDecl] = field(default_factory=list)
    pous: list[Pou] = field(default_factory=list)
    configs: list[Configuration] = field(default_factory=list)
    stray_globals: list[VarBlock] = field(default_factory=list)  # VAR_GLOBAL at top level


@cache
def _field_names(cls: type) -> tuple[str, ...]:
    # dataclasses.fields() builds its answer on every call: asked once per node of a walk, it
    # was 40 % of a walk's time
    return tuple(f.name for f in dataclasses.fields(cls))


def walk(obj: object) -> Iterator[object]:
    """Every AST node and plain value below obj (dataclass fields, lists, tuples, dicts), with
    a stack, never recursion: a deeply nested file cannot exhaust Python's stack."""
    stack: list[object] = [obj]
    while stack:
        cur = stack.pop()
        yield cur
        if isinstance(cur, Node):
            kind: type = type(cur)
            stack.extend(getattr(cur, name) for name in _field_names(kind))
        elif isinstance(cur, list | tuple):
            stack.extend(cur)
        elif isinstance(cur, dict):
            stack.extend(cur.values())
