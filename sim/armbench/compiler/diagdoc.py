"""Render docs/diagnostics.md from the CODES table (a test fails when the page is stale)."""

from __future__ import annotations

import sys

from .diagnostics import CODES

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


def render() -> str:
    rows = "".join(f"| {code} | {title} | {fix} |\n" for code, (title, fix) in CODES.items())
    return HEADER + rows


if __name__ == "__main__":
    sys.stdout.write(render())
