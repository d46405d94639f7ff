"""Front end of one file: read it, parse it, then the checks that need only its syntax tree.

The nesting guard (nesting.py) runs first, before anything walks the tree recursively or
lowers it: a file nested deeper than the passes can recurse is reported (E0108) and never
lowered. The lexical rules (rules.py) walk the tree with a stack of their own.
"""

from __future__ import annotations

from pathlib import Path

from .diagnostics import Diagnostics
from .nesting import check_nesting
from .parse import ParsedFile, parse_text
from .rules import check_rules
from .source import SourcePos, decode_source

# A lexical rule explains its line better than the generic syntax error the parser gives there.
_EXPLAINING = frozenset({"E0101", "E0102", "E0103", "E0104", "E0107"})


def read_parse(path: Path, diags: Diagnostics) -> ParsedFile | None:
    """The file's syntax tree (syntax errors as E0100), or None when it cannot be read."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        diags.error(SourcePos(str(path), 1, 1), "E0001", f"cannot read {path}: {exc}")
        return None
    return parse_source(path, data, diags)


def parse_source(path: Path, data: bytes, diags: Diagnostics) -> ParsedFile | None:
    """The syntax tree of the file ``path`` whose bytes are ``data`` (None: not text)."""
    try:
        src = decode_source(data)
    except UnicodeDecodeError as exc:
        diags.error(SourcePos(str(path), 1, 1), "E0001", f"cannot read {path}: {exc}")
        return None
    if src.assumed:
        diags.note(SourcePos(str(path), 1, 1), "N0001", "not valid UTF-8: read as "
                   "Windows-1252 (cp1252), as CODESYS V2 writes it")
    return parse_text(str(path), src.text, diags)


def check_syntax(pf: ParsedFile, diags: Diagnostics) -> None:
    """The nesting guard, then the lexical portability rules."""
    check_nesting(pf, diags)
    check_rules(pf, diags)


def drop_syntax_cascades(diags: Diagnostics) -> None:
    """A lexical rule (E0101-E0104, E0107) already explains the line: drop generic syntax
    errors there."""
    explained = {(d.pos.file, d.pos.line) for d in diags.items if d.code in _EXPLAINING}
    if explained:
        diags.keep(lambda d: not (d.code == "E0100" and (d.pos.file, d.pos.line) in explained))
