"""ST text for the exports: slices of the source (POU bodies, comments) and AST -> ST text.

Needs: the source text of a file that passed the checker and its AST (source positions are
1-based lines and character columns). The scanner knows only what it must skip to find
keywords reliably: ``(* *)`` comments (never nested in portable ST) and string literals.
"""

from __future__ import annotations

import re
from bisect import bisect_right
from dataclasses import dataclass

from ..compiler import ast as A
from ..compiler.source import SourcePos

_TOKEN = re.compile(
    r"(?P<comment>\(\*.*?\*\))|(?P<string>'[^']*'|\"[^\"]*\")|(?P<word>[A-Za-z0-9_]+)|(?P<ws>\s+)|."
    , re.DOTALL)
_RULER = re.compile(r"^\s*[-=*]{8,}\s*$")


@dataclass(frozen=True)
class Token:
    kind: str  # "comment" | "string" | "word" | "other"
    text: str
    start: int
    end: int


class SourceText:
    """A file's text with its tokens, and offsets for source positions."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.line_starts = [0] + [m.end() for m in re.finditer("\n", text)]
        self.tokens: list[Token] = []
        for m in _TOKEN.finditer(text):
            kind = m.lastgroup or "other"
            if kind != "ws":
                self.tokens.append(Token(kind, m.group(), m.start(), m.end()))
        self._starts = [t.start for t in self.tokens]

    def offset(self, pos: SourcePos) -> int:
        return self.line_starts[pos.line - 1] + pos.col - 1

    def line_of(self, offset: int) -> int:
        return bisect_right(self.line_starts, offset)  # 1-based

    def token_index(self, offset: int) -> int:
        """Index of the first token starting at or after offset."""
        return bisect_right(self._starts, offset - 1)

    def pou_body(self, pou: A.Pou) -> str:
        """The body of a POU: the source between its last END_VAR and its END_<kind>,
        without the blank lines around it (indentation and comments kept)."""
        end_kw = "END_" + pou.kind.upper()
        i = self.token_index(self.offset(pou.pos))
        decl_end: Token | None = None
        header_end: int | None = None
        for tok in self.tokens[i:]:
            if tok.kind != "word":
                continue
            word = tok.text.upper()
            if word == "END_VAR":
                decl_end = tok
            elif word == end_kw:
                if decl_end is not None:
                    start = decl_end.end
                else:  # no VAR block at all: the body starts on the line after the header
                    header_end = self.text.find("\n", self.offset(pou.pos))
                    start = len(self.text) if header_end < 0 else header_end + 1
                return _trim_blank_lines(self.text[start:tok.start])
        raise ValueError(f"{pou.pos}: no {end_kw} after {pou.kind} {pou.name}")

    def leading_comment(self, pos: SourcePos) -> str | None:
        """The text of the comment right before pos (only whitespace between), without
        its delimiters and ruler lines; None when there is none."""
        j = self.token_index(self.offset(pos)) - 1
        if j < 0 or self.tokens[j].kind != "comment":
            return None
        return _comment_text(self.tokens[j].text) or None

    def trailing_comment(self, pos: SourcePos) -> str | None:
        """The comment after the ``;`` ending the declaration at pos, on the same line."""
        i = self.token_index(self.offset(pos))
        for k in range(i, len(self.tokens) - 1):
            tok = self.tokens[k]
            if tok.kind == "other" and tok.text == ";":
                nxt = self.tokens[k + 1]
                if nxt.kind == "comment" and self.line_of(nxt.start) == self.line_of(tok.start):
                    return _comment_text(nxt.text)
                return None
        return None


def _comment_text(comment: str) -> str:
    """A comment's text: delimiters, ruler lines and common indentation removed."""
    lines = [ln.rstrip() for ln in comment[2:-2].split("\n")]
    first = lines[0].strip()
    rest = [ln for ln in lines[1:] if not _RULER.match(ln)]
    cut = min((len(ln) - len(ln.lstrip()) for ln in rest if ln.strip()), default=0)
    out = ([] if _RULER.match(first) or not first else [first]) + [ln[cut:] for ln in rest]
    return _trim_blank_lines("\n".join(out))


def _trim_blank_lines(text: str) -> str:
    lines = text.split("\n")
    while lines and not lines[0].strip():
        lines.pop(0)
    while lines and not lines[-1].strip():
        lines.pop()
    return "\n".join(ln.rstrip() for ln in lines)


# ------------------------------------------------------------------ AST -> ST text
_PREC = {"OR": 1, "XOR": 2, "AND": 3, "=": 4, "<>": 4, "<": 5, "<=": 5, ">": 5, ">=": 5,
         "+": 6, "-": 6, "*": 7, "/": 7, "MOD": 7, "**": 8}


