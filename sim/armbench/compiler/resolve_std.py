"""Typing of calls to the IEC standard functions (ABS, SQRT, MIN, LIMIT, SEL, MUX, SHL, ...).

Needs: an expression checker (resolve.py's Checker), whose expression typing and literal
settling it uses through the ExprChecker protocol below, not by importing it. Each
function kind of stdlib.StdFunc has its rule here, as MatIEC applies it: generic arguments
unify to one type, untyped literals take it, integers never become REAL.
"""

from __future__ import annotations

from typing import Protocol

from . import ast as A
from .diagnostics import Diagnostics
from .stdlib import StdFunc
from .symbols import CallTarget
from .types import (
    BOOL,
    DINT,
    ERROR_T,
    INT_LIT,
    LREAL,
    REAL_LIT,
    STRING,
    ElemType,
    LiteralType,
    Type,
)

# arguments of the string functions: S a STRING, N an integer (a position or a length)
_STR_SIGNATURES = {"LEN": "S", "LEFT": "SN", "RIGHT": "SN", "MID": "SNN", "DELETE": "SNN",
                   "INSERT": "SSN", "REPLACE": "SSNN", "FIND": "SS"}


class ExprChecker(Protocol):
    """What the standard-call rules need of the checker that owns them."""

    d: Diagnostics
    calls: dict[A.Call, CallTarget]

    def expr(self, e: A.Expr, expected: Type | None) -> Type: ...

    def coerce_to(self, e: A.Expr, t: Type, target: Type, what: str) -> None: ...


def numbered(f: StdFunc, args: list[A.Expr]) -> CallTarget:
    """The call target of a function whose inputs are IN0, IN1, ... in order."""
    return CallTarget("std", std=f, inputs=tuple((f"IN{i}", a) for i, a in enumerate(args)))


