"""The nesting guard: how deep ST nests, checked on the syntax tree before any recursive pass.

The figures it checks against are in limits.py.

Two limits, one diagnostic (E0108, once per file, at the first construct beyond either):

* MatIEC's parser stack. MatIEC is a bison parser compiled as C++ with a non-trivial location
  type, so bison cannot enlarge its stack beyond YYINITDEPTH = 200 entries: a file whose parse
  needs more is a syntax error in OpenPLC, however shallow it looks. The check replays how many
  grammar symbols MatIEC's LR stack holds at each point of the tree (`_prefix` says what a
  construct keeps on the stack while one of its parts is parsed, `_closing`/`_leaf` what it
  holds when it is reduced) and compares the peak with what MatIEC leaves a statement or a
  declaration. Every figure was measured on OpenPLC's iec2c (docs/diagnostics.md, Limits): 63
  nested IFs pass and 64 fail, 189 nested parentheses pass and 190 fail, and so on.
* The bench's own recursion guard. The passes after parsing (lower, resolve, emit_c, ffi) walk
  nested statements, expressions and types recursively; a file nested deeper than
  NESTING_LIMIT levels of syntax tree is not lowered, so those walks stay far inside Python's
  recursion limit. MatIEC's stack is the tighter limit for everything except chains of field
  accesses and indices on a variable (`s.f.f.f[1].f`), which MatIEC parses flat: there the
  bench is stricter, and such chains are capped by the type depth (E0211) anyway.

Left-associative chains of binary operators (`a + b + c + ...`, thousands of terms) are flat
for both: MatIEC's grammar is left-recursive and a binary expression that is the left operand
of another adds no level here either. Lists (statements, ELSIF branches, CASE clauses, values,
declarations, POUs) are left-recursive in MatIEC's grammar: any length passes (5,000 measured).
"""

from __future__ import annotations

from dataclasses import dataclass

import tree_sitter as ts

from .diagnostics import Diagnostics
from .limits import (
    DECLARATION_ROOM,
    MAX_PARENTHESES,
    NESTING_LIMIT,
    PARSER_STACK,
    STATEMENT_ROOM,
)
from .parse import ParsedFile

# Nodes between a counted parent and its counted children that are not in MatIEC's grammar as
# a level of their own (the bench's guard only).
_TRANSPARENT = frozenset({
    "argument_list", "named_argument", "elsif_clause", "else_clause", "case_clause",
    "case_value", "subrange", "assignment_statement", "invocation_statement", "structure_field",
    "variable_declaration", "structure_initializer_field", "comment", "pragma",
})
_STATEMENT_FIELDS = frozenset({"body", "consequence"})
_NOT_STATEMENTS = frozenset({"empty_statement", "comment", "pragma"})
_POUS = frozenset(STATEMENT_ROOM)
_LISTS = frozenset({"argument_list", "structure_initializer"})
_ZERO_PREFIX = frozenset({"invocation_statement", "case_value", "source_file", "var_block",
                          "var_input", "var_output", "var_in_out", "var_external", "var_temp",
                          "var_global", "var_config", "var_access"})

# What the user sees in the message, by node type.
_NAMES = {
    "if_statement": "IF", "elsif_clause": "ELSIF", "else_clause": "ELSE",
    "case_statement": "CASE", "case_clause": "CASE branch", "for_statement": "FOR",
    "while_statement": "WHILE", "repeat_statement": "REPEAT",
    "parenthesized_expression": "parentheses", "unary_expression": "unary minus or NOT",
    "binary_expression": "operator", "call_expression": "call", "index_expression": "index [ ]",
    "member_access_expression": "field access", "structure_initializer": "STRUCT initial value",
}


@dataclass(slots=True)  # not frozen: one per syntax node, and a frozen init costs twice
class _Frame:
    node: ts.Node
    stack: int  # symbols on MatIEC's stack when the node starts (its prefix included)
    room: int  # symbols MatIEC leaves this statement or declaration
    levels: int  # levels of syntax tree (the bench's guard)
    parent: _Frame | None


