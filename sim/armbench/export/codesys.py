"""The CODESYS variant of a program's located variables, and its Modbus register map.

Needs: a CheckedProgram without errors (its AST: every POU's located VarDecls and the
assignments in its body).

Why a variant: OpenPLC keeps one table per location kind (%IX/%QX bits, %IW, %QW, %MW, %MD,
%ML: docs/matiec-facts.md), so ``%MW0`` and ``%MD0`` are different variables there; CODESYS
addresses each area (%I, %Q, %M) by byte (``%MWn`` = bytes 2n..2n+1, ``%MDn`` = 4n..4n+3,
``%MXb.i`` = bit i of byte b), so the same two overlap.

Why the %I/%Q areas: the CODESYS Modbus TCP Server Device (CODESYS Modbus documentation,
"Modbus TCP Server Device - General") maps its holding registers (written by the client) to
``%IW`` inputs of the application and its input registers (read by the client, function 4)
to ``%QW`` outputs, with coils sharing the holding registers' data and discrete inputs the
input registers'. A located variable over those addresses *is* that register, with nothing to
map by hand. %M memory is not on Modbus in CODESYS at all. So:

- a located variable the program assigns (status, answers, results, PWM words, ...) goes to
  the %Q area: an input register (function 4) or discrete input for the client;
- one it never assigns (command blocks, batch targets, PSM inputs) goes to the %I area: a
  holding register (functions 16/3) or coil.

Inside each area every variable keeps its OpenPLC size and number where those bytes are free
(larger sizes first, then declaration order), so ``%MD130`` becomes ``%ID130`` or
``%QD130``; those that would overlap move, in declaration order and aligned to their size,
behind the highest byte used (rounded up to 16 bytes). Everything is derived from the located
variables of the program, so variables added to it later are placed the same way.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

from ..compiler import ast as A
from ..compiler.symbols import CheckedProgram

_ADDRESS = re.compile(r"^%([IQM])([XBWDL])(\d+)(?:\.(\d+))?$", re.IGNORECASE)
SIZE_BYTES = {"X": 1, "B": 1, "W": 2, "D": 4, "L": 8}
_SIZE_ORDER = "LDWBX"  # placement order: larger first
DEVICE_MAX_REGISTERS = 4096  # per register kind (CODESYS Modbus TCP Server Device)
TAIL_ALIGN = 16  # bytes: the moved variables start on this boundary after the fixed ones


class CodesysLayoutError(ValueError):
    """A program whose located variables cannot be laid out for CODESYS; says which."""


@dataclass(frozen=True)
class Location:
    """A parsed direct address: area I/Q/M, size X/B/W/D/L, number (byte for X), bit."""

    area: str
    size: str
    index: int
    bit: int | None = None

    @classmethod
    def parse(cls, text: str) -> Location:
        m = _ADDRESS.match(text.strip())
        if m is None:
            raise CodesysLayoutError(f"not a direct address: {text!r}")
        area, size, index, bit = m.group(1).upper(), m.group(2).upper(), int(m.group(3)), m.group(4)
        if (size == "X") != (bit is not None):
            raise CodesysLayoutError(f"{text}: a bit address needs .bit, other sizes none")
        return cls(area, size, index, None if bit is None else int(bit))

    def __str__(self) -> str:
        if self.size == "X":
            return f"%{self.area}X{self.index}.{self.bit}"
        return f"%{self.area}{self.size}{self.index}"

    def bits(self) -> range:
        """The bits this location covers in its area's byte memory (CODESYS addressing)."""
        if self.size == "X":
            assert self.bit is not None
            start = 8 * self.index + self.bit
            return range(start, start + 1)
        n = SIZE_BYTES[self.size]
        return range(8 * n * self.index, 8 * n * (self.index + 1))


