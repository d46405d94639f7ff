"""Limits: how deep ST may nest, checked on the syntax tree before any recursive pass runs.

The passes after parsing (lower, resolve, emit_c, ffi) walk nested statements, expressions and
types recursively. A file nested deeper than NESTING_LIMIT gets one E0108 diagnostic and is not
lowered, so those walks stay far inside Python's recursion limit. The check itself walks the
tree with an explicit stack.

Left-associative chains of binary operators (`a + b + c + ...`, thousands of terms) are flat
code, not nesting: a binary expression that is the left operand of another adds no level, and
every pass walks such chains in a loop.

The limit is far above what real code needs (the C standard guarantees 63 nested parentheses
and 127 nested blocks, CPython's own parser stops at 200 nested parentheses) and below what
MatIEC's parser holds (bison's default 10,000-entry stack, which MatIEC's sources do not raise):
MatIEC accepts such files, the bench deliberately does not.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import tree_sitter as ts

if TYPE_CHECKING:  # diagnostics.py reads the limit for its table: no import cycle at run time
    from .diagnostics import Diagnostics
    from .parse import ParsedFile

# Levels of statements, parentheses, operators, calls, indices (E0108) and of types and
# instances held inside each other (E0211). The deepest pass spends about three Python frames
# per level (typing a call: expr -> call -> bind -> expr), so 200 levels stay ~600 frames, well
# inside Python's default limit of 1000 even when the caller is itself deep in a stack
# (tests/compiler/test_limits.py checks this with 250 frames in use).
NESTING_LIMIT = 200

# Nodes that always sit between a counted parent and its counted children (an argument list,
# an ELSIF branch, a CASE clause): they add no level of their own.
_TRANSPARENT = frozenset({
    "argument_list", "named_argument", "elsif_clause", "else_clause", "case_clause",
    "case_value", "subrange", "assignment_statement", "invocation_statement", "structure_field",
    "variable_declaration", "structure_initializer_field", "comment", "pragma",
})


def check_nesting(pf: ParsedFile, diags: Diagnostics, limit: int = NESTING_LIMIT) -> None:
    """Report (once per file) the first construct that nests deeper than `limit` levels."""
    # the declarations of a file (POUs, TYPE blocks, the CONFIGURATION) are level 0
    stack: list[tuple[ts.Node, int]] = [(c, 0) for c in reversed(pf.tree.root_node.children)]
    while stack:
        node, depth = stack.pop()
        if depth > limit:
            diags.error(pf.pos(node), "E0108", f"nesting deeper than {limit} levels "
                        "(statements, parentheses, operators, calls, indices): move the "
                        "inner part into a variable or a FUNCTION")
            return
        children = node.named_children
        for i in range(len(children) - 1, -1, -1):
            child = children[i]
            stack.append((child, depth + _levels(node, child)))


def _levels(parent: ts.Node, child: ts.Node) -> int:
    if child.type in _TRANSPARENT or child.named_child_count == 0:  # names, literals
        return 0
    if child.type == "binary_expression" and parent.type == "binary_expression" and \
            parent.child_by_field_name("left") == child:
        return 0
    return 1
