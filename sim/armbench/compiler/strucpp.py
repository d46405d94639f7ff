"""The rules of `armbench check --target openplc-v4`: what STruC++, OpenPLC v4's compiler,
refuses, what g++ then fails on in the C++ it writes, and what it builds with a different
value than MatIEC (OpenPLC v3) computes.

Needs: a CheckedProgram (after resolve; what an erroneous program leaves unresolved is skipped).
Every rule was measured on STruC++ 0.6.1 (fb7980f) with its runtime headers and g++ 12 run as
the v4 runtime runs it (-std=c++17 -O1 -DSTRUCPP_THREADED); the corpus cases
(tests/corpus/diagnostics/, codes below) hold the evidence, and
tests/compiler/test_strucpp_verdicts.py runs them through the real STruC++ where STRUCPP
names it. docs/strucpp-facts.md has the measurements, docs/diagnostics.md what to write
instead.

- E0109 CONTINUE: not in STruC++'s grammar.
- E0110 literals its lexer has no token for: a sign after '#' (DINT#-8, T#-250ms), Type#Value
  of an enumeration, '_' in a REAL literal (1_000.0) (BOOL#TRUE too, which the bench refuses
  for every target, E0300); and a typed literal as a CASE label, which its grammar refuses.
- E0216 names STruC++ reserves (reserved.py: its keywords, the POUs of its libraries and
  runtime, C macros its C++ sees).
- E0217 VAR_GLOBAL inside a RESOURCE: its grammar takes them in the CONFIGURATION only.
- E0310 NOT (...) and ROL/ROR given a C++ int (cxxtypes.py).
- E0311 untyped decimal integer literals it writes with another value (a JavaScript double).
- E0312 conversions from and to TIME: milliseconds in STruC++, seconds in MatIEC.
- E0412 MUX, and AND/OR/XOR/MIN/MAX called by name, whose arguments are C++ types g++ cannot
  deduce one template type from (cxxtypes.py).
- E0413 named arguments of a standard function out of its parameter order: STruC++ passes
  them in the order written.
- E0505 a STRUCT or FB initialiser as a declaration's initial value.
- E0506 a repeated value n(v) in an array initialiser.
- E0507 an initial value on a TYPE: refused, or on an enumeration ignored.
- E0508 array initial values it drops: of a PROGRAM's variables, of VAR_GLOBALs, of STRUCT
  fields (they start at 0).
- E0509 subscripts of, or initial values for, an array of 3 or more dimensions.
- E0510 a CONSTANT without an initial value (VAR, VAR_TEMP, VAR_EXTERNAL CONSTANT).
- E0511 an array of 2 or 3 dimensions in what the debugger's table (generated_debug.cpp,
  which the v4 editor writes with STruC++'s compile API and uploads) lists: the VAR (also
  CONSTANT), VAR_INPUT, VAR_OUTPUT and VAR_IN_OUT of a FUNCTION_BLOCK, the VAR, VAR_INPUT and
  VAR_OUTPUT of a PROGRAM, VAR_GLOBALs, also inside STRUCT fields and array elements. The
  table takes each element's address as X[i][j], and the runtime's 2-D and 3-D arrays
  have no operator[] (4-D and deeper ones are nested 1-D arrays, which have). VAR_TEMP,
  VAR_EXTERNAL, FUNCTIONs and a PROGRAM's VAR_IN_OUT are not in the table.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from . import ast as A
from .cxxtypes import CxxType, call_arguments, cxx_type, iec_base, strucpp_literal_value
from .diagnostics import Diagnostics
from .reserved import matiec_refuses_name, strucpp_reserves
from .rules import declared_names, is_c_macro
from .symbols import CheckedProgram
from .targets import OPENPLC, OPENPLC_V4, Target
from .types import ArrayType, ElemType, StructType, Type

# the codes of these rules (the STruC++ cross-check, tests/compiler/test_strucpp_verdicts.py, runs
# their corpus cases)
STRUCPP_CODES = frozenset({"E0109", "E0110", "E0216", "E0217", "E0310", "E0311", "E0312",
                           "E0412", "E0413", "E0505", "E0506", "E0507", "E0508", "E0509",
                           "E0510", "E0511"})
_V4 = frozenset({OPENPLC_V4})
_V3_AND_V4 = frozenset({OPENPLC, OPENPLC_V4})
_VIA = "STruC++ (OpenPLC v4)"


def check_strucpp(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    sev = target.severity(_V4)
    assert sev is not None  # a construct a dialect refuses is at least a warning
    rep = _Reporter(diags, sev)
    body = _BodyNodes.of(prog)
    check_statements(body, rep)
    check_literals(prog, body, rep)
    check_names(prog, rep)
    check_declarations(prog, rep)
    check_debug_table(prog, rep)
    check_expressions(prog, body, rep)
    between = target.severity_between(_V3_AND_V4)
    if between is not None:
        check_time_conversions(prog, body, _Reporter(diags, between))


@dataclass(frozen=True)
class _Reporter:
    diags: Diagnostics
    severity: str

    def __call__(self, node: A.Node, code: str, message: str) -> None:
        self.diags.report(self.severity, node.pos, code, message)


# ------------------------------------------------------------------ walking the program
def _user_pous(prog: CheckedProgram) -> Iterator[A.Pou]:
    for unit in prog.units:
        yield from unit.pous


@dataclass
class _BodyNodes:
    """The nodes of the POU bodies the rules look at, gathered in one walk (a walk of the
    library and the controller takes a fifth of a second)."""

    continues: list[A.Continue] = field(default_factory=list)
    case_labels: list[A.CaseLabel] = field(default_factory=list)
    literals: list[A.Literal] = field(default_factory=list)
    indices: list[A.Index] = field(default_factory=list)
    nots: list[A.Unary] = field(default_factory=list)
    calls: list[A.Call] = field(default_factory=list)

    @classmethod
    def of(cls, prog: CheckedProgram) -> _BodyNodes:
        out = cls()
        nodes: list[A.Unary] = []
        # by exact class: the walk yields every field value too, and one dict lookup per
        # item is cheaper than a chain of isinstance tests
        buckets: dict[type, list[Any]] = {
            A.Literal: out.literals, A.Call: out.calls, A.Index: out.indices, A.Unary: nodes,
            A.CaseLabel: out.case_labels, A.Continue: out.continues}
        for node in A.walk([pou.body for pou in _user_pous(prog)]):
            bucket = buckets.get(type(node))
            if bucket is not None:
                bucket.append(node)
        out.nots = [u for u in nodes if u.op == "NOT" and u.parenthesised]
        return out


def _declarations(prog: CheckedProgram) -> Iterator[tuple[str, A.VarBlock]]:
    """Every VAR block, with where it is: the POU kind, "CONFIGURATION" or "RESOURCE"."""
    for unit in prog.units:
        for pou in unit.pous:
            for blk in pou.blocks:
                yield pou.kind, blk
        for cfg in unit.configs:
            for blk in cfg.globals:
                yield "CONFIGURATION", blk
            for res in cfg.resources:
                for blk in res.globals:
                    yield "RESOURCE", blk


def _struct_fields(prog: CheckedProgram) -> Iterator[tuple[A.TypeDecl, A.StructField]]:
    for unit in prog.units:
        for td in unit.types:
            if isinstance(td.definition, A.StructTypeRef):
                for f in td.definition.fields:
                    yield td, f


def _type_of(prog: CheckedProgram, ref: A.TypeRef) -> object:
    """The checked type a declaration's TypeRef names (None where it is not resolved)."""
    if isinstance(ref, A.NamedTypeRef):
        return prog.types.get(ref.name.upper())
    return None


