"""Render docs/diagnostics.md from the CODES table (a test fails when the page is stale)."""

from __future__ import annotations

import sys

from .diagnostics import CODES
from .limits import NESTING_LIMIT

HEADER = """# Diagnostics of `armbench check`

Generated from `sim/armbench/compiler/diagnostics.py` by
`python -m armbench.compiler.diagdoc > docs/diagnostics.md`; do not edit by hand.

Every diagnostic is one line, `file:line:col: error[CODE]: message` (notes, `note[N...]`,
do not fail the check). `armbench check` ends with a one-line summary. The portability rules
mirror what MatIEC (the compiler inside OpenPLC) or OpenPLC's C build rejects, as measured on
the real tools (see DESIGN.md §5.1): code that passes `armbench check` compiles there too.

| code | what it means | what to write instead |
|---|---|---|
"""


LIMITS = f"""
## Limits (E0108, E0210, E0211)

- **Nesting (E0108).** Statements, parentheses, unary operators, operands, calls, indices and
  field accesses may nest at most {NESTING_LIMIT} levels inside one another (counted on the syntax
  tree; an ELSIF branch, a CASE clause or an argument list adds no level of its own). The C
  standard guarantees 63 nested parentheses and 127 nested blocks, CPython stops at 200 nested
  parentheses; MatIEC's parser (bison, default 10,000-entry stack) holds more, so this is a
  limit of the bench, reported once per file at the first construct beyond it.
- **Long chains are not nesting.** `a + b + c + ...`, `x AND y AND z ...` and other
  left-associative chains of binary operators may have any length (tested to 20,000 terms);
  the C for them is split into temporaries every 100 operators, so gcc never sees deep
  expressions. Long ELSIF and CASE lists and long call graphs are flat as well.
- **Containment (E0210).** A STRUCT may not contain itself, directly, through other STRUCTs or
  through an ARRAY of itself; a FUNCTION_BLOCK may not hold an instance of itself, directly or
  through other FBs. Each cycle group is reported once, at the declaration that comes first
  in the file, naming one cycle: `STRUCT A contains itself through A.b -> B.a`. VAR_IN_OUT
  and VAR_EXTERNAL are references, not containment.
- **Type depth (E0211).** STRUCTs, ARRAY types and FB instances may hold one another at most
  {NESTING_LIMIT} levels deep (an alias `TYPE T1 : T2; END_TYPE` adds no level).
"""


def render() -> str:
    rows = "".join(f"| {code} | {title} | {fix} |\n" for code, (title, fix) in CODES.items())
    return HEADER + rows + LIMITS


if __name__ == "__main__":
    sys.stdout.write(render())