class StdCallTyper:
    def __init__(self, checker: ExprChecker) -> None:
        self.k = checker

    def check(self, c: A.Call, f: StdFunc, expected: Type | None) -> Type:
        args = self.order_args(c, f)
        if args is None:
            return ERROR_T
        types: list[Type] = []
        for a in args:  # a loop, not a comprehension: one frame less per nested call
            types.append(self.k.expr(a, None))
        if any(t is ERROR_T for t in types):
            return ERROR_T
        k = f.kind

        def need(n: int) -> bool:
            if len(args) != n:
                self.k.d.error(c.pos, "E0400", f"{f.name} takes {n} argument(s), {len(args)} "
                             "given")
                return False
            return True

        def unify(exprs: list[A.Expr], ts: list[Type], pref: Type | None) -> Type:
            concrete = [t for t in ts if not isinstance(t, LiteralType)]
            if concrete:
                anchor: Type = concrete[0]
            elif isinstance(pref, ElemType) and pref.is_numeric:
                anchor = pref
            else:
                anchor = LREAL if any(t is REAL_LIT for t in ts) else DINT
            for ex, t in zip(exprs, ts, strict=True):
                self.k.coerce_to(ex, t, anchor, f"argument of {f.name}")
            return anchor

        if k.startswith("str_"):
            return self.string_call(c, f, args, types, expected)
        if k in ("same_n", "limit") and any(t is STRING for t in types):
            self.k.d.error(c.pos, "E0105", f"unsupported construct: {f.name} of STRINGs (the "
                           "bench does not model MatIEC's prefix-only STRING ordering here; "
                           "compare with < and choose with SEL)")
            return ERROR_T
        if k in ("real1", "num1", "bits1", "trunc", "move"):
            if not need(1):
                return ERROR_T
            t = types[0]
            if k == "real1" or k == "trunc":
                if isinstance(t, LiteralType):
                    if t is INT_LIT:
                        self.k.d.error(args[0].pos, "E0301", f"{f.name} needs REAL or LREAL: "
                                     "write a real literal (MatIEC rejects SQRT(2))")
                        return ERROR_T
                    t = expected if isinstance(expected, ElemType) and expected.is_real \
                        else REAL_LIT
                    if t is not REAL_LIT:
                        self.k.coerce_to(args[0], REAL_LIT, t, f.name)
                if t is not REAL_LIT and not (isinstance(t, ElemType) and t.is_real):
                    self.k.d.error(args[0].pos, "E0300", f"{f.name} needs REAL or LREAL, not "
                                 f"{t}")
                    return ERROR_T
                self.k.calls[c] = CallTarget("std", std=f, inputs=(("IN", args[0]),))
                if k == "trunc":
                    if isinstance(expected, ElemType) and expected.is_int:
                        return expected
                    return DINT
                return t
            if k == "num1" and not (isinstance(t, LiteralType) or
                                    (isinstance(t, ElemType) and t.is_numeric)):
                self.k.d.error(args[0].pos, "E0300", f"ABS needs a number, not {t}")
                return ERROR_T
            if k == "bits1" and not (isinstance(t, ElemType) and t.is_bits):
                self.k.d.error(args[0].pos, "E0300", f"NOT needs BOOL or bits, not {t}")
                return ERROR_T
            t = unify(args, types, expected)
            self.k.calls[c] = CallTarget("std", std=f, inputs=(("IN", args[0]),))
            return t
        if k == "expt":
            if not need(2):
                return ERROR_T
            t0 = types[0]
            if t0 is INT_LIT or (isinstance(t0, ElemType) and not t0.is_real):
                self.k.d.error(args[0].pos, "E0300", f"EXPT needs a REAL or LREAL base, not {t0}")
                return ERROR_T
            if isinstance(t0, LiteralType):
                t0 = expected if isinstance(expected, ElemType) and expected.is_real else LREAL
                self.k.coerce_to(args[0], REAL_LIT, t0, "EXPT")
            t1 = types[1]
            if isinstance(t1, LiteralType):
                t1 = t0 if t1 is REAL_LIT else DINT
                self.k.coerce_to(args[1], types[1], t1, "EXPT")
            elif not (isinstance(t1, ElemType) and t1.is_numeric):
                self.k.d.error(args[1].pos, "E0300", f"EXPT exponent must be a number, not {t1}")
                return ERROR_T
            self.k.calls[c] = CallTarget("std", std=f, inputs=(("IN1", args[0]),
                                                            ("IN2", args[1])))
            return t0
        if k in ("same_n", "limit", "int2", "bits_n"):
            if k == "limit" and not need(3):
                return ERROR_T
            if k == "int2" and not need(2):
                return ERROR_T
            if len(args) < 2:
                self.k.d.error(c.pos, "E0400", f"{f.name} needs at least 2 arguments")
                return ERROR_T
            t = unify(args, types, expected)
            if k == "int2" and not (isinstance(t, ElemType) and t.is_int):
                self.k.d.error(c.pos, "E0300", f"{f.name} needs integers, not {t}")
            if k == "bits_n" and not (isinstance(t, ElemType) and t.is_bits):
                self.k.d.error(c.pos, "E0300", f"{f.name} needs BOOL or bits, not {t}")
            elif f.name == "XOR" and isinstance(t, ElemType) and t.kind == "bits":
                self.k.d.error(c.pos, "E0105", f"unsupported construct: XOR(...) of {t} in "
                               "call form: OpenPLC's C build fails (MatIEC calls "
                               f"XOR__{t}__{t}, which its library lacks); write a XOR b")
            if not isinstance(t, ElemType):
                self.k.d.error(c.pos, "E0300", f"{f.name} needs elementary arguments, not {t}")
                return ERROR_T
            self.k.calls[c] = numbered(f, args)
            return t
        if k == "sel":
            if not need(3):
                return ERROR_T
            self.k.coerce_to(args[0], types[0], BOOL, "SEL selector")
            t = unify(args[1:], types[1:], expected)
            self.k.calls[c] = numbered(f, args)
            return t
        if k == "mux":
            if len(args) < 2:
                self.k.d.error(c.pos, "E0400", "MUX needs a selector and inputs")
                return ERROR_T
            kt = types[0]
            if isinstance(kt, LiteralType):
                self.k.coerce_to(args[0], kt, DINT, "MUX selector")
            elif not (isinstance(kt, ElemType) and kt.is_int):
                self.k.d.error(args[0].pos, "E0300", f"MUX selector must be an integer, not {kt}")
            t = unify(args[1:], types[1:], expected)
            self.k.calls[c] = numbered(f, args)
            return t
        if k == "shift":
            if not need(2):
                return ERROR_T
            t0 = types[0]
            if not (isinstance(t0, ElemType) and t0.kind == "bits"):
                self.k.d.error(args[0].pos, "E0300", f"{f.name} needs a bit string (BYTE, WORD, "
                             f"DWORD, LWORD), not {t0}")
                return ERROR_T
            t1 = types[1]
            if isinstance(t1, LiteralType):
                self.k.coerce_to(args[1], t1, DINT if t1 is INT_LIT else t1, f.name)
            elif not (isinstance(t1, ElemType) and t1.is_int):
                self.k.d.error(args[1].pos, "E0300", f"{f.name} shift count must be an integer")
            self.k.calls[c] = CallTarget("std", std=f, inputs=(("IN", args[0]), ("N", args[1])))
            return t0
        return ERROR_T

    def string_call(self, c: A.Call, f: StdFunc, args: list[A.Expr], types: list[Type],
                    expected: Type | None) -> Type:
        """LEN, LEFT, RIGHT, MID, CONCAT, INSERT, DELETE, REPLACE, FIND: STRING arguments,
        integer lengths and positions (any integer type, literals as DINT); LEN and FIND
        return the integer type the context wants, as MatIEC's overloads do."""
        if f.kind == "str_concat":
            if len(args) < 2:
                self.k.d.error(c.pos, "E0400", "CONCAT needs at least 2 arguments")
                return ERROR_T
            sig = "S" * len(args)
        else:
            sig = _STR_SIGNATURES[f.name]
            if len(args) != len(sig):
                self.k.d.error(c.pos, "E0400", f"{f.name} takes {len(sig)} argument(s) "
                               f"({', '.join(f.params)}), {len(args)} given")
                return ERROR_T
        ok = True
        for a, t, want in zip(args, types, sig, strict=True):
            if want == "S":
                self.k.coerce_to(a, t, STRING, f"argument of {f.name}")
                ok = ok and (t is STRING)
            elif t is INT_LIT:
                self.k.coerce_to(a, t, DINT, f"argument of {f.name}")
            elif not (isinstance(t, ElemType) and t.is_int):
                self.k.d.error(a.pos, "E0300", f"{f.name} needs an integer length or position, "
                               f"not {t}")
                ok = False
        if not ok:
            return ERROR_T
        if f.kind == "str_concat":
            self.k.calls[c] = numbered(f, args)
        else:
            self.k.calls[c] = CallTarget("std", std=f, inputs=tuple(zip(f.params, args,
                                                                         strict=True)))
        if f.kind in ("str_len", "str_find"):
            return expected if isinstance(expected, ElemType) and expected.is_int else INT_LIT
        return STRING

    def order_args(self, c: A.Call, f: StdFunc) -> list[A.Expr] | None:
        if not c.args or c.args[0].name is None:
            return [a.value for a in c.args]
        if "*" in f.params:
            out: dict[int, A.Expr] = {}
            for a in c.args:
                assert a.name is not None
                n = a.name.upper()
                if n == "K" and f.name == "MUX":
                    out[-1] = a.value
                elif n.startswith("IN") and n[2:].isdigit():
                    out[int(n[2:])] = a.value
                else:
                    self.k.d.error(a.pos, "E0407", f"{f.name} has no parameter '{a.name}'")
                    return None
            return [out[k] for k in sorted(out)]
        by_name = {p: i for i, p in enumerate(f.params)}
        vals: list[A.Expr | None] = [None] * len(f.params)
        for a in c.args:
            assert a.name is not None
            i = by_name.get(a.name.upper())
            if i is None:
                self.k.d.error(a.pos, "E0407", f"{f.name} has no parameter '{a.name}' "
                             f"(it takes {', '.join(f.params)})")
                return None
            vals[i] = a.value
        if any(v is None for v in vals):
            self.k.d.error(c.pos, "E0409", f"{f.name} needs all of {', '.join(f.params)}")
            return None
        return [v for v in vals if v is not None]
