"""Generator of st/KinematicsFixedTables.st: the trig tables of the integer-only kinematics.

Three tables of 257 UINT entries (514 bytes each, 1,542 bytes in all), each stored as the
*residual* of the function over its straight chord, so that the 16 bits of a UINT hold more
precision than the function value itself would:

``SinTableFixed`` -- quarter-wave sine, angle ``t = i * 90 deg / 256`` (i = 0..256)::

    entry[i] = round(sin(t) * 2**18 - i * 1024)        (0 .. 55,180; Q18 units)
    sin(t) * 2**18 = t * 2**18 / 90 deg + residual(t)   (the chord runs 0 -> 2**18)

``AtanTableFixed`` -- arc tangent on [0, 1], ``x = i / 256``::

    entry[i] = round(atan(x) in units of 1.0E-4 deg - x * 450,000)   (0 .. 40,752)
    atan(x) = 450,000 * x + residual(x)                  (the chord runs 0 -> 45 deg)

``RsqrtTableFixed`` -- reciprocal square root on [1, 2], ``x = 1 + i / 256``::

    entry[i] = round(2**20 - i * 307,121 / 256 - 2**20 / sqrt(x))   (0 .. 39,651; Q20 units)
    2**20 / sqrt(x) = chord(x) - residual(x)   (the chord runs 2**20 -> 2**20 - 307,121,
                                                307,121 = 2**20 - round(2**20 / sqrt(2)))

All residuals are >= 0 (sine and arc tangent are concave, the reciprocal square root is
convex on these ranges) and 0 at both ends. The ST code adds the chord back in exact integer
arithmetic and interpolates the residual linearly (KinematicsFixed.st documents the error
budget).

The output is byte-for-byte reproducible: no time stamps, fixed formatting, and every entry is
checked to lie at least 1.0E-6 units away from a rounding tie, so a libm that differs in the
last bit of ``sin``/``atan`` cannot change a value.

    python -m armbench.lutgen                 # (re)write st/KinematicsFixedTables.st
    python -m armbench.lutgen --out DIR       # write DIR/KinematicsFixedTables.st
    python -m armbench.lutgen --check         # exit 1 when the committed file is stale
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .locate import LocateError, find_checkout

ST_DIR = Path("st")  # inside the checkout (armbench.locate.find_checkout)
TABLES_FILE = "KinematicsFixedTables.st"

SEGMENTS = 256  # table intervals; entries = SEGMENTS + 1
SIN_SCALE = 1 << 18  # Q18: sin = 1.0 is 262,144
ATAN_UNITS_PER_DEG = 10_000  # arc tangent in 1.0E-4 deg
ATAN_CHORD_END = 45 * ATAN_UNITS_PER_DEG  # atan(1) = 45 deg = 450,000 units
RSQRT_SCALE = 1 << 20  # Q20: 1 / sqrt(1) = 1.0 is 1,048,576
RSQRT_CHORD_DROP = RSQRT_SCALE - round(RSQRT_SCALE / math.sqrt(2.0))  # 307,121
UINT_MAX = 0xFFFF
UINT_BYTES = 2
TIE_MARGIN = 1.0e-6  # minimum distance of an unrounded entry from x.5


@dataclass(frozen=True)
class Table:
    """One generated table: its ST block name, a description and its entries."""

    block: str
    title: str
    unit: str
    entries: tuple[int, ...]

    @property
    def bytes(self) -> int:
        """Storage of the table as ST ``ARRAY[0..256] OF UINT`` (element size x count)."""
        return UINT_BYTES * len(self.entries)


def _round_checked(value: float, what: str) -> int:
    frac = value - math.floor(value)
    if abs(frac - 0.5) < TIE_MARGIN:
        raise ValueError(f"{what}: {value!r} is too close to a rounding tie to be reproducible")
    out = math.floor(value + 0.5)
    if not 0 <= out <= UINT_MAX:
        raise ValueError(f"{what}: {out} does not fit a UINT")
    return out


def _residuals(func: Callable[[int], float], chord_end: int, name: str) -> tuple[int, ...]:
    return tuple(
        _round_checked(func(i) - chord_end * i / SEGMENTS, f"{name}[{i}]")
        for i in range(SEGMENTS + 1)
    )


def sin_table() -> Table:
    """Quarter-wave sine residual over its chord, Q18, 257 entries for 0..90 deg."""
    entries = _residuals(
        lambda i: math.sin(i * (math.pi / 2.0) / SEGMENTS) * SIN_SCALE, SIN_SCALE, "sin"
    )
    return Table("SinTableFixed", "quarter-wave sine residual, t = Index * 90/256 deg",
                 "Q18 (1 = 1/262144)", entries)


def atan_table() -> Table:
    """Arc tangent residual over its chord on [0, 1], 1.0E-4 deg, 257 entries."""
    entries = _residuals(
        lambda i: math.degrees(math.atan(i / SEGMENTS)) * ATAN_UNITS_PER_DEG, ATAN_CHORD_END,
        "atan",
    )
    return Table("AtanTableFixed", "arc tangent residual, x = Index / 256",
                 "1.0E-4 deg", entries)


def rsqrt_table() -> Table:
    """Reciprocal square root residual under its chord on [1, 2], Q20, 257 entries."""
    entries = tuple(
        _round_checked(RSQRT_SCALE - RSQRT_CHORD_DROP * i / SEGMENTS
                       - RSQRT_SCALE / math.sqrt(1.0 + i / SEGMENTS), f"rsqrt[{i}]")
        for i in range(SEGMENTS + 1)
    )
    return Table("RsqrtTableFixed", "reciprocal square root residual, x = 1 + Index / 256",
                 "Q20 (1 = 1/1048576)", entries)


def tables() -> list[Table]:
    return [sin_table(), atan_table(), rsqrt_table()]


def table_bytes() -> int:
    """Total table storage in bytes (element size x element count, all tables)."""
    return sum(t.bytes for t in tables())


def _format_entries(entries: Sequence[int], per_line: int = 12) -> list[str]:
    lines = []
    for start in range(0, len(entries), per_line):
        chunk = ", ".join(f"{v:5d}" for v in entries[start:start + per_line])
        last = start + per_line >= len(entries)
        lines.append(f"      {chunk}{'' if last else ','}")
    return lines


_HEADER = """\
(* ============================================================================
   KinematicsFixedTables.st -- trig tables of the integer-only kinematics
   ============================================================================
   GENERATED by "python -m armbench.lutgen" (sim/armbench/lutgen.py); do not
   edit: change the generator and regenerate. The file is reproducible byte
   for byte (a unit test regenerates it and compares).

   Three lookup blocks, each holding one ARRAY[0..256] OF UINT (257 x 2 bytes
   = 514 bytes; {total} bytes in all) as a VAR CONSTANT with an initialiser.
   A table is the RESIDUAL of the function over its straight chord (sine and
   arc tangent are concave, the reciprocal square root convex on these
   ranges, so the residual is >= 0 and zero at both ends); the caller adds
   the chord back in exact integer arithmetic. This keeps the values inside a
   UINT at 4x (sine), 10x (arc tangent) and 16x (reciprocal square root)
   finer steps than storing the function itself.

     SinTableFixed   Entry[i] = round(sin(i * 90/256 deg) * 2^18 - i * 1024)
                     range {sin_min}..{sin_max}, unit Q18 (1/262144)
     AtanTableFixed  Entry[i] = round(atan(i/256) [1.0E-4 deg] - i * 450000/256)
                     range {atan_min}..{atan_max}, unit 1.0E-4 deg
     RsqrtTableFixed Entry[i] = round(2^20 - i * 307121/256
                                      - 2^20 / sqrt(1 + i/256))
                     range {rsqrt_min}..{rsqrt_max}, unit Q20 (1/1048576);
                     307121 = 2^20 - round(2^20 / sqrt(2))

   Interface of all three blocks (one call per lookup, no other state):
     Index : INT   interval number, 0..255; values outside are clamped.
     Lower : DINT  Entry[Index]        (unit as above)
     Upper : DINT  Entry[Index + 1]
   Users (KinematicsFixed.st): QuarterSineFixed (sine), Atan2Fixed (arc
   tangent), RsqrtFixed (reciprocal square root).
   Portability: tables live in FUNCTION_BLOCK instances (MatIEC has no global
   constants outside a CONFIGURATION), literal bounds, integer types only.
   ============================================================================ *)
