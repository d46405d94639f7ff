"""Resolve and type-check: AST units -> CheckedProgram. Needs: lowered units without syntax errors.

Implements MatIEC's typing: no implicit conversion between elementary types, untyped literals
take the type their context asks for (integer literals never become REAL), constant
expressions are folded and range-checked, calls are checked against the callee's interface.
Declarations live in resolve_decl.py, standard-function typing in resolve_std.py.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import Any

from . import ast as A
from .config_syntax import configuration_form
from .containment import check_containment, check_declaration_order, pou_holder, type_holder
from .diagnostics import Diagnostics
from .resolve_decl import Declarations
from .resolve_std import StdCallTyper
from .source import SourcePos
from .stdlib import CALL_FORM_OPERATORS, CONVERSIONS, STD_FBS, STD_FUNCS
from .symbols import (
    CallTarget,
    CheckedProgram,
    NameRef,
    PouSym,
    VarSym,
)
from .types import (
    BOOL,
    DINT,
    ELEMENTARY,
    ERROR_T,
    INT_LIT,
    LINT,
    REAL_LIT,
    STRING,
    TIME,
    ArrayType,
    ElemType,
    EnumType,
    LiteralType,
    PouType,
    StructType,
    Type,
    same_type,
)


class Checker(Declarations):
    def __init__(self, units: list[A.SourceUnit], diags: Diagnostics) -> None:
        self.units = units
        self.d = diags
        self.types: dict[str, Type] = {}
        self.type_decls: dict[str, A.TypeDecl] = {}
        self.pous: dict[str, PouSym] = {}
        self.expr_types: dict[A.Expr, Type] = {}
        self.names: dict[A.Expr, NameRef] = {}
        self.calls: dict[A.Call, CallTarget] = {}
        self.consts: dict[A.Expr, int | float] = {}
        self.globals: dict[str, VarSym] = {}
        self.enum_values: dict[str, list[tuple[EnumType, int]]] = {}
        self.call_graph: dict[str, set[str]] = {}
        self.call_sites: dict[tuple[str, str], SourcePos] = {}  # first call of callee by caller
        self.cur: PouSym | None = None
        self.loop_depth = 0
        self.global_consts: dict[str, int] = {}
        self.std = StdCallTyper(self)

    # ================================================================ declarations
    def run(self) -> CheckedProgram:
        for name, fields in STD_FBS.items():
            sym = PouSym(name, "FUNCTION_BLOCK", None, builtin=True)
            for f in fields:
                sym.vars[f.name] = VarSym(f.name, ELEMENTARY[f.type], f.kind, False,
                                          SourcePos("<builtin>", 0, 0))
            self.pous[name] = sym
            self.types[name] = PouType(name, "FUNCTION_BLOCK", sym)
        for u in self.units:
            for td in u.types:
                self._declare(td.name, td.pos, self.type_decls, td)
            for p in u.pous:
                if self._declare(p.name, p.pos, self.pous, PouSym(p.name, p.kind, p)) and \
                        p.kind != "FUNCTION":
                    self.types[p.name.upper()] = PouType(p.name, p.kind,
                                                         self.pous[p.name.upper()])
            for g in u.stray_globals:
                self.d.error(g.pos, "E0206", "VAR_GLOBAL outside a CONFIGURATION is not "
                             "portable (MatIEC rejects a CODESYS-style GVL)")
        for u in self.units:
            for c in u.configs:
                for blk in c.globals + [g for r in c.resources for g in r.globals]:
                    for decl in blk.decls:
                        if blk.constant and isinstance(decl.init, A.Literal) and \
                                decl.init.kind == "int":
                            self.global_consts[decl.name.upper()] = int(decl.init.value)
        holders = {key: type_holder(td) for key, td in self.type_decls.items()}
        for sym in self.user_pous():
            if sym.node is not None and sym.kind != "FUNCTION":
                holders.setdefault(sym.key, pou_holder(sym.node))
        bad, order = check_containment(holders, self.d)
        check_declaration_order(self.type_decls, bad, self.d)
        for key in bad:
            if key in self.type_decls:
                self.types[key] = ERROR_T
        # what a type contains is built before it, so building never recurses through names
        for key in order + list(self.type_decls):
            if key in self.type_decls and key not in self.types:
                self.types[key] = self.named_type(self.type_decls[key], set())
        for sym in self.user_pous():
            self.declare_pou_vars(sym)
        config = None
        for u in self.units:
            for c in u.configs:
                if config is not None:
                    self.d.error(c.pos, "E0602", "more than one CONFIGURATION")
                    continue
                config = self.configuration(c)
        progs = [p for p in self.user_pous() if p.kind == "PROGRAM"]
        if progs and config is None:
            node = progs[0].node
            assert node is not None
            self.d.error(node.pos, "E0602", f"PROGRAM {progs[0].name} has no CONFIGURATION: "
                         "the bench and OpenPLC run a PROGRAM only as an instance under a "
                         f"periodic TASK; add `{configuration_form(progs[0].name)}`")
        for sym in self.user_pous():
            self.check_body(sym)
        self.check_recursion()
        return CheckedProgram(self.types, {k: v for k, v in self.ordered_pous()},
                              self.expr_types, self.names, self.calls, config, self.units)

    def user_pous(self) -> list[PouSym]:
        return [p for p in self.pous.values() if not p.builtin]

    def _declare(self, name: str, pos: SourcePos, table: dict[str, Any], value: object) -> bool:
        key = name.upper()
        if key in self.pous or key in self.type_decls or key in ELEMENTARY:
            self.d.error(pos, "E0201", f"'{name}' is already declared (names are "
                         "case-insensitive)")
            return False
        table[key] = value
        return True

    # ================================================================ bodies
    def check_body(self, p: PouSym) -> None:
        assert p.node is not None
        self.cur = p
        self.call_graph[p.key] = set()
        for v in p.vars.values():
            if v.kind == A.VAR_EXTERNAL:
                g = self.globals.get(v.key)
                if g is None:
                    self.d.error(v.pos, "E0205", f"VAR_EXTERNAL '{v.name}' has no VAR_GLOBAL "
                                 "in the CONFIGURATION")
                elif not same_type(g.type, v.type):
                    self.d.error(v.pos, "E0205", f"VAR_EXTERNAL '{v.name}' is {v.type} but the "
                                 f"global is {g.type}")
            if v.init is not None:
                self.check_init(v.init, v.type)
        self.stmts(p.node.body)
        self.cur = None

    def check_init(self, init: A.Init, t: Type) -> None:
        if t is ERROR_T:
            return
        if isinstance(init, A.ArrayInit):
            if not isinstance(t, ArrayType):
                self.d.error(init.pos, "E0300", f"array initialiser for {_a(t)}")
                return
            count = 0
            for n, v in init.items:
                reps = 1
                if n is not None:
                    reps = self.literal_bound(n) or 0
                count += reps
                if isinstance(v, A.Expr) and isinstance(t.element, ElemType) and \
                        t.element.is_real and self.expr(v, t.element) is INT_LIT:
                    # MatIEC tolerates integers in an array initialiser of REALs
                    self.settle(v, t.element)
                    continue
                self.check_init(v, t.element)
            if count > t.size:
                self.d.error(init.pos, "E0503", f"{count} initial values for {t.size} "
                             "elements (MatIEC crashes on this)")
            return
        if isinstance(init, A.StructInit):
            if not isinstance(t, StructType):
                self.d.error(init.pos, "E0300", f"structure initialiser for {_a(t)}")
                return
            for fname, fv in init.fields:
                f = t.fields.get(fname.upper())
                if f is None:
                    self.d.error(init.pos, "E0305", f"{t.name} has no field '{fname}'")
                    continue
                if isinstance(f[1], EnumType):
                    self.d.error(fv.pos, "E0105", f"enumerated field '{fname}' in a structure "
                                 "initialiser crashes MatIEC: set it in the code instead")
                    continue
                self.check_init(fv, f[1])
            return
        if isinstance(t, ArrayType):
            # a single value for a whole array
            if isinstance(init, A.Literal):
                self.check_init(A.ArrayInit(init.pos, [(None, init)]), t)
                return
        self.coerce_to(init, self.expr(init, t), t, "Initial value")
        if not self.is_constant(init):
            self.d.error(init.pos, "E0300", "an initial value must be a constant")

    def is_constant(self, e: A.Expr) -> bool:
        stack = [e]
        while stack:
            x = stack.pop()
            if isinstance(x, A.Literal):
                continue
            if isinstance(x, A.Name):
                ref = self.names.get(x)
                if ref is None or ref.kind != "enum":
                    return False
            elif isinstance(x, A.Unary):
                stack.append(x.operand)
            elif isinstance(x, A.Binary):
                stack += (x.right, x.left)
            else:
                return False
        return True

    def stmts(self, body: list[A.Stmt]) -> None:
        for s in body:
            self.stmt(s)

    def stmt(self, s: A.Stmt) -> None:
        if isinstance(s, A.Assign):
            tt = self.lvalue(s.target)
            vt = self.expr(s.value, tt)
            self.coerce_to(s.value, vt, tt, "':='")
        elif isinstance(s, A.CallStmt):
            self.call(s.call, statement=True)
        elif isinstance(s, A.If):
            for cond, body in s.branches:
                self.bool_cond(cond)
                self.stmts(body)
            if s.orelse is not None:
                self.stmts(s.orelse)
        elif isinstance(s, A.Case):
            st = self.expr(s.subject, None)
            if st is not ERROR_T and not (isinstance(st, EnumType) or
                                          (isinstance(st, ElemType) and (st.is_int or
                                                                         st.kind == "bits"))):
                self.d.error(s.subject.pos, "E0303", f"CASE needs an integer or enumerated "
                             f"selector, not {st}")
            for cl in s.clauses:
                for lab in cl.labels:
                    for e in (lab.low, lab.high):
                        if e is not None:
                            self.coerce_to(e, self.expr(e, st), st, "CASE label")
                self.stmts(cl.body)
            if s.orelse is not None:
                self.stmts(s.orelse)
        elif isinstance(s, A.For):
            vt = self.lvalue(s.var)
            if vt is not ERROR_T and not (isinstance(vt, ElemType) and vt.is_int):
                self.d.error(s.var.pos, "E0303", f"FOR needs an integer control variable, "
                             f"not {vt}")
            for e in (s.start, s.end, s.step):
                if e is not None:
                    self.coerce_to(e, self.expr(e, vt), vt, "FOR")
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
        elif isinstance(s, A.While | A.Repeat):
            self.bool_cond(s.cond)
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
        elif isinstance(s, A.Exit | A.Continue):
            if self.loop_depth == 0:
                self.d.error(s.pos, "E0400", "EXIT/CONTINUE outside a loop")

    def bool_cond(self, e: A.Expr) -> None:
        t = self.expr(e, BOOL)
        self.coerce_to(e, t, BOOL, "condition")

    # ---------------------------------------------------------------- lvalues
    def lvalue(self, e: A.Expr) -> Type:
        t = self.expr(e, None)
        root = e
        while isinstance(root, A.Member | A.Index):
            root = root.obj
        ref = self.names.get(root)
        if isinstance(e, A.Name) and ref is None and t is not ERROR_T:
            self.d.error(e.pos, "E0302", f"'{e.name}' cannot be assigned")
            return ERROR_T
        if ref is not None and ref.var is not None:
            v = ref.var
            if v.constant:
                self.d.error(e.pos, "E0302", f"'{v.name}' is a CONSTANT")
            if isinstance(e, A.Member) and isinstance(self.expr_types.get(e.obj), PouType):
                inst_t = self.expr_types[e.obj]
                assert isinstance(inst_t, PouType)
                sym = inst_t.symbol
                assert isinstance(sym, PouSym)
                mv = sym.vars.get(e.member.upper())
                if mv is not None and mv.kind == A.VAR_OUTPUT:
                    self.d.error(e.pos, "E0408", f"'{e.member}' is an output of "
                                 f"{sym.name}: it cannot be written from outside")
                elif mv is not None and mv.kind not in (A.VAR_INPUT,):
                    self.d.error(e.pos, "E0302", f"'{e.member}' is internal to {sym.name}")
        if isinstance(e, A.Call):
            self.d.error(e.pos, "E0302", "a call result cannot be assigned")
        return t

    # ---------------------------------------------------------------- expressions
    def expr(self, e: A.Expr, expected: Type | None) -> Type:
        # the nesting operators are dispatched here, not in _expr: one Python frame less per
        # level of nesting (see limits.NESTING_LIMIT)
        if isinstance(e, A.Call):
            t = self.call(e, statement=False, expected=expected)
        elif isinstance(e, A.Binary):
            t = self.binary(e, expected)
        elif isinstance(e, A.Unary):
            t = self.unary(e, expected)
        else:
            t = self._expr(e, expected)
        self.expr_types[e] = t
        return t

    def _expr(self, e: A.Expr, expected: Type | None) -> Type:
        if isinstance(e, A.Literal):
            return self.literal(e)
        if isinstance(e, A.Name):
            return self.name(e)
        if isinstance(e, A.Member):
            if isinstance(e.obj, A.Call):
                self.d.error(e.pos, "E0404", "field access on a call result ('F(x).X') is "
                             "rejected by MatIEC")
                self.expr(e.obj, None)
                return ERROR_T
            ot = self.expr(e.obj, None)
            if ot is ERROR_T:
                return ERROR_T
            if isinstance(ot, StructType):
                f = ot.fields.get(e.member.upper())
                if f is None:
                    self.d.error(e.pos, "E0305", f"{ot.name} has no field '{e.member}'")
                    return ERROR_T
                return f[1]
            if isinstance(ot, PouType):
                sym = ot.symbol
                assert isinstance(sym, PouSym)
                v = sym.vars.get(e.member.upper())
                if v is None or v.kind == A.VAR_TEMP:
                    self.d.error(e.pos, "E0305", f"{sym.name} has no variable '{e.member}'")
                    return ERROR_T
                return v.type
            self.d.error(e.pos, "E0305", f"'.{e.member}' on {_a(ot)}")
            return ERROR_T
        if isinstance(e, A.Index):
            ot = self.expr(e.obj, None)
            for i in e.indices:
                it = self.expr(i, DINT)
                if isinstance(it, LiteralType) and not it.is_real and it is not ERROR_T:
                    self.coerce_to(i, it, DINT, "index")
                elif it is not ERROR_T and not (isinstance(it, ElemType) and it.is_int):
                    self.d.error(i.pos, "E0303", f"array index must be an integer, not {it}")
            if ot is ERROR_T:
                return ERROR_T
            if not isinstance(ot, ArrayType):
                self.d.error(e.pos, "E0306", f"indexing {_a(ot)}")
                return ERROR_T
            if len(e.indices) != len(ot.dims):
                self.d.error(e.pos, "E0307", f"{len(e.indices)} indices for a "
                             f"{len(ot.dims)}-dimensional array")
                return ERROR_T
            for i, (lo, hi) in zip(e.indices, ot.dims, strict=True):
                c = self.consts.get(i)
                if isinstance(c, int) and not lo <= c <= hi:
                    self.d.error(i.pos, "E0308", f"index {c} is outside {lo}..{hi}")
            return ot.element
        return ERROR_T

    def literal(self, e: A.Literal) -> Type:
        if e.kind == "enum":
            assert e.type_prefix is not None
            et = self.types.get(e.type_prefix.upper())
            if not isinstance(et, EnumType):
                self.d.error(e.pos, "E0200", f"'{e.type_prefix}' is not an enumerated type")
                return ERROR_T
            v = et.values.get(str(e.value).upper())
            if v is None:
                self.d.error(e.pos, "E0200", f"{et.name} has no value '{e.value}'")
                return ERROR_T
            self.names[e] = NameRef("enum", enum_value=v[1])
            return et
        if e.kind == "string":
            return STRING
        if e.type_prefix is not None:
            t = ELEMENTARY.get(e.type_prefix)
            if t is None:
                self.d.error(e.pos, "E0300", f"unknown literal type {e.type_prefix}")
                return ERROR_T
            base = self.literal(A.Literal(e.pos, e.kind, e.value, e.text))
            self.check_literal_fits(e, base, t)
            if isinstance(e.value, int | float) and not isinstance(e.value, bool):
                self.consts[e] = e.value
            return t
        if e.kind == "int":
            self.consts[e] = int(e.value)
            return INT_LIT
        if e.kind == "real":
            self.consts[e] = float(e.value)
            return REAL_LIT
        if e.kind == "bool":
            return BOOL
        if e.kind == "time":
            return TIME
        return ERROR_T

    def check_literal_fits(self, e: A.Expr, lit_t: Type, t: ElemType) -> None:
        if lit_t is INT_LIT and (t.is_int or t.is_bits):
            val = self.consts.get(e)
            if isinstance(e, A.Literal):
                val = int(e.value)
            if isinstance(val, int):
                lo, hi = t.int_range() if t.kind != "bool" else (0, 1)
                if t.kind == "bits" and val < 0:
                    lo = -(1 << (t.bits - 1))
                if not lo <= val <= hi:
                    self.d.error(e.pos, "E0304", f"{val} does not fit {t.name} "
                                 f"({lo}..{hi})")
        elif lit_t is REAL_LIT and t.is_real:
            pass
        elif lit_t is BOOL and t is BOOL:
            pass
        elif lit_t is INT_LIT and t.is_real:
            self.d.error(e.pos, "E0301", f"integer literal where {t.name} is needed: "
                         "MatIEC has no implicit conversion")
        else:
            self.d.error(e.pos, "E0300", f"{_a(lit_t)} cannot be {_a(t.name)}")

    def name(self, e: A.Name) -> Type:
        key = e.name.upper()
        if self.cur is not None:
            v = self.cur.vars.get(key)
            if v is not None:
                if v.kind == A.VAR_EXTERNAL:
                    g = self.globals.get(key)
                    self.names[e] = NameRef("global", g or v)
                    return v.type
                self.names[e] = NameRef("var", v)
                return v.type
            if self.cur.kind == "FUNCTION" and key == self.cur.key:
                rv = VarSym(self.cur.name, self.cur.return_type or ERROR_T, "RETURN", False,
                            e.pos)
                self.names[e] = NameRef("pou_result", rv)
                return rv.type
        ev = self.enum_values.get(key)
        if ev:
            if len(ev) > 1:
                self.d.error(e.pos, "E0200", f"'{e.name}' is a value of several enumerated "
                             f"types ({', '.join(t.name for t, _ in ev)}): write Type#{e.name}")
                return ERROR_T
            self.names[e] = NameRef("enum", enum_value=ev[0][1])
            return ev[0][0]
        if key in self.globals:
            self.d.error(e.pos, "E0200", f"'{e.name}' is a global: declare it VAR_EXTERNAL in "
                         "this POU")
            return ERROR_T
        self.d.error(e.pos, "E0200", f"'{e.name}' is not declared")
        return ERROR_T

    # ---------------------------------------------------------------- operators
    def unary(self, e: A.Unary, expected: Type | None) -> Type:
        if e.op == "-" and isinstance(e.operand, A.Literal) and e.operand.type_prefix is None \
                and e.operand.kind in ("int", "real"):
            t = self.expr(e.operand, expected)
            c = self.consts.get(e.operand)
            if c is not None:
                self.consts[e] = -c
            return t
        t = self.expr(e.operand, expected)
        if t is ERROR_T:
            return t
        if e.op == "NOT":
            if isinstance(t, LiteralType) or not (isinstance(t, ElemType) and t.is_bits):
                self.d.error(e.pos, "E0303", f"NOT needs BOOL or a bit string, not {t}")
                return ERROR_T
            return t
        if isinstance(t, LiteralType):
            c = self.consts.get(e.operand)
            if c is not None:
                self.consts[e] = -c if e.op == "-" else c
            return t
        if not (isinstance(t, ElemType) and (t.kind in ("sint", "real", "time"))):
            self.d.error(e.pos, "E0303", f"unary {e.op} needs a signed number, not {t}")
            return ERROR_T
        return t

    _ARITH = {"+", "-", "*", "/", "DIV", "MOD", "**"}
    _CMP = {"=", "<>", "<", "<=", ">", ">="}
    _LOGIC = {"AND", "OR", "XOR"}

    def binary(self, e: A.Binary, expected: Type | None) -> Type:
        """Types `a + b + c + ...` in a loop: its left spine is as deep as the chain is long."""
        spine: list[tuple[A.Binary, Type | None]] = []
        node: A.Expr = e
        while isinstance(node, A.Binary):
            sub_expected = expected if node.op in self._ARITH or node.op in self._LOGIC \
                else None
            spine.append((node, sub_expected))
            node, expected = node.left, sub_expected
        lt = self.expr(node, expected)
        for b, sub_expected in reversed(spine):
            rt = self.expr(b.right, sub_expected)
            lt = self.binary_node(b, lt, rt)
            if b is not e:
                self.expr_types[b] = lt
        return lt

    def binary_node(self, e: A.Binary, lt: Type, rt: Type) -> Type:
        op = "/" if e.op == "DIV" else e.op  # DIV: the call form's division (operator_call)
        if lt is ERROR_T or rt is ERROR_T:
            return ERROR_T
        if op == "**":
            self.d.error(e.pos, "E0106", "'**' passes MatIEC but OpenPLC's C build fails "
                         "(no __expt): write EXPT(x, 2.0) or x * x")
        if op in ("*", "/") and lt is TIME and (rt is INT_LIT or (isinstance(rt, ElemType)
                                                                and rt.is_int)):
            if rt is INT_LIT:
                self.coerce_to(e.right, rt, LINT, f"'{op}'")
            return TIME
        # settle untyped literals against the other side
        if isinstance(lt, LiteralType) and not isinstance(rt, LiteralType):
            self.coerce_to(e.left, lt, rt, f"'{op}'")
            lt = rt
        elif isinstance(rt, LiteralType) and not isinstance(lt, LiteralType):
            self.coerce_to(e.right, rt, lt, f"'{op}'")
            rt = lt
        if isinstance(lt, LiteralType) and isinstance(rt, LiteralType):
            if op in self._CMP:
                return BOOL
            self.fold(e)
            return REAL_LIT if (lt.is_real or rt.is_real) else INT_LIT
        if not same_type(lt, rt) and not (op in ("+", "-") and lt is TIME and rt is TIME):
            self.d.error(e.pos, "E0300", f"'{op}' between {lt} and {rt}: MatIEC has no "
                         "implicit conversion; convert one side explicitly")
            return ERROR_T
        if op in self._CMP:
            if isinstance(lt, ArrayType | StructType | PouType):
                self.d.error(e.pos, "E0303", f"'{op}' cannot compare {lt} values")
                return ERROR_T
            if isinstance(lt, EnumType) and op not in ("=", "<>"):
                self.d.error(e.pos, "E0303", f"'{op}' on enumerated values")
            return BOOL
        if not isinstance(lt, ElemType):
            self.d.error(e.pos, "E0303", f"'{op}' needs elementary operands, not {lt}")
            return ERROR_T
        if op in self._LOGIC:
            if not lt.is_bits:
                self.d.error(e.pos, "E0303", f"{op} needs BOOL or bit strings, not {lt}")
                return ERROR_T
            return lt
        if op == "MOD" and not lt.is_int:
            self.d.error(e.pos, "E0303", f"MOD needs integers, not {lt}")
            return ERROR_T
        if lt.kind == "time" and op in ("+", "-"):
            return lt
        if not lt.is_numeric:
            self.d.error(e.pos, "E0303", f"'{op}' needs numbers, not {lt}")
            return ERROR_T
        return lt

    def fold(self, e: A.Binary) -> None:
        a, b = self.consts.get(e.left), self.consts.get(e.right)
        if a is None or b is None:
            return
        try:
            if e.op == "+":
                r: int | float = a + b
            elif e.op == "-":
                r = a - b
            elif e.op == "*":
                r = a * b
            elif e.op == "/":
                if isinstance(a, int) and isinstance(b, int):
                    q = abs(a) // abs(b)
                    r = q if (a >= 0) == (b >= 0) else -q
                else:
                    r = a / b
            elif e.op == "MOD" and isinstance(a, int) and isinstance(b, int):
                r = 0 if b == 0 else abs(a) % abs(b) * (1 if a >= 0 else -1)
            else:
                return
        except ZeroDivisionError:
            self.d.error(e.pos, "E0304", "division by zero in a constant expression")
            return
        self.consts[e] = r

    def coerce_to(self, e: A.Expr, t: Type, target: Type, what: str) -> None:
        """Check that a value of type t may go where target is needed; settle literals."""
        if t is ERROR_T or target is ERROR_T:
            return
        if isinstance(t, LiteralType):
            if isinstance(target, ElemType):
                self.check_literal_fits(e, t, target)
                self.settle(e, target)
            elif isinstance(target, LiteralType):
                return
            else:
                self.d.error(e.pos, "E0300", f"{what}: {_a(t)} cannot be {_a(target)}")
            return
        if same_type(t, target):
            return
        self.d.error(e.pos, "E0300", f"{what}: {t} where {target} is needed; MatIEC has no "
                     "implicit conversion (use an explicit *_TO_* conversion)")

    def settle(self, e: A.Expr, target: ElemType) -> None:
        """Give untyped literal sub-expressions their context type (for C emission)."""
        stack = [e]
        while stack:
            x = stack.pop()
            if not isinstance(self.expr_types.get(x), LiteralType):
                continue
            self.expr_types[x] = target
            if isinstance(x, A.Unary):
                stack.append(x.operand)
            elif isinstance(x, A.Binary) and x.op not in self._CMP:
                stack += (x.right, x.left)

    # ---------------------------------------------------------------- calls
    def call(self, c: A.Call, statement: bool, expected: Type | None = None) -> Type:
        """A call; its implicit EN input and ENO output (any function, FB or standard function
        takes them, by name) are taken off the argument list and kept on its CallTarget."""
        en = eno = None
        if any(a.name is not None and a.name.upper() in ("EN", "ENO") for a in c.args):
            rest: list[A.Arg] = []
            for a in c.args:
                n = a.name.upper() if a.name is not None else ""
                if n == "EN" and not a.is_output:
                    en = a.value
                elif n == "ENO" and a.is_output:
                    eno = a.value
                else:
                    rest.append(a)
            c.args = rest
        t = self._call(c, statement, expected)
        if en is None and eno is None:
            return t
        if en is not None:
            self.coerce_to(en, self.expr(en, BOOL), BOOL, "EN")
        if eno is not None:
            self.coerce_to(eno, BOOL, self.lvalue(eno), "ENO")
        tgt = self.calls.get(c)
        if tgt is not None:
            self.calls[c] = replace(tgt, en=en, eno=eno)
        return t

    def _call(self, c: A.Call, statement: bool, expected: Type | None = None) -> Type:
        if not isinstance(c.callee, A.Name):
            if self.expr(c.callee, None) is not ERROR_T:
                self.d.error(c.pos, "E0400", "only named POUs and FB instances can be called")
            return ERROR_T
        name = c.callee.name
        key = name.upper()
        named = [a for a in c.args if a.name is not None]
        if named and len(named) != len(c.args):
            self.d.error(c.pos, "E0402", f"call of {name} mixes named and positional "
                         "arguments (MatIEC rejects this)")
            for a in c.args:
                self.expr(a.value, None)
            return ERROR_T
        # FB instance call?
        inst_t: Type | None = None
        if self.cur is not None and key in self.cur.vars:
            inst_t = self.cur.vars[key].type
            self.expr(c.callee, None)
        if isinstance(inst_t, PouType):
            sym = inst_t.symbol
            assert isinstance(sym, PouSym)
            if not statement:
                self.d.error(c.pos, "E0400", f"FB instance {name} is called as a statement, "
                             "not inside an expression")
            return self.bind(c, sym, "fb", ERROR_T)
        if inst_t is not None:
            self.d.error(c.pos, "E0400", f"'{name}' is {_a(inst_t)}, not a FUNCTION or FB "
                         "instance")
            return ERROR_T
        if statement:
            self.d.error(c.pos, "E0403", f"FUNCTION {name} is called as a statement: MatIEC "
                         "rejects this; assign its result")
        if not c.args:
            self.d.error(c.pos, "E0401", f"{name}() without arguments: MatIEC rejects calls "
                         "with no argument, even with defaults")
            if key not in self.pous and key not in STD_FUNCS and key not in CONVERSIONS:
                return ERROR_T
        if key in CONVERSIONS:
            src, dst = CONVERSIONS[key]
            if len(c.args) != 1:
                self.d.error(c.pos, "E0400", f"{name} takes one argument")
                return ERROR_T
            at = self.expr(c.args[0].value, src)
            self.coerce_to(c.args[0].value, at, src, f"argument of {name}")
            self.calls[c] = CallTarget("conv", conv=(src, dst),
                                       inputs=(("IN", c.args[0].value),))
            return dst
        if key in STD_FUNCS:
            return self.std.check(c, STD_FUNCS[key], expected)
        if key in CALL_FORM_OPERATORS and key not in self.pous:
            return self.operator_call(c, key, expected)
        sym = self.pous.get(key)
        if sym is None:
            if key == "ATAN2":
                self.d.error(c.pos, "E0400", "ATAN2 is not an IEC standard function: MatIEC "
                             "has none (use the library's ArcTan2)")
            else:
                self.d.error(c.pos, "E0400", f"'{name}' is not a FUNCTION")
            for a in c.args:
                self.expr(a.value, None)
            return ERROR_T
        if sym.kind != "FUNCTION":
            self.d.error(c.pos, "E0400", f"{sym.kind.replace('_', ' ')} {sym.name} must be "
                         "called through an instance")
            return ERROR_T
        if self.cur is not None:
            self.call_graph.setdefault(self.cur.key, set()).add(key)
            self.call_sites.setdefault((self.cur.key, key), c.pos)
            self.check_struct_return_call(c, sym)
        return self.bind(c, sym, "function", sym.return_type or ERROR_T)

    def operator_call(self, c: A.Call, key: str, expected: Type | None) -> Type:
        """ADD(a, b, c), GT(IN1 := a, IN2 := b), MULTIME(t, 3), ...: typed and computed as the
        operator expression (a + b + c; a > b AND b > c for the extensible comparisons), as
        MatIEC's standard library declares them. DIV is `/` except that a zero divisor gives
        0, as MatIEC's DIV function does (the operator `/` traps)."""
        op, least, most = CALL_FORM_OPERATORS[key]
        args: list[A.Expr] = []
        if c.args and c.args[0].name is not None:
            by_index: dict[int, A.Expr] = {}
            for a in c.args:
                assert a.name is not None
                n = a.name.upper()
                if not (n.startswith("IN") and n[2:].isdigit()) or a.is_output:
                    self.d.error(a.pos, "E0407", f"{key} has no parameter '{a.name}' (it "
                                 "takes IN1, IN2" + (", ..." if not most else "") + ")")
                    return ERROR_T
                by_index[int(n[2:])] = a.value
            if sorted(by_index) != list(range(1, len(by_index) + 1)):
                self.d.error(c.pos, "E0409", f"{key} needs IN1, IN2, ... without gaps")
                return ERROR_T
            args = [by_index[i] for i in sorted(by_index)]
        else:
            args = [a.value for a in c.args]
        if len(args) < least or (most and len(args) > most):
            self.d.error(c.pos, "E0400", f"{key} takes " + (f"{least}" if most == least else
                         f"at least {least}") + f" arguments, {len(args)} given")
            return ERROR_T
        tree: A.Expr
        if op in self._CMP and len(args) > 2:
            pairs: list[A.Expr] = [A.Binary(c.pos, op, args[i], args[i + 1])
                                   for i in range(len(args) - 1)]
            tree = pairs[0]
            for p in pairs[1:]:
                tree = A.Binary(c.pos, "AND", tree, p)
        else:
            tree = args[0]
            for x in args[1:]:
                tree = A.Binary(c.pos, "DIV" if key == "DIV" else op, tree, x)
        t = self.expr(tree, expected)
        if key in ("ADD_TIME", "SUB_TIME", "MULTIME", "DIVTIME") and t is not ERROR_T and \
                t is not TIME:
            self.d.error(c.pos, "E0300", f"{key} computes on TIME, not {t}")
            return ERROR_T
        self.calls[c] = CallTarget("alias", inputs=tuple((f"IN{i + 1}", x)
                                                         for i, x in enumerate(args)),
                                   alias=tree)
        return t

    def check_struct_return_call(self, c: A.Call, sym: PouSym) -> None:
        # iec2c accepts this call, but in a FUNCTION_BLOCK or PROGRAM body it wraps it in a
        # C helper whose return type it spells from the STRUCT's field list, which g++ then
        # rejects; inside a FUNCTION the call compiles (measured on OpenPLC v3 @ bb35f69).
        assert self.cur is not None
        if self.cur.kind == "FUNCTION" or not isinstance(sym.return_type, StructType):
            return
        outs = [p.name for p in sym.params() if p.kind in (A.VAR_OUTPUT, A.VAR_IN_OUT)]
        if outs:
            where = self.cur.kind.replace("_", " ")
            self.d.error(c.pos, "E0410", f"{sym.name} returns the STRUCT "
                         f"{sym.return_type.name} and has VAR_OUTPUT/VAR_IN_OUT '{outs[0]}': "
                         f"OpenPLC's C build fails on such a call in a {where} (it compiles "
                         "only inside a FUNCTION)")

    def bind(self, c: A.Call, sym: PouSym, kind: str, result: Type) -> Type:
        params = sym.params()
        inputs: list[tuple[str, A.Expr]] = []
        outputs: list[tuple[str, A.Expr]] = []
        if c.args and c.args[0].name is None:
            formal = [p for p in params if p.kind != A.VAR_OUTPUT] if kind == "fb" else params
            if kind == "function":
                formal = [p for p in params if p.kind != A.VAR_OUTPUT]
            if len(c.args) > len(formal):
                self.d.error(c.pos, "E0400", f"{sym.name} takes {len(formal)} inputs, "
                             f"{len(c.args)} given")
                return ERROR_T
            pairs = list(zip(formal, c.args, strict=False))
        else:
            pairs = []
            for a in c.args:
                assert a.name is not None
                p = sym.vars.get(a.name.upper())
                if p is None or p.kind not in (A.VAR_INPUT, A.VAR_OUTPUT, A.VAR_IN_OUT):
                    self.d.error(a.pos, "E0407", f"{sym.name} has no parameter '{a.name}'")
                    self.expr(a.value, None)
                    continue
                if a.is_output != (p.kind == A.VAR_OUTPUT):
                    self.d.error(a.pos, "E0407", f"'{a.name}' of {sym.name} is a "
                                 f"{p.kind}: use {'=>' if p.kind == A.VAR_OUTPUT else ':='}")
                    continue
                pairs.append((p, a))
        seen: set[str] = set()
        for p, a in pairs:
            if p.key in seen:
                self.d.error(a.pos, "E0407", f"'{p.name}' given twice")
                continue
            seen.add(p.key)
            if p.kind == A.VAR_OUTPUT:
                tt = self.lvalue(a.value)
                self.coerce_to(a.value, p.type, tt, f"output {p.name} of {sym.name}")
                outputs.append((p.key, a.value))
            elif p.kind == A.VAR_IN_OUT:
                tt = self.lvalue(a.value)
                if tt is not ERROR_T and not same_type(tt, p.type):
                    self.d.error(a.value.pos, "E0300", f"VAR_IN_OUT {p.name} of {sym.name} "
                                 f"is {p.type}, the argument is {tt}")
                inputs.append((p.key, a.value))
            else:
                at = self.expr(a.value, p.type)
                self.coerce_to(a.value, at, p.type, f"input {p.name} of {sym.name}")
                inputs.append((p.key, a.value))
        if kind == "function":
            for p in params:
                if p.kind == A.VAR_IN_OUT and p.key not in seen:
                    self.d.error(c.pos, "E0409", f"VAR_IN_OUT {p.name} of {sym.name} must be "
                                 "passed")
        self.calls[c] = CallTarget(kind, pou=sym, inputs=tuple(inputs), outputs=tuple(outputs))
        return result

    # ---------------------------------------------------------------- whole program
    def check_recursion(self) -> None:
        """Report each call cycle once, at the call that closes it (depth first, no recursion:
        a chain of thousands of FUNCTIONs each calling the next is legal)."""
        state: dict[str, int] = {}  # 1 = on the current path, 2 = done
        for root in self.call_graph:
            if root in state:
                continue
            state[root] = 1
            path = [root]
            pending = [iter(sorted(self.call_graph.get(root, ())))]
            while path:
                k = path[-1]
                callee = next(pending[-1], None)
                if callee is None:
                    state[k] = 2
                    path.pop()
                    pending.pop()
                elif state.get(callee) == 1:
                    cycle = path[path.index(callee):] + [callee]
                    names = " -> ".join(self.pous[n].name for n in cycle)
                    self.d.error(self.call_sites[(k, callee)], "E0209",
                                 f"recursive call cycle {names}: IEC 61131-3 and MatIEC "
                                 "forbid recursion")
                elif state.get(callee) is None:
                    state[callee] = 1
                    path.append(callee)
                    pending.append(iter(sorted(self.call_graph.get(callee, ()))))

    def ordered_pous(self) -> Iterable[tuple[str, PouSym]]:
        """Callees and instance types before their users, so C declarations come first."""
        done: set[str] = set()
        out: list[tuple[str, PouSym]] = []

        def deps(p: PouSym) -> Iterator[PouSym]:
            d = set(self.call_graph.get(p.key, ()))
            for v in p.vars.values():
                if isinstance(v.type, PouType) and not v.type.symbol.builtin:  # type: ignore
                    d.add(v.type.name.upper())
            for k in sorted(d):
                dp = self.pous.get(k)
                if dp is not None and not dp.builtin:
                    yield dp

        for root in self.user_pous():
            if root.key in done:
                continue
            on_path = {root.key}
            path = [root]
            pending = [deps(root)]
            while path:
                dp = next(pending[-1], None)
                if dp is None:
                    p = path.pop()
                    pending.pop()
                    if p.key not in done:
                        done.add(p.key)
                        out.append((p.key, p))
                elif dp.key not in done and dp.key not in on_path:
                    on_path.add(dp.key)
                    path.append(dp)
                    pending.append(deps(dp))
        return out


def _a(t: object) -> str:
    """'a REAL', 'an INT': the article for a type name in a message."""
    name = str(t)
    return f"an {name}" if name[:1].upper() in "AEIOU" else f"a {name}"


def check(units: list[A.SourceUnit], diags: Diagnostics) -> CheckedProgram:
    return Checker(units, diags).run()
