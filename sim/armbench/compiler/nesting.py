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


# What a construct keeps on MatIEC's stack while one of its parts is parsed: by node type, the
# part's field -> (symbols, more symbols once a list of that part is on the stack, i.e. from
# its second item), and the same pair for any other field. One table lookup per part: the
# guard visits every node of every file, and a chain of tests per part cost 40 % of the
# front end of st/.
_Part = tuple[int, int]
_PREFIXES: dict[str, tuple[dict[str, _Part], _Part]] = {
    # IF e THEN stmt_list elseif_list (ELSIF ... | ELSE ...) END_IF
    "if_statement": ({"condition": (1, 0), "consequence": (3, 1)}, (5, 0)),
    "elsif_clause": ({"condition": (1, 0)}, (3, 1)),  # elseif_list ELSIF e THEN stmt_list
    "else_clause": ({}, (1, 1)),  # ELSE stmt_list
    # CASE e OF case_element_list ELSE ...
    "case_statement": ({"subject": (1, 0), "case_clause": (3, 1)}, (4, 0)),
    "case_clause": ({"case_value": (0, 2)}, (2, 1)),  # case_list ',' value ... ':' stmt_list
    # FOR v := e TO e BY e DO stmt_list END_FOR (the body's place: _for_prefixes)
    "for_statement": ({"control": (1, 0), "start": (3, 0), "end": (5, 0), "step": (7, 0)},
                      (7, 1)),
    "while_statement": ({"condition": (1, 0)}, (3, 1)),  # WHILE e DO stmt_list
    "repeat_statement": ({"condition": (3, 0)}, (1, 1)),  # REPEAT stmt_list UNTIL e
    # x := e, name := e, name => v
    "assignment_statement": ({"right": (2, 0), "value": (2, 0)}, (0, 0)),
    "named_argument": ({"right": (2, 0), "value": (2, 0)}, (0, 0)),
    "structure_initializer_field": ({"right": (2, 0), "value": (2, 0)}, (0, 0)),
    # DINT#-5 is DINT, '#' and -5; BOOL#1 is one token (the value's place: _typed_prefix)
    "typed_literal": ({"value": (2, 0)}, (0, 0)),
    # a op b, v . f, lo .. hi, T#v
    **{t: ({"right": (2, 0), "member": (2, 0), "upper": (2, 0), "value": (2, 0)}, (0, 0))
       for t in ("binary_expression", "member_access_expression", "subrange")},
    "unary_expression": ({}, (1, 0)),
    "parenthesized_expression": ({}, (1, 0)),
    "call_expression": ({"arguments": (2, 0)}, (0, 0)),  # f '(' param_list ')'
    "argument_list": ({}, (0, 2)),  # param_list ',' param (relative to the call's '(')
    "index_expression": ({"object": (0, 0)}, (2, 2)),  # v '[' subscript_list ',' e ']'
    "structure_initializer": ({}, (1, 2)),  # '(' field_init_list ',' field_init ')'
    "variable_declaration": ({"names": (0, 0), "type": (2, 0)}, (4, 0)),  # names ':' type := v
    **{t: ({}, (0, 0)) for t in _ZERO_PREFIX},
}
# anything else (declarations, types): more than any measured construct part
_OTHER_PREFIX: tuple[dict[str, _Part], _Part] = ({}, (2, 0))
# Symbols a construct holds when MatIEC reduces it (its own length in the grammar); 3 for
# anything not named: a op b, ( e ), x := e, v . f, stmt ';' after stmt_list, ... (FOR and
# typed literals depend on their parts: _for_prefixes, _typed_prefix)
_CLOSING = {
    "if_statement": 6,  # IF e THEN stmt_list elseif_list END_IF (an ELSE counts in else_clause)
    "else_clause": 3,  # ELSE stmt_list END_IF / END_CASE, after the IF's 5 or the CASE's 4
    "case_statement": 5, "while_statement": 5, "repeat_statement": 5,
    "elsif_clause": 4, "call_expression": 4, "index_expression": 4, "variable_declaration": 4,
    "unary_expression": 2,
    "argument_list": 1,  # its items; the call's own closing counts the parentheses
}
_ROOM_FOR_DECLARATIONS = _POUS | {"type_declaration", "configuration_declaration"}


def _for_prefixes(node: ts.Node) -> tuple[dict[str, _Part], _Part, int]:
    """A FOR's part table, default and closing: its body comes after BY e when it has one."""
    if node.child_by_field_name("step") is None:
        return (*_PREFIXES["for_statement"], 9)
    return _PREFIXES["for_statement"][0], (9, 1), 11


def _typed_prefix(node: ts.Node) -> tuple[dict[str, _Part], _Part, int]:
    """A typed literal's part table, default and closing: BOOL#1 is one token, DINT#-5 three."""
    type_node = node.child_by_field_name("type")
    if type_node is not None and type_node.text is not None and \
            type_node.text.upper() == b"BOOL":
        return {"value": (1, 0)}, (0, 0), 2
    return (*_PREFIXES["typed_literal"], 3)


