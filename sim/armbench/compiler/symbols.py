"""Symbols and the checked program: what the resolver hands to the C emitter and the FFI."""

from __future__ import annotations

from dataclasses import dataclass, field

from . import ast as A
from .source import SourcePos
from .stdlib import StdFunc
from .types import ElemType, Type


@dataclass(eq=False)
class VarSym:
    name: str
    type: Type
    kind: str  # ast block kind, or "RETURN"
    constant: bool
    pos: SourcePos
    init: A.Init | None = None
    address: str | None = None

    @property
    def key(self) -> str:
        return self.name.upper()


@dataclass(eq=False)
class PouSym:
    name: str
    kind: str  # FUNCTION | FUNCTION_BLOCK | PROGRAM
    node: A.Pou | None
    vars: dict[str, VarSym] = field(default_factory=dict)
    return_type: Type | None = None
    builtin: bool = False

    @property
    def key(self) -> str:
        return self.name.upper()

    def params(self) -> list[VarSym]:
        return [v for v in self.vars.values()
                if v.kind in (A.VAR_INPUT, A.VAR_IN_OUT, A.VAR_OUTPUT)]

    def inputs(self) -> list[VarSym]:
        return [v for v in self.vars.values() if v.kind in (A.VAR_INPUT, A.VAR_IN_OUT)]


@dataclass(frozen=True)
class CallTarget:
    kind: str  # "function" | "fb" | "std" | "conv" | "alias"
    pou: PouSym | None = None
    std: StdFunc | None = None
    conv: tuple[ElemType, ElemType] | None = None
    # bound arguments: parameter key -> expression (inputs/in-outs), outputs -> target expr
    inputs: tuple[tuple[str, A.Expr], ...] = ()
    outputs: tuple[tuple[str, A.Expr], ...] = ()
    # "alias": a standard function in call form (ADD(a, b), GT(a, b, c)) computed as the
    # operator expression it stands for, built from the call's own argument nodes
    alias: A.Expr | None = None
    # the implicit EN input and ENO output every call has (`F(EN := c, ..., ENO => ok)`)
    en: A.Expr | None = None
    eno: A.Expr | None = None


@dataclass(frozen=True)
class NameRef:
    kind: str  # "var" | "global" | "enum" | "pou_result"
    var: VarSym | None = None
    enum_value: int = 0


@dataclass
class TaskModel:
    name: str
    interval_ns: int
    priority: int
    pos: SourcePos


@dataclass
class InstanceModel:
    name: str
    task: str | None
    pou: PouSym
    pos: SourcePos


@dataclass
class ConfigModel:
    name: str
    resource: str
    globals: dict[str, VarSym]
    tasks: list[TaskModel]
    instances: list[InstanceModel]


@dataclass
class CheckedProgram:
    types: dict[str, Type]
    pous: dict[str, PouSym]  # user POUs in dependency order (callees first)
    expr_types: dict[A.Expr, Type]
    names: dict[A.Expr, NameRef]
    calls: dict[A.Call, CallTarget]
    config: ConfigModel | None
    units: list[A.SourceUnit]
