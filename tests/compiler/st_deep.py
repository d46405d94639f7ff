"""Generators of deeply nested and very long ST programs (the depth and size fuzz inputs).

`program(construct, n)` returns a complete, valid ST file in which `construct` is nested (or,
for the chains, repeated) n times. Every file is well typed, so below the nesting limit
`armbench check` must accept it and above it must answer with diagnostics.
"""

from __future__ import annotations

import random
from collections.abc import Callable

from armbench.compiler.diagnostics import Diagnostic
from armbench.compiler.strucpp import STRUCPP_CODES
from armbench.compiler.targets import CODESYS, OPENPLC, Target

# The nesting limits are MatIEC's: the constructs are checked for OpenPLC v3 and CODESYS, and
# what STruC++ refuses in some of them (T#-1s, arrays of 3 and more dimensions, a FUNCTION
# named Inc like OSCAT's; its rules' business, test_strucpp_verdicts.py) is a warning, left out by
# matiec_view, so that the program is still checked and emitted.
LIMITS_TARGET = Target(frozenset({OPENPLC, CODESYS}))


def matiec_view(diags: list[Diagnostic]) -> list[Diagnostic]:
    return [d for d in diags if d.code not in STRUCPP_CODES]

CONFIG = """
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""

_INC = """FUNCTION Inc : DINT
VAR_INPUT
  a : DINT;
END_VAR
  Inc := a + 1;