def _dims(prog: CheckedProgram, ref: A.TypeRef) -> int:
    """How many dimensions the array a TypeRef declares or names has (0: no array)."""
    if isinstance(ref, A.ArrayTypeRef):
        return len(ref.ranges)
    t = _type_of(prog, ref)
    return len(t.dims) if isinstance(t, ArrayType) else 0


# ------------------------------------------------------------------ statements
def check_statements(body: _BodyNodes, rep: _Reporter) -> None:
    for node in body.continues:
        rep(node, "E0109", f"CONTINUE is not in {_VIA}'s grammar (a syntax error there): put "
            "the rest of the loop body under IF NOT (condition) THEN ... END_IF")


# ------------------------------------------------------------------ literals
def _literals(prog: CheckedProgram, body: _BodyNodes) -> Iterator[tuple[A.Literal, bool]]:
    """Every literal of the program, and whether STruC++ copies it into its C++ as written:
    the initial value of an elementary variable of a PROGRAM or a CONFIGURATION is; every other
    place goes through its expression writer (bodies, CASE labels, FUNCTION and FUNCTION_BLOCK
    initial values, array initialisers, STRUCT fields, bounds)."""
    yield from ((lit, False) for lit in body.literals)
    for unit in prog.units:
        for pou in unit.pous:
            for blk in pou.blocks:
                verbatim = pou.kind == "PROGRAM"
                for decl in blk.decls:
                    yield from _decl_literals(decl, verbatim)
        for cfg in unit.configs:
            for blk in [*cfg.globals, *(b for r in cfg.resources for b in r.globals)]:
                for decl in blk.decls:
                    yield from _decl_literals(decl, True)
            for node in A.walk([r.tasks for r in cfg.resources]):
                if isinstance(node, A.Literal):
                    yield node, True
        for node in A.walk(unit.types):
            if isinstance(node, A.Literal):
                yield node, False