# The most symbols a token sequence without named children takes (_leaf: DT#... is 9,
# TIME#-1s 9): a name or literal with more room than that left cannot be too deep, and is not
# visited at all (more than half of a file's nodes).
_MAX_LEAF = 9


def check_nesting(pf: ParsedFile, diags: Diagnostics, limit: int = NESTING_LIMIT) -> None:
    """Report (once per file) the first construct nested too deep for MatIEC or the bench.

    A depth-first walk in source order; each entry of the work list is a node, the symbols on
    MatIEC's stack when it starts (its prefix included), the symbols MatIEC leaves its
    statement or declaration, its levels of syntax tree (the bench's guard), its type and its
    number of named children."""
    names = _kind_names(pf.tree.language)
    work: list[tuple[ts.Node, int, int, int, str, int]] = [
        (c, 0, PARSER_STACK, 0, names.get(c.kind_id) or c.type, c.named_child_count)
        for c in reversed(pf.tree.root_node.named_children)]
    prefixes, closings, transparent = _PREFIXES, _CLOSING, _TRANSPARENT
    while work:
        node, stack, room, levels, t, count = work.pop()
        if not count:  # a name or literal close to the limit
            peak = stack + _leaf(node)
            if peak > room:
                diags.error(pf.pos(node), "E0108", _matiec_message(node, room, peak))
                return
            continue
        if t == "for_statement":
            parts, default, closing = _for_prefixes(node)
        elif t == "typed_literal":
            parts, default, closing = _typed_prefix(node)
        else:
            parts, default = prefixes.get(t, _OTHER_PREFIX)
            closing = closings.get(t, 3)
        if stack + closing > room:
            diags.error(pf.pos(node), "E0108", _matiec_message(node, room, stack + closing))
            return
        if levels > limit:
            diags.error(pf.pos(node), "E0108", f"nesting deeper than {limit} levels "
                        "(statements, parentheses, operators, calls, indices, field accesses; "
                        "a limit of the bench): move the inner part into a variable or a "
                        "FUNCTION")
            return
        children: list[tuple[ts.Node, int, int, int, str, int]] = []
        seen: dict[str, int] = {}  # statements / list items already parsed, per field
        pou = t in _POUS
        declarations = t in _ROOM_FOR_DECLARATIONS
        items = t in _LISTS
        binary = t == "binary_expression"
        for i, child in enumerate(node.named_children):
            ct = names.get(child.kind_id) or child.type
            field = node.field_name_for_named_child(i) or ("item" if items else ct)
            k = seen.get(field, 0)
            if ct not in _NOT_STATEMENTS:
                seen[field] = k + 1
            if pou and field in _STATEMENT_FIELDS:
                child_room, start = STATEMENT_ROOM[t], 1 if k else 0  # statement_list from the 2nd
            elif declarations:
                child_room, start = DECLARATION_ROOM, 0
            else:
                base, later = parts.get(field, default)
                child_room, start = room, stack + base + (later if k else 0)
            grandchildren = child.named_child_count
            if not grandchildren:
                if start + _MAX_LEAF > child_room:
                    children.append((child, start, child_room, levels, ct, 0))
                continue
            # the parts MatIEC has no level for, and the left operand of a binary operator
            # (chains are flat), add no level
            deeper = 0 if (ct in transparent or
                           (binary and field == "left" and ct == "binary_expression")) else 1
            children.append((child, start, child_room, levels + deeper, ct, grandchildren))
        work.extend(reversed(children))
    pf.guarded = True


def _kind_names(language: ts.Language) -> dict[int, str]:
    """The node type names of ``language`` by kind id: one shared string each, where
    Node.type makes a new one per call (a few hundred names: cheap to list per file; ERROR,
    65535, is not among them)."""
    return {i: language.node_kind_for_id(i) or "" for i in range(language.node_kind_count)}


def _matiec_message(node: ts.Node, room: int, peak: int) -> str:
    counts: dict[str, int] = {}
    up: ts.Node | None = node
    while up is not None:
        name = _NAMES.get(up.type)
        if name is not None:
            counts[name] = counts.get(name, 0) + 1
        up = up.parent
    ranked = sorted(counts.items(), key=lambda kv: -kv[1])
    what = ", ".join(f"{n} nested {name}" for name, n in ranked)
    return (f"nesting too deep for MatIEC ({what or 'nested constructs'}): its parser needs "
            f"{peak} of the {room} stack entries left here and OpenPLC's build stops with a "
            f"syntax error (e.g. at most 63 nested IFs or {MAX_PARENTHESES} nested "
            "parentheses): move the inner part into a variable or a FUNCTION")


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
