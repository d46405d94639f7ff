"""Limits: how deep ST may nest, the figures that the nesting guard (nesting.py), the type
depth check (containment.py) and the diagnostics table and page (diagnostics.py, diagdoc.py)
share. Constants only: every module may import it, it imports nothing.

How they are checked and where the figures come from: nesting.py (E0108) and
containment.py (E0211); the measurements on OpenPLC's iec2c: docs/diagnostics.md, Limits.
"""

from __future__ import annotations

# Levels of syntax tree (E0108, the bench's guard) and of types and instances held inside each
# other (E0211). The deepest pass spends about three Python frames per level (typing a call:
# expr -> call -> bind -> expr), so 200 levels stay ~600 frames, well inside Python's default
# limit of 1000 even when the caller is itself deep in a stack (tests/compiler/test_limits.py
# checks this with 250 frames in use).
NESTING_LIMIT = 200

# MatIEC's parser stack: YYINITDEPTH entries, of which the file's outer context (library, POU
# header, declaration blocks) takes a fixed part. What is left, measured as the peak that still
# passes: `x := (((...(x)...)))` with 189 parentheses peaks at x, :=, 188 x '(' and '(' expr ')'
# = 193 symbols in a PROGRAM or FUNCTION_BLOCK, 188 parentheses = 192 in a FUNCTION; a VAR
# initial value `(n := (n := ... (v := 1)))` passes 61 levels and fails at 62 (191 symbols).
PARSER_STACK = 200
STATEMENT_ROOM = {"program_declaration": 193, "function_block_declaration": 193,
                  "function_declaration": 192}
DECLARATION_ROOM = 191
# The parenthesised nesting MatIEC allows for a statement of a PROGRAM, for the messages.
MAX_PARENTHESES = STATEMENT_ROOM["program_declaration"] - 4