"""

_BLOCK = """
(* ---------------------------------------------------------------------------
   {block} -- {title}.
   Index : INT, 0..255 (clamped). Lower, Upper : DINT, Entry[Index] and
   Entry[Index + 1], unit {unit}. One call per lookup, no state.
   --------------------------------------------------------------------------- *)
FUNCTION_BLOCK {block}
  VAR_INPUT
    Index : INT;  (* interval 0..255, clamped *)
  END_VAR
  VAR_OUTPUT
    Lower : DINT;  (* Entry[Index] *)
    Upper : DINT;  (* Entry[Index + 1] *)
  END_VAR
  VAR
    Row : INT;
  END_VAR
  VAR CONSTANT
    Entry : ARRAY[0..{segments}] OF UINT := [
{entries}
    ];
  END_VAR
  Row := Index;
  IF Row < 0 THEN
    Row := 0;
  ELSIF Row > {last_row} THEN
    Row := {last_row};
  END_IF;
  Lower := UINT_TO_DINT(Entry[Row]);
  Upper := UINT_TO_DINT(Entry[Row + 1]);
END_FUNCTION_BLOCK
"""


def render_tables() -> str:
    """The complete text of KinematicsFixedTables.st."""
    sin_t, atan_t, rsqrt_t = tables()
    text = _HEADER.format(
        total=table_bytes(),
        sin_min=min(sin_t.entries), sin_max=max(sin_t.entries),
        atan_min=min(atan_t.entries), atan_max=max(atan_t.entries),
        rsqrt_min=min(rsqrt_t.entries), rsqrt_max=max(rsqrt_t.entries),
    )
    for table in (sin_t, atan_t, rsqrt_t):
        text += _BLOCK.format(
            block=table.block, title=table.title, unit=table.unit, segments=SEGMENTS,
            last_row=SEGMENTS - 1, entries="\n".join(_format_entries(table.entries)),
        )
    return text


def write_tables(out_dir: Path) -> Path:
    """Write KinematicsFixedTables.st into ``out_dir`` (created if needed); return its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / TABLES_FILE
    path.write_bytes(render_tables().encode("ascii"))
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m armbench.lutgen", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: st/ of the checkout)")
    parser.add_argument("--repo", type=Path, default=None,
                        help="the checkout (default: found from the current directory)")
    parser.add_argument("--check", action="store_true",
                        help="compare with the file in --out instead of writing it")
    args = parser.parse_args(argv)
    if args.out is None:
        try:
            args.out = find_checkout(args.repo).root / ST_DIR
        except LocateError as exc:
            parser.error(str(exc))
    if args.check:
        path = args.out / TABLES_FILE
        current = path.read_bytes() if path.exists() else b""
        if current != render_tables().encode("ascii"):
            print(f"{path} is stale: run python -m armbench.lutgen", file=sys.stderr)
            return 1
        print(f"{path} is up to date ({table_bytes()} table bytes)")
        return 0
    path = write_tables(args.out)
    print(f"wrote {path} ({table_bytes()} table bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
