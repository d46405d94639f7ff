"""STRING literals as OpenPLC v3 builds them: MatIEC copies each '...' literal into the C
source with its escapes rewritten ($N -> \\x0A, $41 -> \\x41, $T -> \\t, ...) and the number of
IEC characters as the length; the C compiler then reads the C escapes, where a hex escape
takes every hex digit that follows ('$41b' is the bytes 0x1B, 0 with length 3). This module
computes the same length and bytes so the bench's STRING values are MatIEC's, byte for byte
(measured with OpenPLC v3's build, see docs/matiec-facts.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from .types import STRING_MAX

# MatIEC's C spelling of each two-character escape ($L is written as a raw newline, which
# ends the C string literal: OpenPLC's C build fails on it)
_SIMPLE = {"$": "$", "'": "'", "N": "\\x0A", "T": "\\t", "R": "\\r", "P": "\\f"}
_HEX = "0123456789abcdefABCDEF"
_C_SIMPLE = {"t": 9, "r": 13, "f": 12, "n": 10, '"': 34, "\\": 92, "'": 39}


class StringLiteralError(ValueError):
    """A literal OpenPLC v3's build refuses; the message says why."""


@dataclass(frozen=True)
class MatiecString:
    count: int  # the length MatIEC gives the literal: its IEC characters
    data: bytes  # the bytes the C compiler puts in the body


def matiec_c_text(body: str) -> tuple[int, str]:
    """The IEC character count and the C string text MatIEC writes for a literal's body (the
    text between the quotes)."""
    out: list[str] = []
    count = 0
    i = 0
    while i < len(body):
        ch = body[i]
        if ch == "$":
            nxt = body[i + 1:i + 2]
            if nxt.upper() == "L":
                raise StringLiteralError("'$L' in a STRING literal: MatIEC writes a raw line "
                                         "break into the C string and OpenPLC's C build fails "
                                         "(write $N or $0A)")
            if nxt.upper() in _SIMPLE:
                out.append(_SIMPLE[nxt.upper()])
                i += 2
            elif len(body) >= i + 3 and body[i + 1] in _HEX and body[i + 2] in _HEX:
                out.append("\\x" + body[i + 1:i + 3])
                i += 3
            else:
                raise StringLiteralError(f"'${nxt}' is not an escape of a STRING literal "
                                         "(MatIEC reads $$, $', $N, $T, $R, $P and $hh)")
        elif ch == "'":
            raise StringLiteralError("a quote inside a STRING literal is written $'")
        else:
            out.append({'"': '\\"', "\\": "\\\\"}.get(ch, ch))
            i += 1
            count += len(ch.encode("utf-8")) - 1  # MatIEC counts bytes
        count += 1
    return count, "".join(out)


def c_bytes(text: str) -> bytes:
    """The bytes a C compiler makes of a string literal's text (gcc: a hex escape takes every
    hex digit after it and keeps the low 8 bits of the value)."""
    out = bytearray()
    raw = text.encode("utf-8")
    i = 0
    while i < len(raw):
        b = raw[i]
        if b != 0x5C:  # backslash
            out.append(b)
            i += 1
            continue
        esc = chr(raw[i + 1])
        if esc == "x":
            j = i + 2
            while j < len(raw) and chr(raw[j]) in _HEX:
                j += 1
            out.append(int(raw[i + 2:j], 16) & 0xFF)
            i = j
        else:
            out.append(_C_SIMPLE[esc])
            i += 2
    return bytes(out)


def string_literal(source: str) -> MatiecString:
    """A '...' literal (with its quotes) as MatIEC's C holds it; StringLiteralError when
    OpenPLC v3's build fails on it."""
    if source.startswith('"'):
        raise StringLiteralError("WSTRING literal: OpenPLC v3's build fails on WSTRING (its "
                                 "MatIEC stops with an internal error); use STRING")
    count, text = matiec_c_text(source[1:-1])
    data = c_bytes(text)
    if len(data) >= STRING_MAX or count >= STRING_MAX:
        raise StringLiteralError(f"STRING literal of {max(len(data), count)} characters: "
                                 f"OpenPLC's C build fails above {STRING_MAX - 1} (the "
                                 f"body holds {STRING_MAX} bytes and C adds a terminating 0)")
    return MatiecString(count, data)


def c_initializer(lit: MatiecString) -> str:
    """`{len, "body"}` for a plc_string_t, every byte spelled in octal."""
    body = "".join(f"\\{b:03o}" for b in lit.data)
    return f'{{{lit.count}, "{body}"}}'