END_FUNCTION
"""


def _main(body: str, decls: str = "", before: str = "") -> str:
    return (f"{before}\nPROGRAM Main\nVAR\n  x : DINT;\n  b : BOOL;\n  i : INT;\n"
            f"  a : ARRAY[0..9] OF DINT;\n{decls}END_VAR\n{body}\nEND_PROGRAM\n{CONFIG}")


def _wrap(n: int, open_: str, close: str, inner: str) -> str:
    return open_ * n + inner + close * n


def _if(n: int) -> str:
    return _main(_wrap(n, "IF b THEN\n", "END_IF;\n", "x := 1;\n"))


def _elsif(n: int) -> str:  # long, not deep: one IF with n ELSIF branches
    return _main("IF b THEN x := 0;\n" + "".join(f"ELSIF x = {k} THEN x := {k + 1};\n"
                                                   for k in range(n)) + "END_IF;")


def _case(n: int) -> str:
    return _main(_wrap(n, "CASE x OF 1:\n", "ELSE x := 2;\nEND_CASE;\n", "x := 1;\n"))


def _case_long(n: int) -> str:
    return _main("CASE x OF\n" + "".join(f"{k}: x := {k};\n" for k in range(n)) + "END_CASE;")


def _for(n: int) -> str:  # one control variable per loop: MatIEC rejects nested FORs sharing one
    body = "".join(f"FOR i{k} := 1 TO 2 DO\n" for k in range(n)) + "x := x + 1;\n" + \
        "END_FOR;\n" * n
    return _main(body, decls="".join(f"  i{k} : INT;\n" for k in range(n)))


def _while(n: int) -> str:
    return _main(_wrap(n, "WHILE b DO\n", "END_WHILE;\n", "b := FALSE;\n"))


def _repeat(n: int) -> str:
    return _main(_wrap(n, "REPEAT\n", "UNTIL b END_REPEAT;\n", "b := TRUE;\n"))


def _paren(n: int) -> str:
    return _main("x := " + _wrap(n, "(", ")", "x") + ";")


def _paren_time(n: int) -> str:  # a literal of 7 stack entries where a name takes 1
    return _main("t := " + _wrap(n, "(", ")", "T#1s") + ";", decls="  t : TIME;\n")


def _paren_neg_time(n: int) -> str:  # a signed duration: 8 entries
    return _main("t := " + _wrap(n, "(", ")", "T#-1s") + ";", decls="  t : TIME;\n")


def _paren_sum(n: int) -> str:  # a + (a + (a + ...)): nested to the right
    return _main("x := " + "(x + " * n + "x" + ")" * n + ";")


def _neg(n: int) -> str:
    return _main("x := " + _wrap(n, "-(", ")", "x") + ";")


def _not(n: int) -> str:  # NOT NOT b is a syntax error in MatIEC: NOT (NOT (b))
    return _main("b := " + _wrap(n, "NOT (", ")", "b") + ";")


def _sum(n: int) -> str:
    return _main("x := " + " + ".join(["x"] * n) + ";")


def _mixed_chain(n: int) -> str:  # long chains of every operator class, flat
    ops = ["+", "-", "*", "/", "MOD"]
    terms = "x"
    for k in range(n):
        terms += f" {ops[k % len(ops)]} {k % 7 + 1}"
    return _main(f"x := {terms};\nb := " + " AND ".join(["b"] * n) + ";\nb := " +
                 " OR ".join(["x > 1"] * n) + ";")


def _const_sum(n: int) -> str:  # a constant initial value folded by the checker
    return _main("x := x + 1;", decls="  k : DINT := " + " + ".join(["1"] * n) + ";\n")


def _real_sum(n: int) -> str:
    return _main("acc := " + " + ".join(["acc"] * n) + ";", decls="  acc : REAL;\n")


def _calls(n: int) -> str:
    return _main("x := " + _wrap(n, "Inc(", ")", "x") + ";", before=_INC)


def _std_calls(n: int) -> str:
    return _main("x := " + _wrap(n, "ABS(", ")", "x") + ";")


def _max_calls(n: int) -> str:
    return _main("x := " + _wrap(n, "MAX(x, ", ")", "x") + ";")


def _conversions(n: int) -> str:
    return _main("x := " + _wrap(n, "INT_TO_DINT(DINT_TO_INT(", "))", "x") + ";")


def _index(n: int) -> str:
    return _main("x := " + _wrap(n, "a[", "]", "0") + ";")


def _struct_fields(n: int) -> str:
    # innermost first: MatIEC rejects a TYPE naming a later type (E0212)
    types = f"TYPE\n  Lvl{n} : STRUCT\n    v : DINT;\n  END_STRUCT;\n" + "".join(
        f"  Lvl{k} : STRUCT\n    f : Lvl{k + 1};\n  END_STRUCT;\n"
        for k in range(n - 1, -1, -1)) + "END_TYPE\n"
    return _main("x := top" + ".f" * n + ".v;", decls="  top : Lvl0;\n", before=types)


def _struct_arrays(n: int) -> str:
    types = f"TYPE\n  Lvl{n} : STRUCT\n    v : DINT;\n  END_STRUCT;\n" + "".join(
        f"  Lvl{k} : STRUCT\n    f : ARRAY[0..1] OF Lvl{k + 1};\n  END_STRUCT;\n"
        for k in range(n - 1, -1, -1)) + "END_TYPE\n"
    return _main("x := top" + ".f[1]" * n + ".v;", decls="  top : Lvl0;\n", before=types)


def _fb_chain(n: int) -> str:
    fbs = "".join(f"FUNCTION_BLOCK Fb{k}\nVAR\n  inner : Fb{k + 1};\nEND_VAR\n  inner();\n"
                  "END_FUNCTION_BLOCK\n" for k in range(n))
    fbs += (f"FUNCTION_BLOCK Fb{n}\nVAR_OUTPUT\n  v : DINT;\nEND_VAR\n  v := 1;\n"
            "END_FUNCTION_BLOCK\n")
    return _main("f();\nx := f" + ".inner" * n + ".v;", decls="  f : Fb0;\n", before=fbs)


def _function_chain(n: int) -> str:  # F0 calls F1 calls ... F(n): deep call graph, flat code
    fns = "".join(f"FUNCTION F{k} : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n"
                  f"  F{k} := F{k + 1}(a);\nEND_FUNCTION\n" for k in range(n))
    fns += f"FUNCTION F{n} : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n  F{n} := a;\nEND_FUNCTION\n"
    return _main("x := F0(x);", before=fns)


def _alias_chain(n: int) -> str:
    types = f"TYPE\n  T{n} : DINT;\n" + "".join(f"  T{k} : T{k + 1};\n"
                                              for k in range(n - 1, -1, -1)) + "END_TYPE\n"
    return _main("t := 1;\nx := t;", decls="  t : T0;\n", before=types)


def _init_paren(n: int) -> str:
    return _main("x := x + 1;", decls="  k : DINT := " + _wrap(n, "(", ")", "1") + ";\n")


def _dims(n: int) -> str:  # dimensions are a list, not nesting
    return _main(f"x := m[{', '.join(['x'] * n)}];",
                 decls=f"  m : ARRAY[{', '.join(['0..0'] * n)}] OF DINT;\n")


CONSTRUCTS: dict[str, Callable[[int], str]] = {
    "if": _if, "elsif": _elsif, "case": _case, "case_long": _case_long, "for": _for,
    "while": _while, "repeat": _repeat, "paren": _paren, "paren_time": _paren_time,
    "paren_neg_time": _paren_neg_time, "paren_sum": _paren_sum, "neg": _neg,
    "not": _not, "sum": _sum, "mixed_chain": _mixed_chain, "const_sum": _const_sum,
    "real_sum": _real_sum, "calls": _calls, "std_calls": _std_calls, "max_calls": _max_calls,
    "conversions": _conversions, "index": _index, "struct_fields": _struct_fields,
    "struct_arrays": _struct_arrays, "fb_chain": _fb_chain, "function_chain": _function_chain,
    "alias_chain": _alias_chain, "init_paren": _init_paren, "dims": _dims,
}

# Long but flat: every size must be accepted, never rejected as too deep.
FLAT = {"elsif", "case_long", "sum", "mixed_chain", "const_sum", "real_sum", "function_chain",
        "alias_chain", "dims"}
# Levels of nesting one step of a construct adds, where it is not one (the bench's own limit).
LEVELS_PER_STEP = {"paren_sum": 2, "conversions": 2, "struct_arrays": 2}
# The largest n for which OpenPLC's iec2c accepts program(construct, n), measured by binary
# search (n + 1 is a syntax error: its bison stack holds 200 entries). The checker must agree.
MATIEC_MAX = {"if": 63, "case": 38, "for": 26, "while": 63, "repeat": 189, "paren": 189,
              "paren_time": 184, "paren_neg_time": 183,
              "paren_sum": 63, "neg": 94, "not": 94, "calls": 94, "std_calls": 94,
              "max_calls": 47, "conversions": 47, "index": 94}


def program(construct: str, n: int) -> str:
    return CONSTRUCTS[construct](n)


_EXPR_WRAPS = [("(", ")"), ("-(", ")"), ("Inc(", ")"), ("ABS(", ")"), ("a[", "]"),
               ("x + (", ")"), ("MAX(x, ", ")"), ("INT_TO_DINT(DINT_TO_INT(", "))"),
               ("SEL(b, x, ", ")"), ("x * 2 - ", " + 1")]
_STMT_WRAPS = [("IF b THEN\n", "END_IF;\n"), ("WHILE b DO\n", "END_WHILE;\n"),
               ("CASE x OF 1:\n", "END_CASE;\n"), ("FOR i := 1 TO 2 DO\n", "END_FOR;\n"),
               ("REPEAT\n", "UNTIL b END_REPEAT;\n"), ("IF b THEN x := 0; ELSE\n", "END_IF;\n")]


# MatIEC stack entries one wrap adds at most / at least (FOR 7 ... REPEAT 1; a call with a
# second argument 4 ... parentheses 1), measured (docs/diagnostics.md)
STMT_WRAP_COST = (1, 7)
EXPR_WRAP_COST = (1, 4)


def mixed(rng: random.Random, stmt_depth: int, expr_depth: int) -> str:
    """Random statements around a random expression, nested stmt_depth and expr_depth deep."""
    expr = "x"
    for _ in range(expr_depth):
        open_, close = rng.choice(_EXPR_WRAPS)
        expr = open_ + expr + close
    body = f"x := {expr};\n"
    for k in range(stmt_depth):
        open_, close = rng.choice(_STMT_WRAPS)
        body = open_.replace("FOR i ", f"FOR i{k} ") + body + close  # MatIEC: one per loop
    loops = "".join(f"  i{k} : INT;\n" for k in range(stmt_depth))
    return _main(body, decls=loops, before=_INC)
