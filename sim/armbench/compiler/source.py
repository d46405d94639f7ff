"""Source files: reading them (encodings), and positions naming file:line:col (1-based) for
every node and message."""

from __future__ import annotations

import codecs
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True, slots=True)
class SourcePos:
    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"

    def __reduce__(self) -> tuple[type[SourcePos], tuple[str, int, int]]:
        # pickled as a constructor call: a frozen dataclass's default state handling costs
        # twice the time, and every node of a cached syntax tree has a position
        return SourcePos, (self.file, self.line, self.col)


NOWHERE = SourcePos("<builtin>", 0, 0)


@dataclass(frozen=True, slots=True)
class SourceText:
    """A source file's text and the encoding it was read with."""

    text: str
    encoding: str  # "utf-8", "utf-8-sig" (with BOM), "utf-16" (with BOM) or "cp1252"

    @property
    def assumed(self) -> bool:
        """True when no BOM or valid UTF-8 said what the encoding is (cp1252 was guessed)."""
        return self.encoding == "cp1252"


def read_source(path: Path) -> SourceText:
    """Read an ST file: UTF-8 (a BOM is dropped, so columns count from the first real
    character), UTF-16 with a BOM, else Windows-1252 -- what CODESYS V2 and TwinCAT 2 write
    (a superset of Latin-1 for text; its five unassigned bytes are read as Latin-1).
    Raises OSError, or UnicodeDecodeError for a BOM followed by invalid text."""
    return decode_source(path.read_bytes())


def decode_source(data: bytes) -> SourceText:
    """The text of an ST file's bytes, as :func:`read_source` reads it (UnicodeDecodeError for
    a BOM followed by invalid text)."""
    if data.startswith(codecs.BOM_UTF8):
        return SourceText(data[len(codecs.BOM_UTF8):].decode("utf-8"), "utf-8-sig")
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return SourceText(data.decode("utf-16"), "utf-16")
    try:
        return SourceText(data.decode("utf-8"), "utf-8")
    except UnicodeDecodeError:
        return SourceText(data.decode("cp1252", errors="strict")
                          if _cp1252_ok(data) else data.decode("latin-1"), "cp1252")


def _cp1252_ok(data: bytes) -> bool:
    return not any(b in data for b in (b"\x81", b"\x8d", b"\x8f", b"\x90", b"\x9d"))