def _decl_literals(decl: A.VarDecl, verbatim: bool) -> Iterator[tuple[A.Literal, bool]]:
    elementary_init = verbatim and isinstance(decl.init, A.Expr)
    for node in A.walk(decl.init):
        if isinstance(node, A.Literal):
            yield node, elementary_init
    for node in A.walk(decl.type):
        if isinstance(node, A.Literal):
            yield node, False


def check_literals(prog: CheckedProgram, body: _BodyNodes, rep: _Reporter) -> None:
    label_literals: set[int] = set()
    for label in body.case_labels:
        for lit in (label.low, label.high):
            if isinstance(lit, A.Unary):
                lit = lit.operand
            if isinstance(lit, A.Literal):
                label_literals.add(id(lit))
            if isinstance(lit, A.Literal) and lit.type_prefix is not None and lit.kind != "enum":
                rep(lit, "E0110", f"typed literal '{lit.text}' as a CASE label: {_VIA}'s "
                    "grammar takes untyped ones only (\"Expected END_CASE, found typed "
                    "literal\"): write it in decimal, untyped (MatIEC takes no based label "
                    "either; above 2^53, where STruC++ changes a decimal, compare with IF)")
    for lit, verbatim in _literals(prog, body):
        why = _unlexed(lit)
        if why is not None:
            text = f"{lit.type_prefix}#{lit.value}" if lit.kind == "enum" else lit.text
            rep(lit, "E0110", f"literal '{text}': {_VIA}'s lexer has no token for {why}")
        elif lit.kind == "int" and not verbatim:
            written = strucpp_literal_value(lit)
            if written != lit.value:
                exact = abs(int(lit.value))
                fix = (f"compare with IF ... = 16#{exact:X} instead (MatIEC takes no typed or "
                       "based CASE label)" if id(lit) in label_literals else
                       f"write the exact value typed, LINT#{exact}, or in hexadecimal, "
                       f"16#{exact:X}")
                rep(lit, "E0311", f"{_VIA} writes {lit.text} into its C++ as {written} (it "
                    f"parses untyped decimals into a JavaScript double): {fix}")


def _unlexed(lit: A.Literal) -> str | None:
    """Why STruC++'s lexer splits ``lit`` (lexer.ts TypedLiteral, TimeLiteral, RealLiteral),
    or None."""
    text = lit.text
    head, hash_, value = text.partition("#")
    if hash_ and value[:1] in ("-", "+"):
        fix = f"-{head}#{value[1:]}" if lit.kind != "time" else f"{head}#0s - {head}#{value[1:]}"
        return f"a sign after '#': write {fix}"
    if lit.kind == "enum" and lit.type_prefix is not None:
        return (f"Type#Value of an enumeration: write {lit.value} (name the values of "
                "different enumerations differently, so the value alone says which)")
    if lit.kind == "real" and "_" in (value if hash_ else text):
        return f"'_' in a REAL literal: write {text.replace('_', '')}"
    return None


# ------------------------------------------------------------------ names
# what STruC++ declares at namespace scope, beside its runtime and library POUs (a PROGRAM is
# the class Program_NAME, a configuration, resource, task or program instance is no C++ name)
_NAMESPACE_SCOPE = frozenset({"type", "function", "function block", "global"})