@dataclass(frozen=True)
class Placed:
    """One located variable of a POU: its OpenPLC location and its CODESYS location."""

    pou: str
    name: str
    st_type: str
    openplc: Location
    codesys: Location
    written: bool  # the POU assigns it (an output of the PLC)
    decl: A.VarDecl

    @property
    def modbus(self) -> tuple[str, int, int]:
        """(table, 0-based address, registers or bits) under the CODESYS Modbus TCP Server
        Device with its first holding register at %IW0 and first input register at %QW0."""
        loc = self.codesys
        if loc.size == "X":
            assert loc.bit is not None
            return ("discrete input" if loc.area == "Q" else "coil"), 8 * loc.index + loc.bit, 1
        first_byte = SIZE_BYTES[loc.size] * loc.index
        words = max(1, SIZE_BYTES[loc.size] // 2)  # a byte shares its register
        return ("input register" if loc.area == "Q" else "holding register"), first_byte // 2, words

    def registers(self) -> range:
        """The registers of its area (holding for %I, input for %Q) it lies in: a bit lies in
        the register of its byte, as coils and discrete inputs share the registers' data."""
        bits = self.codesys.bits()
        return range(bits.start // 16, (bits.stop + 15) // 16)


def _assigned_names(pou: A.Pou) -> set[str]:
    names: set[str] = set()
    for node in A.walk(pou.body):
        if isinstance(node, A.Assign) and isinstance(node.target, A.Name):
            names.add(node.target.name.upper())
        elif isinstance(node, A.Arg) and node.is_output and isinstance(node.value, A.Name):
            names.add(node.value.name.upper())
    return names


def _type_text(tref: A.TypeRef) -> str:
    return tref.name if isinstance(tref, A.NamedTypeRef) else type(tref).__name__


def located(prog: CheckedProgram) -> list[tuple[A.Pou, A.VarDecl, bool]]:
    """Every located variable of every POU, in source order, with "the POU assigns it"."""
    out = []
    for unit in prog.units:
        for pou in unit.pous:
            written = _assigned_names(pou)
            for block in pou.blocks:
                for d in block.decls:
                    if d.address is not None:
                        out.append((pou, d, d.name.upper() in written))
    return out


def layout(prog: CheckedProgram) -> list[Placed]:
    """The CODESYS locations of the program's located variables (module docstring)."""
    items = located(prog)
    parsed = [(pou, d, w, Location.parse(d.address or "")) for pou, d, w in items]
    by_area: dict[str, list[int]] = {"I": [], "Q": []}
    for k, (_, _, written, _) in enumerate(parsed):
        by_area["Q" if written else "I"].append(k)
    result: dict[int, Location] = {}
    for area, members in by_area.items():
        used: set[int] = set()
        moved: list[int] = []
        order = sorted(members, key=lambda k: (_SIZE_ORDER.index(parsed[k][3].size), k))
        for k in order:
            natural = Location(area, parsed[k][3].size, parsed[k][3].index, parsed[k][3].bit)
            bits = set(natural.bits())
            if bits & used:
                moved.append(k)
            else:
                used |= bits
                result[k] = natural
        next_bit = -(-(max(used, default=-1) + 1) // (8 * TAIL_ALIGN)) * 8 * TAIL_ALIGN
        for k in sorted(moved):
            size = parsed[k][3].size
            if size == "X":
                loc = Location(area, "X", next_bit // 8, next_bit % 8)
                next_bit += 1
            else:
                width = 8 * SIZE_BYTES[size]
                start = -(-next_bit // width) * width
                loc = Location(area, size, start // width)
                next_bit = start + width
            result[k] = loc
    return [Placed(pou.name, d.name, _type_text(d.type), loc, result[k], written, d)
            for k, (pou, d, written, loc) in enumerate(parsed)]


def device_registers(placed: Iterable[Placed]) -> tuple[int, int]:
    """(holding registers, input registers) a Modbus TCP Server Device needs so that every
    placed variable, bits included, is one of its registers (first ones at %IW0 and %QW0)."""
    need = {"I": 1, "Q": 1}  # a device has 1..4096 of each
    for p in placed:
        need[p.codesys.area] = max(need[p.codesys.area], p.registers().stop)
    return need["I"], need["Q"]


def overlaps(locations: Iterable[tuple[str, Location]]) -> list[tuple[str, str]]:
    """Pairs of names whose CODESYS byte ranges share a bit (same area)."""
    owner: dict[tuple[str, int], str] = {}
    clashes = []
    for name, loc in locations:
        for b in loc.bits():
            key = (loc.area, b)
            if key in owner and owner[key] != name:
                clashes.append((owner[key], name))
                break
            owner[key] = name
    return clashes


def render_register_map(placed: list[Placed], title: str) -> str:
    """Markdown: every located variable with its OpenPLC and CODESYS location and its Modbus
    register under the CODESYS Modbus TCP Server Device."""
    holding, inputs = device_registers(placed)
    out = [
        f"# {title}: CODESYS register map",
        "",
        "Generated by `armbench export` from the located variables of the program -- do not",
        f"edit. The CODESYS variant (`{title}_codesys.xml`) places each of them in the %I",
        "or %Q area so that no two share a byte under CODESYS's byte addressing, and so that",
        "each is a register of the CODESYS **Modbus TCP Server Device** (docs/exports.md):",
        "",
        "- what the program writes is in %Q: **input registers** (read with function 4) and",
        "  discrete inputs (function 2);",
        "- what a client writes is in %I: **holding registers** (write with function 16, read",
        "  back with function 3) and coils.",
        "",
        "Device settings this map assumes: holding registers not *Writable*, their I/O mapping",
        f"starting at `%IW0`, at least {holding} of them; input registers starting at",
        f"`%QW0`, at least {inputs} of them. A 32-bit value takes two registers, the",
        "**least significant word first** (CODESYS lays a DINT/REAL out in the CPU's byte",
        "order: x86 and the Raspberry Pi's ARM are little-endian), unlike OpenPLC's most",
        "significant word first. Not verified on a CODESYS runtime here (none can be installed",
        "on this machine); the layout itself is checked by `tests/export/test_codesys.py`.",
        "",
        "Clients and tests speak this layout as the Modbus flavor `codesys`: armbench's pytest",
        "plugin with `--plc-address HOST:502 --plc-flavor codesys` (the arm controller's suite:",
        "`python -m pytest tests/modbus --plc-address HOST:502 --plc-flavor codesys`), a script",
        "with `ArmControllerClient(PlcClient(HOST, 502), flavor=\"codesys\")`; `armbench serve",
        "--flavor codesys` runs the program in a soft PLC serving this layout (README,",
        "\"Testing a real PLC over Modbus\").",
        "",
        *([f"**Warning**: more than {DEVICE_MAX_REGISTERS} registers are needed, the most a "
           "Modbus TCP Server Device offers: this program does not fit one device.", ""]
          if max(holding, inputs) > DEVICE_MAX_REGISTERS else []),
        "| name | type | OpenPLC | CODESYS | Modbus table | address | words |",
        "|---|---|---|---|---|---:|---:|",
    ]
    for p in sorted(placed, key=lambda p: (p.codesys.area, min(p.codesys.bits()))):
        table, address, count = p.modbus
        out.append(f"| `{p.name}` | {p.st_type} | `{p.openplc}` | `{p.codesys}` | {table} | "
                   f"{address} | {count} |")
    out.append("")
    return "\n".join(out)