def expr_text(e: A.Expr, parent_prec: int = 0) -> str:
    """ST text of an expression (initialisers, bounds, task parameters)."""
    if isinstance(e, A.Literal):
        if e.kind == "enum" and e.type_prefix:
            return f"{e.type_prefix}#{e.value}"
        return e.text
    if isinstance(e, A.Name):
        return e.name
    if isinstance(e, A.Member):
        return f"{expr_text(e.obj, 99)}.{e.member}"
    if isinstance(e, A.Index):
        return f"{expr_text(e.obj, 99)}[{', '.join(expr_text(i) for i in e.indices)}]"
    if isinstance(e, A.Unary):
        sep = " " if e.op.upper() == "NOT" else ""
        inner = f"{e.op}{sep}{expr_text(e.operand, 9)}"
        return f"({inner})" if parent_prec > 9 else inner
    if isinstance(e, A.Binary):
        # `a + b + c + ...` nests to the left as deep as it is long: walk it in a loop
        spine: list[tuple[A.Binary, int, int]] = []
        node: A.Expr = e
        while isinstance(node, A.Binary):
            p = _PREC.get(node.op.upper(), 0)
            spine.append((node, p, parent_prec))
            node, parent_prec = node.left, p
        text = expr_text(node, parent_prec)
        for b, p, outer in reversed(spine):
            inner = f"{text} {b.op} {expr_text(b.right, p + 1)}"
            text = f"({inner})" if p < outer else inner
        return text
    if isinstance(e, A.Call):
        args = ", ".join(
            (f"{a.name} {'=>' if a.is_output else ':='} " if a.name else "") + expr_text(a.value)
            for a in e.args)
        return f"{expr_text(e.callee, 99)}({args})"
    raise TypeError(f"{e.pos}: cannot render {type(e).__name__}")



# ------------------------------------------------------------------ declaration slices
_OPEN = {"STRUCT": "END_STRUCT", "(": ")", "[": "]"}


def declaration_span(st: SourceText, node: A.TypeDecl | A.Pou) -> tuple[int, int]:
    """(start, end) offsets of one declaration in the file: from the start of the line of
    its header comment (the comment right before it, only whitespace between) or of itself,
    to the end of its ``END_<kind>`` (a POU) or of the ``;`` ending it (one TYPE definition,
    inside its TYPE block)."""
    at = st.offset(node.pos)
    i = st.token_index(at)
    start = at
    if i > 0 and st.tokens[i - 1].kind == "comment":
        start = st.tokens[i - 1].start
    line_start = st.line_starts[st.line_of(start) - 1]
    if not st.text[line_start:start].strip():
        start = line_start
    closers: list[str] = []
    end_kw = "END_" + node.kind.upper() if isinstance(node, A.Pou) else None
    for tok in st.tokens[i:]:
        if tok.kind not in ("word", "other"):
            continue
        word = tok.text.upper()
        if end_kw is not None:
            if word == end_kw:
                return start, tok.end
        elif word in _OPEN:
            closers.append(_OPEN[word])
        elif closers and word == closers[-1]:
            closers.pop()
        elif not closers and word == ";":
            return start, tok.end
    raise ValueError(f"{node.pos}: no end of the declaration of {node.name}")


_LOCATED = re.compile(r"^(\w+)\s+AT\s+(%\S+?)\s*:\s*(.*?)\s*;$", re.IGNORECASE | re.DOTALL)


def monitor_friendly(st: SourceText, decls: list[A.VarDecl]) -> str:
    """The file's text with each located declaration in ``decls`` on a line of its own as
    ``Name AT %ADDR : TYPE;`` (single spaces), and any comment that shared its line on the
    lines above it. Why: the OpenPLC Runtime's Monitoring page (webserver/monitoring.py,
    parse_st) lists a located variable only from a line without ``(*`` or ``*)`` whose
    space-separated fields are name, AT, address, colon, type."""
    by_line: dict[int, list[tuple[int, int, str]]] = {}
    for d in decls:
        at = st.offset(d.pos)
        k = st.token_index(at)
        while k < len(st.tokens) and st.tokens[k].text != ";":
            k += 1
        if k == len(st.tokens):
            continue
        text = " ".join(st.text[at:st.tokens[k].end].split())
        m = _LOCATED.match(text)
        if m is None:  # e.g. two names before AT: left as written
            continue
        rest = re.sub(r"\s*:=\s*", " := ", m.group(3))
        by_line.setdefault(st.line_of(at), []).append(
            (at, st.tokens[k].end, f"{m.group(1)} AT {m.group(2)} : {rest};"))
    if not by_line:
        return st.text
    out: list[str] = []
    pos = 0
    for line in sorted(by_line):
        begin = st.line_starts[line - 1]
        if begin < pos:  # inside a span already rewritten (a comment reaching this line)
            continue
        end = st.text.find("\n", begin)
        end = len(st.text) if end < 0 else end
        # a comment that starts on this line may run on: take it whole
        for tok in st.tokens[st.token_index(begin):]:
            if tok.start >= end:
                break
            end = max(end, tok.end)
        nl = st.text.find("\n", end)
        end = len(st.text) if nl < 0 else nl
        line_text = st.text[begin:end]
        indent = line_text[:len(line_text) - len(line_text.lstrip())]
        spans = sorted(by_line[line])
        others: list[str] = []
        cut = begin
        for s, e, _ in spans:
            others.append(st.text[cut:s])
            cut = e
        others.append(st.text[cut:end])
        rest_text = " ".join(" ".join(others).split())
        out.append(st.text[pos:begin])
        if rest_text:
            out.append(indent + rest_text + "\n")
        out.append("\n".join(indent + new for _, _, new in spans))
        pos = end
    out.append(st.text[pos:])
    return "".join(out)