def check_names(prog: CheckedProgram, rep: _Reporter) -> None:
    for n in declared_names(prog):
        if matiec_refuses_name(n.name, n.what) or is_c_macro(n.name):
            continue  # E0202, E0204: errors for every target
        why = strucpp_reserves(n.name, n.what in _NAMESPACE_SCOPE)
        if why is not None:
            rep.diags.report(rep.severity, n.pos, "E0216", f"{n.what} '{n.name}' is {why}: "
                             f"{_VIA} refuses it, or g++ then fails on its C++: rename it")


# ------------------------------------------------------------------ declarations
def check_declarations(prog: CheckedProgram, rep: _Reporter) -> None:
    for unit in prog.units:
        for cfg in unit.configs:
            for res in cfg.resources:
                for blk in res.globals:
                    rep(blk, "E0217", f"VAR_GLOBAL inside RESOURCE {res.name}: {_VIA}'s "
                        "grammar takes VAR_GLOBAL only in the CONFIGURATION: move the block "
                        "up, before the RESOURCE")
        for td in unit.types:
            if td.init is None:
                continue
            if isinstance(td.definition, A.EnumTypeRef):
                rep(td, "E0507", f"TYPE {td.name} has an initial value: {_VIA} ignores it "
                    "on an enumeration (its variables start at the first value): give the "
                    "initial value at each variable of the type instead")
            else:
                rep(td, "E0507", f"TYPE {td.name} has an initial value: {_VIA}'s grammar "
                    "takes none there (\"Expected END_TYPE, found :=\"): give the initial "
                    "value at each variable of the type instead")
    for where, blk in _declarations(prog):
        for decl in blk.decls:
            _check_decl(prog, rep, where, blk, decl)
    for td, f in _struct_fields(prog):
        _check_init(prog, rep, f, f.type, f.init, f"field {td.name}.{f.name}")
        if isinstance(f.init, A.ArrayInit):
            rep(f, "E0508", f"{_VIA} drops the initial values of array field "
                f"{td.name}.{f.name}: it starts at 0 there: fill it in the POU that uses it "
                "(once, at the first scan)")


def _check_decl(prog: CheckedProgram, rep: _Reporter, where: str, blk: A.VarBlock,
                decl: A.VarDecl) -> None:
    what = f"variable {decl.name}" if where not in ("CONFIGURATION", "RESOURCE") \
        else f"global {decl.name}"
    _check_init(prog, rep, decl, decl.type, decl.init, what)
    if isinstance(decl.init, A.ArrayInit) and where in ("PROGRAM", "CONFIGURATION",
                                                        "RESOURCE"):
        holder = "a PROGRAM's variables" if where == "PROGRAM" else "VAR_GLOBALs"
        rep(decl, "E0508", f"{_VIA} drops the initial values of {holder} that are arrays: "
            f"{decl.name} starts at 0 there: keep the table in a FUNCTION_BLOCK's VAR "
            "CONSTANT (those keep theirs), or fill it at the first scan")
    if blk.constant and decl.init is None and blk.kind != A.VAR_INPUT \
            and where not in ("CONFIGURATION", "RESOURCE"):
        fix = ("declare it VAR_EXTERNAL without CONSTANT" if blk.kind == A.VAR_EXTERNAL
               else "give it an initial value, or make it a plain VAR that nothing writes")
        rep(decl, "E0510", f"CONSTANT {decl.name} has no initial value: {_VIA} refuses it "
            f"(\"CONSTANT variable must have an initializer\"): {fix}")


def _check_init(prog: CheckedProgram, rep: _Reporter, node: A.Node, ref: A.TypeRef,
                init: A.Init | None, what: str) -> None:
    if init is None:
        return
    if isinstance(init, A.StructInit):
        rep(node, "E0505", f"{what} has a structure initialiser (name := value, ...) as its "
            f"initial value: {_VIA}'s grammar has none: assign the fields in the body (once, "
            "at the first scan), or let a zero value mean the default")
    for node_ in A.walk(init):
        if isinstance(node_, A.ArrayInit):
            for count, _ in node_.items:
                if count is not None:
                    rep(count, "E0506", f"{what}: a repeated value n(v) in an array "
                        f"initialiser: {_VIA}'s grammar has none: write the values out")
    if isinstance(init, A.ArrayInit) and _dims(prog, ref) >= 3:
        rep(node, "E0509", f"{what}: initial values for an array of {_dims(prog, ref)} "
            f"dimensions: {_VIA}'s runtime has no such constructor and g++ fails: use an "
            "array of STRUCTs that each hold a 2-D array")