def check_nesting(pf: ParsedFile, diags: Diagnostics, limit: int = NESTING_LIMIT) -> None:
    """Report (once per file) the first construct nested too deep for MatIEC or the bench."""
    work: list[_Frame] = [_Frame(c, 0, PARSER_STACK, 0, None)
                          for c in reversed(pf.tree.root_node.children)]
    while work:
        f = work.pop()
        node = f.node
        peak = f.stack + (_leaf(node) if node.named_child_count == 0 else _closing(node))
        if peak > f.room:
            diags.error(pf.pos(node), "E0108", _matiec_message(f, peak))
            return
        if f.levels > limit:
            diags.error(pf.pos(node), "E0108", f"nesting deeper than {limit} levels "
                        "(statements, parentheses, operators, calls, indices, field accesses; "
                        "a limit of the bench): move the inner part into a variable or a "
                        "FUNCTION")
            return
        children: list[_Frame] = []
        seen: dict[str, int] = {}  # statements / list items already parsed, per field
        for i, child in enumerate(node.children):
            if not child.is_named:
                continue
            field = node.field_name_for_child(i) or (
                "item" if node.type in _LISTS else child.type)
            k = seen.get(field, 0)
            if child.type not in _NOT_STATEMENTS:
                seen[field] = k + 1
            room = f.room
            if node.type in _POUS and field in _STATEMENT_FIELDS:
                room = STATEMENT_ROOM[node.type]
                start = 1 if k else 0  # statement_list on the stack from the 2nd statement
            elif node.type in _POUS or node.type in ("type_declaration",
                                                      "configuration_declaration"):
                room, start = DECLARATION_ROOM, 0
            else:
                start = f.stack + _prefix(node, field, k)
            children.append(_Frame(child, start, room, f.levels + _levels(node, child), f))
        work.extend(reversed(children))
    pf.guarded = True


def _matiec_message(f: _Frame, peak: int) -> str:
    counts: dict[str, int] = {}
    up: _Frame | None = f
    while up is not None:
        name = _NAMES.get(up.node.type)
        if name is not None:
            counts[name] = counts.get(name, 0) + 1
        up = up.parent
    ranked = sorted(counts.items(), key=lambda kv: -kv[1])
    what = ", ".join(f"{n} nested {name}" for name, n in ranked)
    return (f"nesting too deep for MatIEC ({what or 'nested constructs'}): its parser needs "
            f"{peak} of the {f.room} stack entries left here and OpenPLC's build stops with a "
            f"syntax error (e.g. at most 63 nested IFs or {MAX_PARENTHESES} nested "
            "parentheses): move the inner part into a variable or a FUNCTION")


def _levels(parent: ts.Node, child: ts.Node) -> int:
    if child.type in _TRANSPARENT or child.named_child_count == 0:  # names, literals
        return 0
    if child.type == "binary_expression" and parent.type == "binary_expression" and \
            parent.child_by_field_name("left") == child:
        return 0
    return 1


