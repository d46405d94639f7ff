"""The rules only some dialects enforce; their severity comes from the target (targets.py).
What STruC++ (OpenPLC v4) refuses is its own module, strucpp.py.

Needs: a CheckedProgram (after resolve and rules.check_names; what an erroneous program
leaves unresolved is skipped). Each rule was established on the real tools:

- E0214: names IEC 61131-3 (3rd edition), CODESYS, TwinCAT or RuSTy reserve and MatIEC does
  not (reserved.py holds the lists and their sources).
- E0215: identifiers with "__" or a trailing "_": iec2c refuses both ("invalid located
  variable declaration"); CODESYS refuses "__".
- E0309: TRUNC received in an integer narrower than 64 bits: RuSTy's TRUNC returns LINT and it
  warns E067 "Implicit downcast from 'LINT' to 'DINT'" for an assignment, an argument, a
  function result or the arithmetic and generic functions (ABS, LIMIT, ...) that carry the
  value there, not for a comparison, an index, a CASE selector or a FOR bound (measured,
  ebf72fb8). CODESYS's TRUNC returns DINT. MatIEC types TRUNC from its context: nothing.
- E0411: an array element (anywhere in the path: a[i], s.v[i], a[i].x) bound to a FUNCTION's
  VAR_IN_OUT or VAR_OUTPUT inside a FUNCTION_BLOCK or PROGRAM: iec2c wraps such a call in a
  C helper that spells the element `.table1` and g++ fails ("has no member named 'table1'");
  the same call inside a FUNCTION, and an FB instance's VAR_IN_OUT given an element, build and
  run (measured on OpenPLC v3's toolchain). RuSTy takes all of them.
- E0512: VAR_TEMP that OpenPLC v3 does not build: in a FUNCTION its grammar has none ("unexpected
  temporary located variable(s) declaration in function declaration"), and of an array or
  STRUCT type in a FUNCTION_BLOCK or PROGRAM its C initialises it as __SET_VAR(data__->,M,,)
  and g++ fails ("expected primary-expression"); elementary and enumeration VAR_TEMPs of a
  FUNCTION_BLOCK or PROGRAM build (measured on OpenPLC v3's toolchain). STruC++ builds all of
  them.
- E0100 (MatIEC's grammar, measured with iec2c): an empty VAR block, CONSTANT on VAR_INPUT,
  VAR_OUTPUT, VAR_IN_OUT or VAR_TEMP, an empty statement, a typed or based CASE label
  (DINT#5:, 16#FF:), a POU with no statement. The soft PLC runs them: upload_severity.
- E0602 (the names): OpenPLC v3's upload needs CONFIGURATION Config0 and RESOURCE Res0 (its
  runtime's build names the generated C files after them); MatIEC compiles any names,
  CODESYS takes any, and the bench's soft PLC runs any. An upload rule: upload_severity.
"""

from __future__ import annotations

from collections.abc import Iterator

from . import ast as A
from .diagnostics import Diagnostics
from .reserved import codesys_family_reserves, matiec_refuses_name
from .rules import declared_names
from .source import SourcePos
from .strucpp import check_strucpp
from .symbols import CallTarget, CheckedProgram, PouSym
from .targets import CODESYS, OPENPLC, OPENPLC_V4, Target
from .types import STRING, ArrayType, ElemType, StructType, Type

_BOTH = frozenset({OPENPLC, CODESYS})
_CODESYS = frozenset({CODESYS})
_OPENPLC = frozenset({OPENPLC})


