"""Any program's located variables as the live view reads them: which, and how over Modbus.

The variables come from the program's own declarations (:func:`armbench.registermap.program_map`,
the derivation that also gives the controller's register map), so the view of a user's
program needs nothing but its ST files. :class:`ReadPlan` turns a set of variables into as
few Modbus requests as it can (one per contiguous stretch of each table, across small gaps)
and :func:`decode` turns the words read back into values, in OpenPLC's word order.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..compiler.symbols import CheckedProgram
from ..registermap import Register, Unreachable, controller_map, program_map
from ..softplc import modbus_map as mm
from ..softplc.modbus_client import PlcClient

_MAX_WORDS = 122  # even, below FC03/FC04's 125: a 32/64-bit value is never split
_MAX_BITS = 2000  # FC01/FC02's limit
_WORD_GAP = 16  # read across gaps this small in one request rather than two
_BIT_GAP = 256


@dataclass(frozen=True)
class ProgramVariables:
    """The located variables of the program a PLC runs, as the live view shows them."""

    name: str  # for the page: the program's file names, or "arm controller"
    registers: tuple[Register, ...]
    unreachable: tuple[Unreachable, ...] = ()
    is_controller: bool = False  # the arm controller's map: arm drawing and commands

    def find(self, name: str) -> Register:
        for r in self.registers:
            if r.name.upper() == name.upper():
                return r
        raise KeyError(name)


def controller_variables() -> ProgramVariables:
    """The packaged arm controller's map (what ``serve --web`` runs without files)."""
    return ProgramVariables("arm controller",
                            tuple(controller_map().values()), (), True)


def _same(a: Register, b: Register) -> bool:
    return (a.location, a.st_type.upper()) == (b.location, b.st_type.upper())


def program_variables(source: CheckedProgram | Sequence[str | Path],
                      name: str) -> ProgramVariables:
    """The located variables of a checked program, or of the program in ``paths`` (the files
    the PLC was built from, library included); ``name`` says which for the page. A program
    that declares every register of the arm controller's map at the same location and type is
    the controller (or a version of it with more): the view then draws the arm and offers its
    commands. Raises CompileFailed when the files do not check."""
    pm = program_map(source)
    mine = {r.name.upper(): r for r in pm.registers}
    controller = controller_map()
    is_controller = all(n in mine and _same(mine[n], r) for n, r in controller.items())
    return ProgramVariables(name, tuple(pm.registers), tuple(pm.unreachable), is_controller)


@dataclass(frozen=True)
class Image:
    """Words and bits read in one round of requests, by table and address."""

    words: dict[tuple[str, int], int]
    bits: dict[tuple[str, int], bool]


def _merge(ranges: Iterable[tuple[int, int]], gap: int, limit: int) -> list[tuple[int, int]]:
    merged: list[list[int]] = []
    for lo, hi in sorted(ranges):
        if merged and lo - merged[-1][1] <= gap:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    out = []
    for lo, hi in merged:
        a = lo
        while a < hi:
            n = min(limit, hi - a)
            out.append((a, n))
            a += n
    return out


class ReadPlan:
    """The Modbus requests that read a set of variables: (table, address, count) each."""

    def __init__(self, registers: Iterable[Register]) -> None:
        regs = list(registers)
        self.requests: list[tuple[str, int, int]] = []
        for table, gap, limit in (("holding", _WORD_GAP, _MAX_WORDS),
                                  ("input", _WORD_GAP, _MAX_WORDS),
                                  ("coil", _BIT_GAP, _MAX_BITS),
                                  ("discrete", _BIT_GAP, _MAX_BITS)):
            ranges = [(r.address, r.address + r.count) for r in regs if r.table == table]
            self.requests += [(table, a, n) for a, n in _merge(ranges, gap, limit)]

    def read(self, plc: PlcClient) -> Image:
        words: dict[tuple[str, int], int] = {}
        bits: dict[tuple[str, int], bool] = {}
        for table, address, count in self.requests:
            if table == "holding":
                ws = plc.read_holding_registers(address, count)
            elif table == "input":
                ws = plc.read_input_registers(address, count)
            else:
                read = plc.read_coils if table == "coil" else plc.read_discrete_inputs
                for i, b in enumerate(read(address, count)):
                    bits[(table, address + i)] = bool(b)
                continue
            for i, w in enumerate(ws):
                words[(table, address + i)] = w
        return Image(words, bits)


def decode(reg: Register, image: Image) -> bool | float | int:
    """A variable's value from the words or bits read (REAL, DINT, UDINT, INT, WORD...)."""
    if reg.table in ("coil", "discrete"):
        return image.bits[(reg.table, reg.address)]
    w = [image.words[(reg.table, reg.address + i)] for i in range(reg.count)]
    t = reg.st_type.upper()
    if t == "REAL":
        return mm.words_to_real(w)
    if t == "LREAL":
        return mm.words_to_lreal(w)
    if t == "DINT":
        return mm.words_to_dint(w)
    if t == "LINT":
        return mm.words_to_lint(w)
    if t == "INT":
        return mm.word_to_int(w[0])
    value = 0
    for x in w:  # UDINT, WORD, DWORD, UINT, ...: unsigned, most significant word first
        value = (value << 16) | x
    return value