def _prefix(parent: ts.Node, field: str, k: int) -> int:
    """Symbols `parent` holds on MatIEC's stack while its k-th part named `field` is parsed
    (k counts earlier parts of the same field: a list on the stack from the second item)."""
    later = 1 if k else 0
    t = parent.type
    if t == "if_statement":  # IF e THEN stmt_list elseif_list (ELSIF ... | ELSE ...) END_IF
        return {"condition": 1, "consequence": 3 + later}.get(field, 5)
    if t == "elsif_clause":  # elseif_list ELSIF e THEN stmt_list
        return 1 if field == "condition" else 3 + later
    if t == "else_clause":  # ELSE stmt_list
        return 1 + later
    if t == "case_statement":  # CASE e OF case_element_list ELSE ...
        return {"subject": 1, "case_clause": 3 + later}.get(field, 4)
    if t == "case_clause":  # case_list ',' value ... ':' stmt_list
        return 2 * later if field == "case_value" else 2 + later
    if t == "for_statement":  # FOR v := e TO e BY e DO stmt_list END_FOR
        has_step = parent.child_by_field_name("step") is not None
        return {"control": 1, "start": 3, "end": 5, "step": 7}.get(
            field, (9 if has_step else 7) + later)
    if t == "while_statement":  # WHILE e DO stmt_list
        return 1 if field == "condition" else 3 + later
    if t == "repeat_statement":  # REPEAT stmt_list UNTIL e
        return 3 if field == "condition" else 1 + later
    if t in ("assignment_statement", "named_argument", "structure_initializer_field"):
        return 2 if field in ("right", "value") else 0  # x := e, name := e, name => v
    if t == "typed_literal":  # DINT#-5 is DINT, '#' and -5; BOOL#1 is one token
        type_node = parent.child_by_field_name("type")
        is_bool = type_node is not None and type_node.text is not None and \
            type_node.text.upper() == b"BOOL"
        return 0 if field != "value" else 1 if is_bool else 2
    if t in ("binary_expression", "member_access_expression", "subrange"):
        return 2 if field in ("right", "member", "upper", "value") else 0  # a op b, T#v
    if t in ("unary_expression", "parenthesized_expression"):
        return 1
    if t == "call_expression":  # f '(' param_list ')'
        return 2 if field == "arguments" else 0
    if t == "argument_list":  # param_list ',' param (relative to the call's '(')
        return 2 * later
    if t == "index_expression":  # v '[' subscript_list ',' e ']'
        return 0 if field == "object" else 2 + 2 * later
    if t == "structure_initializer":  # '(' field_init_list ',' field_init ')'
        return 1 + 2 * later
    if t == "variable_declaration":  # names ':' type ':=' initial value
        return {"names": 0, "type": 2}.get(field, 4)
    if t in _ZERO_PREFIX:
        return 0
    return 2  # anything else (declarations, types): more than any measured construct part


def _closing(node: ts.Node) -> int:
    """Symbols a construct holds when MatIEC reduces it (its own length in the grammar)."""
    t = node.type
    if t == "if_statement":
        return 6  # IF e THEN stmt_list elseif_list END_IF (an ELSE counts in else_clause)
    if t == "else_clause":
        return 3  # ELSE stmt_list END_IF / END_CASE, after the IF's 5 or the CASE's 4
    if t == "for_statement":
        return 11 if node.child_by_field_name("step") is not None else 9
    if t in ("case_statement", "while_statement", "repeat_statement"):
        return 5
    if t in ("elsif_clause", "call_expression", "index_expression", "variable_declaration"):
        return 4
    if t == "unary_expression":
        return 2
    if t == "typed_literal":  # BOOL#1 is one token
        return 2 if _prefix(node, "value", 0) == 1 else 3
    if t == "argument_list":
        return 1  # its items; the call's own closing counts the parentheses
    return 3  # a op b, ( e ), x := e, v . f, stmt ';' after stmt_list, ...


# leaves whose count depends on their text; statements that are one token and its ';' (2)
_TEXT_LEAVES = frozenset({"time_literal", "date_literal", "time_of_day_literal",
                          "date_and_time_literal", "integer_literal", "real_literal"})
_STATEMENT_LEAVES = frozenset({"empty_statement", "exit_statement", "return_statement",
                               "continue_statement"})


def _leaf(node: ts.Node) -> int:
    """Symbols a token sequence without named children takes (measured one by one)."""
    t = node.type
    if t not in _TEXT_LEAVES:
        return 2 if t in _STATEMENT_LEAVES else 1
    text = node.text.decode("utf-8", "replace") if node.text is not None else ""
    if t == "time_literal":  # T#1h2m3s 7, TIME#1s 8, T#-1s 8, TIME#-1s 9
        return 7 + (1 if text.upper().startswith("TIME#") else 0) + (1 if "#-" in text else 0)
    if t == "date_literal":  # D#.. 6, DATE#.. 7
        return 6 if text[:2].upper() == "D#" else 7
    if t == "time_of_day_literal":
        return 7
    if t == "date_and_time_literal":
        return 9
    return 2 if text[:1] in "+-" else 1  # integer_literal, real_literal