def check_dialects(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    check_reserved_names(prog, diags, target)
    check_trunc_narrowing(prog, diags, target)
    check_element_out_arguments(prog, diags, target)
    check_var_temp(prog, diags, target)
    check_configuration_names(prog, diags, target)
    check_string_values(prog, diags, target)
    check_c_pragmas(prog, diags, target)
    check_block_forms(prog, diags, target)
    check_case_on_bits(prog, diags, target)
    check_case_label_forms(prog, diags, target)
    check_empty_bodies(prog, diags, target)
    check_strucpp(prog, diags, target)


# ------------------------------------------------------------------ names
def check_reserved_names(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    for n in declared_names(prog):
        name = n.name
        if "__" in name or name.endswith("_"):
            double = "__" in name
            sev = target.severity(_BOTH if double else _OPENPLC)
            if sev is not None:
                form, who = (("two underscores in a row", "MatIEC and CODESYS refuse")
                             if double else ("a trailing underscore", "MatIEC refuses"))
                diags.report(sev, n.pos, "E0215", f"{n.what} '{name}' has {form}: {who} it; "
                             "write one underscore between parts and none at the end")
            continue
        if matiec_refuses_name(name, n.what):
            continue  # E0202, an error for every target
        why = codesys_family_reserves(name)
        if why is None or not (why.every_name or n.is_global):
            continue
        sev = target.severity(_CODESYS)
        assert sev is not None  # a construct a dialect refuses is at least a warning
        scope = "as any name" if why.every_name else "as a POU or type name"
        diags.report(sev, n.pos, "E0214", f"{n.what} '{name}' is {why}, refused there "
                     f"{scope}: rename it")


# ------------------------------------------------------------------ TRUNC
# Standard functions whose result is the value of one of their inputs; SEL's G and MUX's K,
# their first inputs, select and are not carried.
_CARRY_ALL = frozenset({"ABS", "MOVE", "MIN", "MAX", "LIMIT", "MOD"})
_CARRY_AFTER_SELECTOR = frozenset({"SEL", "MUX"})
_ARITH = {"+", "-", "*", "/", "MOD"}


def check_trunc_narrowing(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    sev = target.severity(frozenset(), warned_by=_CODESYS)
    if sev is None:
        return
    for value, into in _value_sinks(prog):
        if not (isinstance(into, ElemType) and into.is_int and into.bits < 64):
            continue
        for trunc in _truncs_carried(prog, value):
            diags.report(sev, trunc.pos, "E0309", f"TRUNC goes into {into.name} here: RuSTy's "
                         "TRUNC returns LINT (CODESYS's DINT), so this narrows there: receive "
                         f"it in a LINT, or write LINT_TO_{into.name}(TRUNC(...))")


def _value_sinks(prog: CheckedProgram) -> Iterator[tuple[A.Expr, Type | None]]:
    """Every expression whose value is stored into a declared type: assigned (to a variable
    or a FUNCTION's result) or passed to an input of a POU or a conversion."""
    for sym in prog.pous.values():
        if sym.node is None:
            continue
        for node in A.walk(sym.node.body):
            if isinstance(node, A.Assign):
                yield node.value, prog.expr_types.get(node.target)
    for tgt in prog.calls.values():
        if tgt.kind == "conv" and tgt.conv is not None:
            for _, e in tgt.inputs:
                yield e, tgt.conv[0]
        elif tgt.kind in ("function", "fb") and tgt.pou is not None:
            for key, e in tgt.inputs:
                param = tgt.pou.vars.get(key)
                if param is not None and param.kind == A.VAR_INPUT:
                    yield e, param.type


def _truncs_carried(prog: CheckedProgram, value: A.Expr) -> Iterator[A.Call]:
    """The TRUNC calls whose result ``value`` is, through arithmetic and value-carrying
    standard functions (a stack: a sum of 20,000 terms is no recursion)."""
    stack = [value]
    while stack:
        e = stack.pop()
        if isinstance(e, A.Binary):
            if e.op in _ARITH:
                stack += (e.left, e.right)
        elif isinstance(e, A.Unary):
            if e.op == "-":
                stack.append(e.operand)
        elif isinstance(e, A.Call):
            tgt = prog.calls.get(e)
            if tgt is None or tgt.kind != "std" or tgt.std is None:
                continue
            name = tgt.std.name
            if name == "TRUNC":
                yield e
            elif name in _CARRY_ALL:
                stack += [arg for _, arg in tgt.inputs]
            elif name in _CARRY_AFTER_SELECTOR:
                stack += [arg for _, arg in tgt.inputs[1:]]


# ------------------------------------------------------------------ array elements as in-outs
def check_element_out_arguments(prog: CheckedProgram, diags: Diagnostics,
                                target: Target) -> None:
    sev = target.severity(_OPENPLC)
    if sev is None:
        return
    # the calls come without the POU that holds them: walk the bodies only when one binds an
    # element (a walk of the library costs 30 ms per check)
    suspects = {id(node) for node, tgt in prog.calls.items()
                if tgt.kind == "function" and tgt.pou is not None
                and any(_through_index(e) for _, e, _ in _bound_by_reference(tgt.pou, tgt))}
    if not suspects:
        return
    for sym in prog.pous.values():
        if sym.node is None or sym.kind == "FUNCTION":
            continue
        for node in A.walk(sym.node.body):
            if not isinstance(node, A.Call) or id(node) not in suspects:
                continue
            tgt = prog.calls[node]
            assert tgt.pou is not None
            for key, e, kind in _bound_by_reference(tgt.pou, tgt):
                if _through_index(e):
                    param = tgt.pou.vars[key]
                    diags.report(sev, e.pos, "E0411", f"array element bound to {kind} "
                                 f"{param.name} of FUNCTION {tgt.pou.name} in {sym.kind} "
                                 f"{sym.name}: OpenPLC's C build fails on it; pass a "
                                 "variable and copy the element in and out")


def check_var_temp(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    sev = target.severity(_OPENPLC)
    if sev is None:
        return
    for unit in prog.units:
        for pou in unit.pous:
            sym = prog.pous.get(pou.name.upper())
            for blk in pou.blocks:
                if blk.kind != A.VAR_TEMP:
                    continue
                if pou.kind == "FUNCTION":
                    diags.report(sev, blk.pos, "E0512", f"VAR_TEMP in FUNCTION {pou.name}: "
                                 "MatIEC's grammar has none in a FUNCTION: declare the "
                                 "variables in VAR (a FUNCTION's VAR starts afresh at every "
                                 "call)")
                    continue
                for decl in blk.decls:
                    var = sym.vars.get(decl.name.upper()) if sym is not None else None
                    if var is not None and isinstance(var.type, ArrayType | StructType):
                        kind = "an array" if isinstance(var.type, ArrayType) else "a STRUCT"
                        diags.report(sev, decl.pos, "E0512", f"VAR_TEMP {decl.name} in "
                                     f"{pou.kind} {pou.name} is {kind}: OpenPLC's C build "
                                     "fails on it: declare it in VAR, or compute with it in a "
                                     "FUNCTION")


def _bound_by_reference(callee: PouSym, tgt: CallTarget) -> Iterator[tuple[str, A.Expr, str]]:
    for key, e in tgt.inputs:
        param = callee.vars.get(key)
        if param is not None and param.kind == A.VAR_IN_OUT:
            yield key, e, "VAR_IN_OUT"
    for key, e in tgt.outputs:
        yield key, e, "VAR_OUTPUT"


def _through_index(e: A.Expr) -> bool:
    while isinstance(e, A.Member | A.Index):
        if isinstance(e, A.Index):
            return True
        e = e.obj
    return False


# ------------------------------------------------------------------ VAR block forms
_NO_CONSTANT = frozenset({A.VAR_INPUT, A.VAR_OUTPUT, A.VAR_IN_OUT, A.VAR_TEMP})


def check_block_forms(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """VAR blocks MatIEC's grammar refuses and CODESYS and STruC++ take (measured on OpenPLC
    v3's build): an empty block, and CONSTANT on VAR_INPUT, VAR_OUTPUT, VAR_IN_OUT, VAR_TEMP;
    and an empty statement (`ELSE;`, `x := 1;;`).
    The bench's soft PLC runs both as the other dialects mean them: a warning there."""
    sev = target.upload_severity(_OPENPLC)
    if sev is None:
        return
    for unit in prog.units:
        for pou in unit.pous:
            if pou.kind == "FUNCTION":
                _check_constant_leak(pou, diags, sev)
            for pos in pou.empty_statements:
                diags.report(sev, pos, "E0100", "an empty statement (a lone ';'): MatIEC "
                             "refuses it: remove the ';'")
        blocks = [b for pou in unit.pous for b in pou.blocks]
        blocks += [b for cfg in unit.configs for b in cfg.globals]
        blocks += [b for cfg in unit.configs for r in cfg.resources for b in r.globals]
        for blk in blocks:
            if not blk.decls:
                diags.report(sev, blk.pos, "E0100", f"an empty {blk.kind} ... END_VAR block: "
                             "MatIEC refuses it: declare a variable in it, or remove it")
            if blk.constant and blk.kind in _NO_CONSTANT:
                diags.report(sev, blk.pos, "E0100", f"{blk.kind} CONSTANT: MatIEC takes "
                             "CONSTANT on VAR, VAR_GLOBAL and VAR_EXTERNAL blocks only: drop "
                             "CONSTANT")


def _check_constant_leak(pou: A.Pou, diags: Diagnostics, sev: str) -> None:
    """In a FUNCTION, MatIEC makes a VAR block that follows a VAR CONSTANT block constant too:
    assigning its variables fails ("Assignment to CONSTANT variables is not allowed"); the
    same blocks in the other order, or in a FUNCTION_BLOCK, build (measured)."""
    after_constant = False
    for blk in pou.blocks:
        if blk.kind == A.VAR and blk.constant:
            after_constant = True
        elif after_constant and blk.kind == A.VAR and blk.decls:
            diags.report(sev, blk.pos, "E0100", f"a VAR block after VAR CONSTANT in FUNCTION "
                         f"{pou.name}: MatIEC makes its variables constant too, and assigning "
                         "them fails: declare the VAR CONSTANT block after it")


def check_case_on_bits(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """CASE on a bit string (BYTE, WORD, DWORD, LWORD): MatIEC refuses it ("'CASE' quantity
    not an integer or enumerated", measured); CODESYS takes it, and so does the soft PLC."""
    sev = target.upload_severity(_OPENPLC)
    if sev is None:
        return
    for sym in prog.pous.values():
        if sym.node is None:
            continue
        for node in A.walk(sym.node.body):
            if isinstance(node, A.Case):
                st = prog.expr_types.get(node.subject)
                if isinstance(st, ElemType) and st.kind == "bits":
                    diags.report(sev, node.subject.pos, "E0303", f"CASE on a {st.name}: MatIEC "
                                 "takes integer and enumerated selectors only: convert it "
                                 f"({st.name}_TO_UINT)")


def check_case_label_forms(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """A CASE label (or a bound of a label's range) written typed (DINT#5) or based (16#FF,
    2#101, 8#17): MatIEC's grammar takes decimal integers, their ranges and enumeration values
    only (iec_bison.yy: case_list_element is signed_integer | subrange | enumerated_value), so
    iec2c fails "invalid case element(s) defined after 'OF'" (measured). STruC++ takes the
    based ones and refuses the typed ones (E0110); the soft PLC runs both."""
    sev = target.upload_severity(_OPENPLC)
    if sev is None:
        return
    for sym in prog.pous.values():
        if sym.node is None:
            continue
        for node in A.walk(sym.node.body):
            if not isinstance(node, A.CaseLabel):
                continue
            for bound in (node.low, node.high):
                lit = bound.operand if isinstance(bound, A.Unary) else bound
                if (isinstance(lit, A.Literal) and lit.kind == "int" and "#" in lit.text):
                    form = "typed" if lit.type_prefix is not None else "based"
                    diags.report(sev, lit.pos, "E0100", f"{form} literal '{lit.text}' as a "
                                 "CASE label: MatIEC takes decimal labels only (\"invalid case "
                                 f"element(s)\"): write {lit.value}")


def check_empty_bodies(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """A FUNCTION, FUNCTION_BLOCK or PROGRAM with no statement (comments only, or nothing
    between its last END_VAR and its END_): MatIEC refuses all three ("no body defined in
    function declaration", "unknown error in function block declaration", measured);
    STruC++ and the soft PLC take them."""
    sev = target.upload_severity(_OPENPLC)
    if sev is None:
        return
    for unit in prog.units:
        for pou in unit.pous:
            if not pou.body and not pou.empty_statements:
                what = pou.kind.replace("_", " ").lower()
                diags.report(sev, pou.pos, "E0100", f"{what} {pou.name} has no statement: "
                             "MatIEC refuses an empty body: give it one (an output assigned "
                             "its own value will do)")


# ------------------------------------------------------------------ C in pragmas
def check_c_pragmas(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """A {pragma} with C in a POU's body, which OpenPLC v3 builds (rules.py flags the forms
    its build fails on), for the bench's soft PLC (build, run, serve, the pytest plugin): an
    error. The bench's C keeps variables unlike MatIEC's, so it cannot paste the C in, and
    skipping it would run a different program without a word: OSCAT's T_PLC_MS, which reads
    the PLC time in such a pragma, would return 0 for ever and every timer built on it would
    never expire. `check --target openplc` accepts it, for the real PLC."""
    if target.upload:
        return
    flagged = {d.pos for d in diags.items if d.code == "E0103"}
    for pou in prog.pous.values():
        if pou.node is None:
            continue
        for pos in pou.node.c_pragmas:
            if pos not in flagged:
                diags.error(pos, "E0103", f"the bench's soft PLC cannot run the C in this "
                            f"{{pragma}} of {pou.kind} {pou.name} (OpenPLC v3 pastes it into "
                            f"its build; the bench would skip it and run another program): "
                            f"write it in ST, or check it for the real PLC with "
                            f"`armbench check --target openplc`")


# ------------------------------------------------------------------ configuration names
def check_configuration_names(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """Config0 and Res0, the names OpenPLC's upload needs: an error for an OpenPLC check or
    upload, a warning for CODESYS and for the soft PLC, which run any names."""
    if prog.config is None:
        return
    sev = target.upload_severity(_OPENPLC)
    if sev is None:
        return
    config = next(c for u in prog.units for c in u.configs)  # the one prog.config models
    where = ("" if sev == "error" else
             " (the bench's soft PLC runs it as it is)" if not target.upload else
             " (CODESYS takes any name)")
    if config.name.upper() != "CONFIG0":
        diags.report(sev, config.pos, "E0602", f"CONFIGURATION '{config.name}': OpenPLC's "
                     f"upload needs it to be named Config0{where}")
    res = config.resources[0]
    if res.name.upper() != "RES0":
        diags.report(sev, res.pos, "E0602", f"RESOURCE '{res.name or '<none>'}': OpenPLC's "
                     f"upload needs it to be named Res0{where}")


# ------------------------------------------------------------------ STRING values
_STRING_CMP = {"=", "<>", "<", "<=", ">", ">="}


def check_string_values(prog: CheckedProgram, diags: Diagnostics, target: Target) -> None:
    """E0121: a STRING comparison or FIND, whose value MatIEC (OpenPLC v3) computes its own
    way: it compares only the common prefix ('ab' = 'abc' is TRUE) and its FIND skips after a
    partial match (FIND('Hello', 'lo') = 6); STruC++ (OpenPLC v4, STRING of 254 characters)
    and CODESYS compare whole strings and find substrings (their runtimes' sources)."""
    sev = target.severity(frozenset(), warned_by=frozenset({OPENPLC_V4, CODESYS}))
    if sev is None:
        return
    found: list[tuple[SourcePos, str]] = []
    for e, t in prog.expr_types.items():
        if isinstance(e, A.Binary) and e.op in _STRING_CMP and \
                prog.expr_types.get(e.left) is STRING and t is not None:
            found.append((e.pos, f"'{e.op}' of STRINGs: OpenPLC v3 (MatIEC) compares only "
                          "the common prefix ('ab' = 'abc' is TRUE there), OpenPLC v4 and "
                          "CODESYS the whole strings: compare LEN too where lengths differ"))
    for c, tgt in prog.calls.items():
        if tgt.kind == "std" and tgt.std is not None and tgt.std.name == "FIND":
            found.append((c.pos, "FIND: OpenPLC v3's (MatIEC's) FIND skips after a partial "
                          "match (FIND('Hello', 'lo') = 6 there, 4 in OpenPLC v4 and CODESYS): "
                          "search for one character, or compare MID(...) in a loop"))
    for pos, msg in sorted(found, key=lambda f: str(f[0])):
        diags.report(sev, pos, "E0121", msg)

