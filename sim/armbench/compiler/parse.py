"""Parse: ST text -> tree-sitter syntax tree, with syntax errors as diagnostics.

Uses the established `tree-sitter-iec61131-3-st` grammar. One gap of that grammar is patched
here without moving any position: typed enumeration literals (`Mode#RUN`) are not in it, so
their `#` is replaced by `_` before parsing and the byte offsets are remembered; the lowering
turns identifiers spanning such an offset back into enum literals.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import tree_sitter as ts
import tree_sitter_iec61131_3_st as st_grammar

from .config_syntax import CONFIGURATION, RESOURCE, ConfigurationHints
from .diagnostics import Diagnostics
from .source import SourcePos

# Prefixes whose `#` the grammar already understands (typed literals, time/date literals).
_GRAMMAR_PREFIXES = {
    "BOOL", "SINT", "INT", "DINT", "LINT", "USINT", "UINT", "UDINT", "ULINT", "BYTE", "WORD",
    "DWORD", "LWORD", "REAL", "LREAL", "TIME", "T", "LTIME", "LT", "DATE", "D", "TIME_OF_DAY",
    "TOD", "DATE_AND_TIME", "DT", "STRING", "WSTRING", "CHAR", "WCHAR",
}
_ENUM_LITERAL = re.compile(r"\b([A-Za-z_]\w*)#([A-Za-z_]\w*)")


@dataclass
class ParsedFile:
    path: str
    text: str
    data: bytes
    tree: ts.Tree
    enum_hash_offsets: frozenset[int]
    line_starts: list[int]
    ascii_lines: dict[int, bool] = field(default_factory=dict)  # row -> all bytes ASCII
    # set by the nesting guard when the file is shallow enough for the recursive passes
    guarded: bool = False

    def pos(self, node: ts.Node) -> SourcePos:
        point = node.start_point  # a new object per call: asked once
        return SourcePos(self.path, point.row + 1, self._col(point))

    def pos_at_byte(self, offset: int) -> SourcePos:
        line = 0
        lo, hi = 0, len(self.line_starts) - 1
        while lo <= hi:
            mid = (lo + hi) // 2
            if self.line_starts[mid] <= offset:
                line, lo = mid, mid + 1
            else:
                hi = mid - 1
        col = len(self.data[self.line_starts[line]:offset].decode("utf-8", "replace")) + 1
        return SourcePos(self.path, line + 1, col)

    def _col(self, point: ts.Point) -> int:
        row = point.row
        if row >= len(self.line_starts):
            return point.column + 1
        ascii_ = self.ascii_lines.get(row)
        if ascii_ is None:  # a 100,000-term line is decoded once, not once per position
            end = self.line_starts[row + 1] if row + 1 < len(self.line_starts) else None
            ascii_ = self.ascii_lines[row] = self.data[self.line_starts[row]:end].isascii()
        if ascii_:
            return point.column + 1
        start = self.line_starts[row]
        return len(self.data[start:start + point.column].decode("utf-8", "replace")) + 1

    def text_of(self, node: ts.Node) -> str:
        return self.data[node.start_byte:node.end_byte].decode("utf-8", "replace")


def _parser() -> ts.Parser:
    return ts.Parser(ts.Language(st_grammar.language()))


def _mask_enum_literals(text: str) -> tuple[str, frozenset[int]]:
    hits = [m.start(2) - 1 for m in _ENUM_LITERAL.finditer(text)
            if m.group(1).upper() not in _GRAMMAR_PREFIXES]
    if not hits:
        return text, frozenset()
    chars = list(text)
    offsets: set[int] = set()
    ascii_ = text.isascii()
    done_chars = done_bytes = 0  # byte offsets counted on from the last hit: linear in size
    for i in hits:
        chars[i] = "_"
        if not ascii_:
            done_bytes += len(text[done_chars:i].encode("utf-8"))
            done_chars = i
        offsets.add(i if ascii_ else done_bytes)
    return "".join(chars), frozenset(offsets)


# A duration literal with '_' between its parts or digits (T#1h_30m, t#5d_14h_12m_18s_3.5ms,
# T#1_000ms): IEC 61131-3 allows them and MatIEC reads them; the grammar does not.
_DURATION = re.compile(r"(?i)\b(?:T|TIME|LT|LTIME)#-?"
                       r"(?:\d[\d_]*(?:\.\d[\d_]*)?(?:ms|us|ns|d|h|m|s)_?)+(?![\w.])")


def _drop_duration_underscores(text: str) -> str:
    """``text`` with the '_' of its duration literals moved behind them as blanks: the
    literal reads as the grammar wants (T#1h30m), and no other position moves (ASCII only)."""
    if "#" not in text or "_" not in text:
        return text

    def fix(m: re.Match[str]) -> str:
        lit = m.group(0)
        bare = lit.replace("_", "")
        return bare + " " * (len(lit) - len(bare))

    return _DURATION.sub(lambda m: fix(m) if "_" in m.group(0) else m.group(0), text)


def _line_starts(data: bytes) -> list[int]:
    starts = [0]
    i = data.find(b"\n")
    while i >= 0:
        starts.append(i + 1)
        i = data.find(b"\n", i + 1)
    return starts


def pragma_code(text: str) -> str:
    """The C of a pragma's text, its braces taken off."""
    return text[1:-1] if text.startswith("{") and text.endswith("}") else text


def pragma_has_code(text: str) -> bool:
    """Whether a pragma holds C beyond comments and blanks (something a build would run)."""
    code = re.sub(r"/\*.*?\*/|//[^\n]*", " ", pragma_code(text), flags=re.S)
    return code.strip() != ""


def strip_upload_lines(text: str) -> str:
    """``text`` with the lines OpenPLC v3's upload takes out before MatIEC blanked: the
    editor's C debugger trailer, ``(*DBG:...*)``, and ``(*FILE:path line*)``, each a whole line
    (webserver/openplc.py, compile_program: `line.startswith('(*DBG:') and
    line.endswith('*)')` on the text split at '\\n'). Their C would otherwise be read as a
    comment that ends at the first ``*)`` of the C. Blanking keeps every line number."""
    if "(*DBG:" not in text and "(*FILE:" not in text:
        return text
    lines = text.split("\n")
    for i, line in enumerate(lines):
        if line.startswith(("(*DBG:", "(*FILE:")) and line.endswith("*)") or (
                line.startswith("(*FILE:c_blocks_code.cpp") and 'extern "C" void' in line):
            lines[i] = ""
    return "\n".join(lines)


def parse_text(path: str, text: str, diags: Diagnostics) -> ParsedFile:
    text = _drop_duration_underscores(strip_upload_lines(text))
    masked, offsets = _mask_enum_literals(text)
    data = masked.encode("utf-8")
    tree = _parser().parse(data)
    line_starts = _line_starts(data)
    pf = ParsedFile(path, text, data, tree, offsets, line_starts)
    _report_syntax_errors(pf, diags)
    return pf


def _report_syntax_errors(pf: ParsedFile, diags: Diagnostics) -> None:
    if not pf.tree.root_node.has_error:
        return
    hints = ConfigurationHints(pf)
    # each node with the innermost CONFIGURATION or RESOURCE around it (for E0111's hints)
    stack: list[tuple[ts.Node, str | None]] = [(pf.tree.root_node, None)]
    while stack:
        node, context = stack.pop()
        if node.is_missing and is_array_default_hole(node):
            continue
        if node.is_missing or node.type == "ERROR":
            hint = hints.hint(node, context)
            if hint is not None:
                diags.error(pf.pos(node), "E0111", hint)
            elif node.type == "ERROR" and _sized_string(node):
                diags.error(pf.pos(node), "E0120", "STRING[n]: OpenPLC v3's MatIEC loses the "
                            "variable (\"not declared\" where it is used; iec2c crashes when "
                            "it is not used): declare STRING (126 bytes)")
            elif node.type == "ERROR":
                diags.error(pf.pos(node), "E0100", _describe_error(pf, node))
            elif node.type == ";" and _after_end_struct(pf.data, node.start_byte):
                diags.error(pf.pos(node), "E0107", "missing ';' after END_STRUCT: MatIEC "
                            "needs END_STRUCT; inside TYPE ... END_TYPE")
            else:
                diags.error(pf.pos(node), "E0100", f"syntax error: missing '{node.type}'")
            continue
        if node.has_error:
            inner = node.type if node.type in (CONFIGURATION, RESOURCE) else context
            stack.extend((child, inner) for child in reversed(node.children))


def _sized_string(node: ts.Node) -> bool:
    """`STRING[n]` or `WSTRING[n]`: the grammar reads the `[n]` after a string type as an
    error."""
    prev = node.prev_sibling
    first = node.children[0] if node.children else None
    return prev is not None and prev.type == "string_type" and first is not None and \
        first.type == "["


def is_array_default_hole(node: ts.Node) -> bool:
    """The grammar has no array initialiser in a TYPE or STRUCT field default
    (`T : ARRAY[0..2] OF INT := [1, 2, 3];`): it reads `[...]` as an index expression on a
    missing name. That shape is valid ST; the lowering turns it into an array initialiser."""
    parent = node.parent
    if parent is None or parent.type != "index_expression":
        return False
    if parent.child_by_field_name("object") != node:
        return False
    owner = parent.parent
    return owner is not None and owner.type in ("type_definition", "structure_field")


def _after_end_struct(data: bytes, offset: int) -> bool:
    """Whether END_STRUCT is the last word before ``offset`` (looks back over whitespace only:
    a file with thousands of syntax errors is still read once, not once per error)."""
    i = offset
    while i > 0 and data[i - 1] in b" \t\r\n":
        i -= 1
    return data[max(0, i - len(b"END_STRUCT")):i].upper() == b"END_STRUCT"


def _describe_error(pf: ParsedFile, node: ts.Node) -> str:
    # the first 40 characters of the first non-blank line, read from a bounded slice
    head = pf.data[node.start_byte:min(node.end_byte, node.start_byte + 4096)]
    snippet = head.decode("utf-8", "replace").strip().splitlines()
    first = snippet[0][:40] if snippet else ""
    prev = node.prev_sibling
    if prev is not None and _after_end_struct(pf.data, prev.end_byte):
        return "syntax error: ';' expected after END_STRUCT (write END_STRUCT;)"
    if first:
        return f"syntax error: unexpected '{first}'"
    return "syntax error"
