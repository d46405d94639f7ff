"""Portability rules that are not typing: comments, literal forms, reserved and colliding names.

Needs: parsed files (lexical rules) and a CheckedProgram (name rules). Reserved names of every
dialect are in reserved.py; the variable names of MatIEC's standard library are a data file
in data/ (see docs/diagnostics.md for each rule).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from tree_sitter import Node

from . import ast as A
from .diagnostics import Diagnostics
from .parse import ParsedFile, pragma_code
from .reserved import matiec_refuses_name
from .source import SourcePos
from .symbols import CheckedProgram
from .types import ArrayType

DATA = Path(__file__).parent / "data"

# Upper-cased, these are C macros of the headers OpenPLC's C build includes.
_C_MACRO_RE = re.compile(
    r"^(EOF|NULL|BUFSIZ|FILENAME_MAX|RAND_MAX|EXIT_SUCCESS|EXIT_FAILURE|CHAR_BIT|NAN|INFINITY|"
    r"HUGE_VAL[FL]?|M_(E|LOG2E|LOG10E|LN2|LN10|PI|PI_2|PI_4|1_PI|2_PI|2_SQRTPI|SQRT2|SQRT1_2)|"
    r"FP_(NAN|INFINITE|ZERO|SUBNORMAL|NORMAL|ILOGB0|ILOGBNAN|FAST_FMAF?L?)|(U?INT(8|16|32|64)?|S?CHAR|U?SHRT|U?LONG|LLONG|"
    r"ULLONG|SIZE|PTRDIFF|INTMAX|UINTMAX|INTPTR|UINTPTR|WCHAR|SIG_ATOMIC)_(MAX|MIN)|"
    r"(FLT|DBL|LDBL)_(MAX|MIN|EPSILON|DIG|MANT_DIG|RADIX|ROUNDS|MAX_EXP|MIN_EXP|TRUE_MIN|"
    r"MAX_10_EXP|MIN_10_EXP|DECIMAL_DIG|HAS_SUBNORM)|SEEK_(SET|CUR|END)|PATH_MAX|NAME_MAX|"
    r"O_(RDONLY|WRONLY|RDWR|CREAT|EXCL|NOCTTY|TRUNC|APPEND|NONBLOCK|NDELAY|SYNC|DSYNC|RSYNC|"
    r"ASYNC|DIRECTORY|NOFOLLOW|CLOEXEC|DIRECT|LARGEFILE|NOATIME|PATH|TMPFILE|ACCMODE)|"
    r"S_I(FMT|FDIR|FCHR|FBLK|FREG|FIFO|FLNK|FSOCK|SUID|SGID|SVTX|RWXU|RUSR|WUSR|XUSR|RWXG|"
    r"RGRP|WGRP|XGRP|RWXO|ROTH|WOTH|XOTH|READ|WRITE|EXEC)|TRUE|FALSE|BOOL|__\w+)$")


@cache
def _names(file: str) -> frozenset[str]:
    lines = (DATA / file).read_text().splitlines()
    return frozenset(ln.strip().upper() for ln in lines if ln.strip() and not ln.startswith("#"))


def stdlib_variable_names() -> frozenset[str]:
    return _names("stdlib-variable-names.txt")


def is_c_macro(name: str) -> bool:
    up = name.upper()
    if up in _names("openplc-macros.txt"):
        return True
    errno_like = up.startswith("E") and re.fullmatch(r"E[A-Z]{3,}", up) is not None
    if errno_like:
        return up in _ERRNO_NAMES
    return _C_MACRO_RE.match(up) is not None


_ERRNO_NAMES = {"EPERM", "ENOENT", "ESRCH", "EINTR", "EIO", "ENXIO", "E2BIG", "ENOEXEC",
                "EBADF", "ECHILD", "EAGAIN", "ENOMEM", "EACCES", "EFAULT", "EBUSY", "EEXIST",
                "EXDEV", "ENODEV", "ENOTDIR", "EISDIR", "EINVAL", "ENFILE", "EMFILE",
                "ENOTTY", "EFBIG", "ENOSPC", "ESPIPE", "EROFS", "EMLINK", "EPIPE", "EDOM",
                "ERANGE", "EDEADLK", "ENOSYS", "ENOTEMPTY", "ETIMEDOUT", "EOVERFLOW"}

# ------------------------------------------------------------------ lexical rules
_LEADING_DOT = re.compile(rb"(?<![\w.\]#)])\.\d")
_TRAILING_DOT = re.compile(rb"(?<![\w#.])\d+\.(?![\d.])")


def check_rules(pf: ParsedFile, diags: Diagnostics) -> None:
    # A tree cursor, not node.children and node.parent: tree-sitter finds a node's parent by
    # walking down from the root, and lists of child nodes cost more the more nodes are alive,
    # so both would make a 20,000-token file cost far more than ten 2,000-token ones.
    cur = pf.tree.walk()
    above: list[str] = []  # types of the nodes above the cursor
    comment_spans: list[tuple[int, int]] = []
    pous: list[Node] = []  # the POUs entered so far: a pragma's is the last one around it
    while True:
        n = cur.node
        assert n is not None
        t = n.type
        descend = True
        if t in POU_NODES:
            pous.append(n)
        if t == "comment":
            descend = False
            text = pf.text_of(n)
            comment_spans.append((n.start_byte, n.end_byte))
            if text.startswith("//"):
                diags.error(pf.pos(n), "E0101", "'//' line comments are rejected by MatIEC: "
                            "use (* ... *)")
            elif text.startswith("/*"):
                diags.error(pf.pos(n), "E0102", "C-style /* */ comments are rejected by "
                            "MatIEC: use (* ... *)")
            elif text.startswith("(*") and "(*" in text[2:]:
                if _matiec_comment_end(text) != len(text):
                    diags.error(pf.pos(n), "E0102", "MatIEC reads the '(*' of '(*)' first, so "
                                "'(*)' does not end this comment: write '( *)' or end it with "
                                "' *)'")
                elif _stray_closer_after(pf.data, n.end_byte):
                    diags.error(pf.pos(n), "E0102", "nested (* (* *) *) comments are rejected "
                                "by MatIEC: use flat comments")
        elif t == "pragma":
            descend = False
            comment_spans.append((n.start_byte, n.end_byte))  # C comments in it are C's
            pou = next((p for p in reversed(pous) if p.end_byte > n.start_byte), None)
            why = pragma_failure(pf, n, pou, above[-1] if above else "")
            if why is not None:
                diags.error(pf.pos(n), "E0103", why)
        elif t == "unary_expression":
            operand = n.child_by_field_name("operand")
            # once per chain, at its first operator: `- - - x` is one mistake, not two
            chained = bool(above) and above[-1] == t and cur.field_name == "operand"
            if operand is not None and operand.type == t and not chained:
                diags.error(pf.pos(n), "E0105", "unsupported construct: a unary operator right "
                            f"after another ('{_snippet(pf, n)}'): MatIEC's grammar rejects "
                            "'NOT NOT b' and '- -x': write NOT (NOT b), -(-x)")
        elif t == "real_literal" and "." not in pf.text_of(n):
            diags.error(pf.pos(n), "E0104", f"real literal '{pf.text_of(n)}' needs a point "
                        "with digits on both sides (MatIEC rejects 1E3): write 1.0E3")
        if descend and cur.goto_first_child():
            above.append(t)
            continue
        while not cur.goto_next_sibling():
            if not cur.goto_parent():
                break
            above.pop()
        else:
            continue
        break
    # `.5` and `1.` do not parse at all; say what is wrong instead of only "syntax error"
    code = bytearray(pf.data)
    for a, b in comment_spans:
        code[a:b] = b" " * (b - a)
    for m in re.finditer(rb"/\*.*?\*/", bytes(code), re.S):
        diags.error(pf.pos_at_byte(m.start()), "E0102", "C-style /* */ comments are rejected "
                    "by MatIEC: use (* ... *)")
    for rx, what in ((_LEADING_DOT, "no digit before the point"),
                     (_TRAILING_DOT, "no digit after the point")):
        for m in rx.finditer(bytes(code)):
            diags.error(pf.pos_at_byte(m.start()), "E0104", f"real literal with {what}: "
                        "write 0.5 or 1.0 (MatIEC rejects .5 and 1.)")


# ------------------------------------------------------------------ pragmas
# OpenPLC v3's build pastes the text of a {pragma} into the C that MatIEC generates, where it
# stands (a POU's body, or the top of POUS.c). So a pragma builds exactly when its text is C
# that compiles there. What the checker can tell fails, measured on OpenPLC v3's build:
#   - a pragma inside a VAR block (MatIEC's grammar refuses it);
#   - CODESYS-style pragmas, {attribute 'hide'}, {warning '...'}, {IF defined(...)}: not C;
#   - in a FUNCTION_BLOCK or PROGRAM, C naming one of the POU's variables as a bare name (or
#     data__->X): MatIEC keeps them in a data__ structure reached through its macros
#     (__GET_VAR(data__->X,), __SET_VAR(data__->,X,,v)), which build;
#   - in a FUNCTION, C naming a variable (or the result) other than in upper case: MatIEC's C
#     declares them upper-cased locals (TX builds, tx fails).
# Any other C (OSCAT's T_PLC_MS reading extern __tick and common_ticktime__, comments, an
# empty pragma) builds, and the checker accepts it for OpenPLC: it cannot compile C itself.
POU_NODES = frozenset({"function_declaration", "function_block_declaration",
                       "program_declaration"})
_POU_KIND = {"function_declaration": "FUNCTION", "function_block_declaration": "FUNCTION_BLOCK",
             "program_declaration": "PROGRAM"}
_VAR_BLOCKS = frozenset({"var_input", "var_output", "var_in_out", "var_temp", "var_external",
                         "var_global", "global_var_declaration_block", "var_block"})
_NOT_C = re.compile(r"""^\s*(?:\w+\s+['"]|(?:endregion|END_IF|ELSE)\s*$|(?:IF|ELSIF)\s+defined\b|"""
                    r"(?:define|undefine)\s+\w+\s*$)")
_C_TOKEN = re.compile(r'"(?:\\.|[^"\\])*"|\'(?:\\.|[^\'\\])*\'|/\*.*?\*/|//[^\n]*|'
                      r"([A-Za-z_]\w*)|([()])", re.S)


def _pou_variables(pf: ParsedFile, pou: Node) -> set[str]:
    names: set[str] = set()
    for block in pou.named_children:
        if block.type not in _VAR_BLOCKS:
            continue
        for decl in block.named_children:
            if decl.type != "variable_declaration":
                continue
            for c in decl.children:
                if c.type == ":":
                    break
                if c.type == "identifier":
                    names.add(pf.text_of(c).upper())
    return names


def pragma_failure(pf: ParsedFile, n: Node, pou: Node | None, context: str) -> str | None:
    """Why OpenPLC v3's build fails on the pragma ``n`` (in ``pou``, inside a node of type
    ``context``), or None when the checker cannot tell it fails."""
    text = pf.text_of(n)
    if context in _VAR_BLOCKS or context == "variable_declaration":
        return ("a {pragma} inside a VAR block: MatIEC's grammar refuses it there (put it "
                "between statements)")
    code = pragma_code(text)
    if _NOT_C.match(code):
        return ("OpenPLC's build pastes a {pragma}'s text into the C it compiles, and "
                f"'{_cut(text)}' is not C (a CODESYS-style pragma): remove it")
    if pou is None:
        return None
    kind = _POU_KIND[pou.type]
    variables = _pou_variables(pf, pou)
    if kind == "FUNCTION":
        name = pou.child_by_field_name("name")
        if name is not None:
            variables.add(pf.text_of(name).upper())
    in_macro: list[bool] = []  # the open parentheses: True for a MatIEC macro's (__GET_VAR...)
    prev = ""
    for m in _C_TOKEN.finditer(code):
        word, paren = m.group(1), m.group(2)
        if paren == "(":
            in_macro.append(prev.startswith("__"))
        elif paren == ")":
            if in_macro:
                in_macro.pop()
        elif word is not None and word.upper() in variables:
            if kind == "FUNCTION" and word != word.upper():
                return (f"the {{pragma}}'s C names '{word}': MatIEC's C spells a FUNCTION's "
                        f"variables upper case, so OpenPLC's C build fails: write "
                        f"{word.upper()}")
            if kind != "FUNCTION" and not any(in_macro):
                return (f"the {{pragma}}'s C names {kind} variable '{word}' directly: MatIEC's C "
                        f"keeps them in the POU's data__ structure, so OpenPLC's C build fails "
                        f"(use __GET_VAR(data__->{word.upper()},) and "
                        f"__SET_VAR(data__->,{word.upper()},,value))")
        prev = word or ""
    return None


def _cut(text: str, most: int = 30) -> str:
    one = " ".join(text.split())
    return one if len(one) <= most else one[:most] + "..."


def _matiec_comment_end(text: str) -> int:
    """Where MatIEC's lexer ends the comment ``text`` opens (past its ``*)``), or -1: it reads
    comments flat, scanning ``(*`` and ``*)`` as tokens from the left, so an inner ``(*`` is
    plain text (measured: ``(* see (* here *)`` builds) but the ``(*`` of ``(*)`` hides
    its ``)``."""
    i = 2
    while i < len(text) - 1:
        pair = text[i:i + 2]
        if pair == "*)":
            return i + 2
        i += 2 if pair == "(*" else 1
    return -1


def _stray_closer_after(data: bytes, end: int) -> bool:
    """Whether a ``*)`` follows ``end`` before any ``(*``: the closer of a comment nested in the
    one that ends at ``end`` (MatIEC, reading flat, fails on it)."""
    closer = data.find(b"*)", end)
    if closer < 0:
        return False
    opener = data.find(b"(*", end, closer + 1)
    return opener < 0


def _snippet(pf: ParsedFile, node: Node, most: int = 40) -> str:
    """The node's text for a message, cut after ``most`` characters."""
    end = min(node.end_byte, node.start_byte + 4 * most)  # a UTF-8 character: 4 bytes at most
    text = pf.data[node.start_byte:end].decode("utf-8", "replace")
    return text if len(text) <= most and end == node.end_byte else text[:most] + "..."


# ------------------------------------------------------------------ name rules
@dataclass(frozen=True)
class DeclaredName:
    """A name the program declares, where, as what, and whether it is global (a POU, type,
    configuration, resource, task or program instance) or local to one (a variable, field or
    enumeration value)."""

    name: str
    pos: SourcePos
    what: str
    is_global: bool


def declared_names(prog: CheckedProgram) -> Iterator[DeclaredName]:
    for unit in prog.units:
        for td in unit.types:
            yield DeclaredName(td.name, td.pos, "type", True)
            d = td.definition
            if isinstance(d, A.StructTypeRef):
                for f in d.fields:
                    yield DeclaredName(f.name, f.pos, "field", False)
            if isinstance(d, A.EnumTypeRef):
                for v in d.values:
                    yield DeclaredName(v.name, v.pos, "enumeration value", False)
        for pou in unit.pous:
            yield DeclaredName(pou.name, pou.pos, pou.kind.replace("_", " ").lower(), True)
            for blk in pou.blocks:
                for decl in blk.decls:
                    yield DeclaredName(decl.name, decl.pos, "variable", False)
        for cfg in unit.configs:
            yield DeclaredName(cfg.name, cfg.pos, "configuration", True)
            for res in cfg.resources:
                if res.name:
                    yield DeclaredName(res.name, res.pos, "resource", True)
                for t in res.tasks:
                    yield DeclaredName(t.name, t.pos, "task", True)
                for pi in res.programs:
                    yield DeclaredName(pi.name, pi.pos, "program instance", True)
                for blk in res.globals:
                    for decl in blk.decls:
                        yield DeclaredName(decl.name, decl.pos, "global", False)
            for blk in cfg.globals:
                for decl in blk.decls:
                    yield DeclaredName(decl.name, decl.pos, "global", False)


def check_names(prog: CheckedProgram, diags: Diagnostics) -> None:
    var_names = stdlib_variable_names()
    for n in declared_names(prog):
        up = n.name.upper()
        if matiec_refuses_name(n.name, n.what):
            diags.error(n.pos, "E0202", f"{n.what} '{n.name}' is reserved in MatIEC (a "
                        "keyword, type or standard function/FB name): rename it")
        elif n.is_global and up in var_names:
            diags.error(n.pos, "E0203", f"{n.what} '{n.name}' equals a variable name inside "
                        "MatIEC's standard library, which then fails to compile: rename it")
        elif is_c_macro(n.name):
            diags.error(n.pos, "E0204", f"{n.what} '{n.name}' becomes the C macro {up} in "
                        "OpenPLC's build: rename it")

    # MatIEC binds a call to its standard function of that name, as the bench does: a named
    # call then fails (the bench says which parameter is missing), a positional one runs the
    # standard function, not the user's (measured)
    for call, target in prog.calls.items():
        callee = call.callee
        if target.kind == "std" and isinstance(callee, A.Name):
            user = prog.pous.get(callee.name.upper())
            if user is not None and not user.builtin:
                diags.warning(call.pos, "E0202", f"this call runs MatIEC's standard function "
                              f"{callee.name.upper()}, not the {user.kind} {user.name} of the "
                              "program (MatIEC binds the name to its own): rename the "
                              f"{user.kind}")


def check_array_input_calls(prog: CheckedProgram, diags: Diagnostics) -> None:
    """A call of a FUNCTION with an array VAR_INPUT: MatIEC's C for the call casts the array
    to the element type and does not compile; the FUNCTION itself builds, uncalled (as in a
    library), measured on OpenPLC v3's build."""
    for call, target in prog.calls.items():
        pou = target.pou
        if target.kind != "function" or pou is None:
            continue
        arr = next((v for v in pou.vars.values()
                    if v.kind == A.VAR_INPUT and isinstance(v.type, ArrayType)), None)
        if arr is not None:
            diags.error(call.pos, "E0405", f"call of FUNCTION {pou.name}, whose input "
                        f"'{arr.name}' is an array: MatIEC's C for the call does not compile")