# ------------------------------------------------------------------ the debugger's table
# the VAR blocks whose variables STruC++'s debug table lists (its debug-table-gen.ts): a
# FUNCTION_BLOCK instance's members, a PROGRAM instance's persistent variables, globals
_DEBUGGED = {"FUNCTION_BLOCK": frozenset({A.VAR, A.VAR_INPUT, A.VAR_OUTPUT, A.VAR_IN_OUT}),
             "PROGRAM": frozenset({A.VAR, A.VAR_INPUT, A.VAR_OUTPUT}),
             "CONFIGURATION": frozenset({A.VAR_GLOBAL}),
             "RESOURCE": frozenset({A.VAR_GLOBAL})}


def multi_dim_part(t: Type, seen: frozenset[str] = frozenset()) -> tuple[str, int] | None:
    """Where a value of type ``t`` holds an array of 2 or 3 dimensions (the runtime's
    IEC_ARRAY_2D and IEC_ARRAY_3D; deeper arrays are nested 1-D arrays there, which [i]
    indexes), through STRUCT fields and array elements (not FB instances: each
    FUNCTION_BLOCK is checked where it is declared): ('' for ``t`` itself, '.Field',
    '[..].Field', ...; its dimensions), or None."""
    if isinstance(t, ArrayType):
        if len(t.dims) in (2, 3):
            return "", len(t.dims)
        inner = multi_dim_part(t.element, seen)
        return (f"[..]{inner[0]}", inner[1]) if inner else None
    if isinstance(t, StructType) and t.name.upper() not in seen:
        for spelling, ft in t.fields.values():
            inner = multi_dim_part(ft, seen | {t.name.upper()})
            if inner:
                return f".{spelling}{inner[0]}", inner[1]
    return None


def check_debug_table(prog: CheckedProgram, rep: _Reporter) -> None:
    for pou in _user_pous(prog):
        sym = prog.pous.get(pou.name.upper())
        kinds = _DEBUGGED.get(pou.kind, frozenset())
        if sym is None or not kinds:
            continue
        for blk in pou.blocks:
            if blk.kind in kinds:
                for decl in blk.decls:
                    var = sym.vars.get(decl.name.upper())
                    if var is not None:
                        _check_debugged(rep, decl, var.type, f"{pou.kind} {pou.name}")
    globals_ = prog.config.globals if prog.config is not None else {}
    for where, blk in _declarations(prog):
        if where in ("CONFIGURATION", "RESOURCE"):
            for decl in blk.decls:
                var = globals_.get(decl.name.upper())
                if var is not None:
                    _check_debugged(rep, decl, var.type, "the CONFIGURATION")


def _check_debugged(rep: _Reporter, decl: A.VarDecl, t: Type, holder: str) -> None:
    part = multi_dim_part(t)
    if part is None:
        return
    path, dims = part
    what = f"{decl.name}{path}" + (f" (type {t.name})" if t.name and not path else "")
    rep(decl, "E0511", f"{what} in {holder} is an array of {dims} dimensions: the debugger's "
        f"table of {_VIA} (generated_debug.cpp, which the v4 editor uploads) indexes its "
        "elements as X[i][j], which its runtime's arrays of 2 and 3 dimensions cannot "
        "(g++ fails, and the v4 build with it): keep the matrix in a FUNCTION, or hold it as a "
        "1-D array of STRUCTs (one row per element) or as 1-D arrays (one per row or column)")


# ------------------------------------------------------------------ expressions
def check_expressions(prog: CheckedProgram, body: _BodyNodes, rep: _Reporter) -> None:
    for index in body.indices:
        if len(index.indices) >= 3:
            rep(index, "E0509", f"subscript of an array of {len(index.indices)} dimensions: "
                f"{_VIA}'s runtime has no element access for it and g++ fails: use an array "
                "of STRUCTs that each hold a 2-D array (A[i].M[j, k])")
    for node in body.nots:
        t = cxx_type(prog, node.operand)
        if t is not None and not t.is_any_bit:
            rep(node, "E0310", f"NOT (...) is {_VIA}'s NOT function here, which takes IEC bit "
                f"types only, and its operand is a C++ {t}{_why_int(prog, node.operand)}: "
                f"g++ fails: {_not_fix(prog, node.operand)}")
    for call in body.calls:
        _check_std_call(prog, rep, call)


def _why_int(prog: CheckedProgram, e: A.Expr) -> str:
    if isinstance(e, A.Binary) and e.op in ("AND", "OR", "XOR"):
        left, right = cxx_type(prog, e.left), cxx_type(prog, e.right)
        if left is not None and right is not None:
            return f" ({left} {e.op} {right})"
    return ""


def _not_fix(prog: CheckedProgram, e: A.Expr) -> str:
    if iec_base(prog.expr_types.get(e)) == "bool":
        return ("apply NOT to each comparison instead (De Morgan: NOT (a AND b) is "
                "(NOT a) OR (NOT b), NOT (x >= y) is x < y), or assign the expression to a "
                "BOOL variable first")
    return "type the literals (WORD#16#FF, not 16#FF), or assign the expression to a variable " \
        "first"


def _check_std_call(prog: CheckedProgram, rep: _Reporter, c: A.Call) -> None:
    tgt = prog.calls.get(c)
    if tgt is None or tgt.kind != "std" or tgt.std is None:
        return
    name = tgt.std.name
    _check_named_order(rep, c, name, tgt.std.params)
    args = call_arguments(prog, c)
    if not args or any(a is None for a in args):
        return
    known: list[CxxType] = [a for a in args if a is not None]
    if name in ("ROL", "ROR") and not known[0].is_any_bit:
        rep(c, "E0310", f"{name}'s input is a C++ {known[0]} here, and {_VIA}'s {name} takes "
            "IEC bit types only: g++ fails: type the literals (WORD#16#1, not 16#1), or assign "
            "the expression to a variable first")
        return
    same = {"MUX": known[1:], "AND": known, "OR": known, "XOR": known}.get(name)
    if name in ("MIN", "MAX") and len(known) >= 3:
        same = known[:-1]  # the variadic template pairs all but the last with one T
    if same and any(t != same[0] for t in same):
        kinds = sorted({str(t) for t in same})
        rep(c, "E0412", f"{name}'s arguments are the C++ types {' and '.join(kinds)} here: "
            f"{_VIA}'s runtime {name} deduces one type from them and g++ fails: type the "
            "literals (INT#5, REAL#1.0), or assign each expression to a variable first")


# the same value whatever the order of their inputs
_COMMUTATIVE = frozenset({"MIN", "MAX", "AND", "OR", "XOR"})


def _check_named_order(rep: _Reporter, c: A.Call, name: str, params: tuple[str, ...]) -> None:
    written = [a.name.upper() for a in c.args if a.name is not None]
    if len(written) != len(c.args) or not written or name in _COMMUTATIVE:
        return
    if "*" in params:
        first = 0 if name == "MUX" else 1
        expected = (["K"] if name == "MUX" else []) + [f"IN{i + first}" for i in range(
            len(written) - (1 if name == "MUX" else 0))]
    else:
        expected = [p.upper() for p in params]
    if written != expected[:len(written)]:
        rep(c, "E0413", f"{name}'s arguments are named in the order {', '.join(written)}: "
            f"{_VIA} passes a standard function's arguments in the order written, ignoring "
            f"the names, and computes another value: write them in the order "
            f"{', '.join(expected[:len(written)])}")


# ------------------------------------------------------------------ TIME conversions
def check_time_conversions(prog: CheckedProgram, body: _BodyNodes, rep: _Reporter) -> None:
    for node in body.calls:
        tgt = prog.calls.get(node)
        if tgt is None or tgt.kind != "conv" or tgt.conv is None:
            continue
        src, dst = tgt.conv
        if "time" not in (src.kind, dst.kind) or dst.kind == "bool" or src.kind == dst.kind \
                or "string" in (src.kind, dst.kind):  # texts, not seconds (matiec-facts.md)
            continue
        rep(node, "E0312", f"{src.name}_TO_{dst.name}: MatIEC (OpenPLC v3) converts TIME from "
            f"and to seconds, {_VIA} milliseconds{_real_time(src, dst)}: the value differs "
            "1000-fold: keep durations in TIME (T#3s, T#1ms * n), or in an integer of "
            "milliseconds you scale yourself")


def _real_time(src: ElemType, dst: ElemType) -> str:
    return " (a REAL truncated to whole milliseconds)" if dst.kind == "time" and src.is_real \
        else ""
