"""The controller's Modbus register map, derived from the located variables of
``plc_project/Controller.st`` (the program is the single source of truth).

Each located variable of the program instance becomes a :class:`Register` with its OpenPLC
Modbus table and address (DESIGN.md §5.3), its ST type and the comment written on its
declaration line; its group is the ``(* ... *)`` comment that opens its VAR block.
:func:`render_markdown` produces ``docs/register-map.md``; ``python -m armbench.registermap``
rewrites it, and a test fails when the file is stale.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from .compiler.diagnostics import CompileFailed
from .compiler.driver import analyse
from .softplc import modbus_map as mm

REPO = Path(__file__).resolve().parents[2]
LIBRARY_FILES = tuple(REPO / "st" / n for n in
                      ("ArmAngles.st", "Kinematics.st", "MG996R.st", "PCA9685.st"))
CONTROLLER = REPO / "plc_project" / "Controller.st"
SOURCES = (*LIBRARY_FILES, CONTROLLER)
DOC = REPO / "docs" / "register-map.md"

_ADDRESS = re.compile(r"^%([IQM])([XBWDL])(\d+)(?:\.(\d+))?$", re.IGNORECASE)
_COMMENT = re.compile(r"\(\*\s*(.*?)\s*\*\)")
_BLOCK_COMMENT = re.compile(r"^\s*\(\*\s*(.*?)\s*\*\)\s*$")


@dataclass(frozen=True)
class Register:
    """One located variable as seen over Modbus."""

    name: str
    st_type: str
    location: str  # e.g. "%MD2"
    table: str  # "holding" | "input" | "coil" | "discrete"
    address: int  # first Modbus address (0-based)
    count: int  # registers (or bits) it occupies
    group: str
    description: str

    @property
    def index(self) -> int:
        """The n of %XYn (the %MD index for the client's read_real/write_real helpers)."""
        m = _ADDRESS.match(self.location)
        assert m is not None
        return int(m.group(3))


def modbus_location(location: str) -> tuple[str, int, int]:
    """(table, first address, count) of a located variable per OpenPLC's map; ValueError when
    it is not reachable over Modbus."""
    m = _ADDRESS.match(location)
    if m is None:
        raise ValueError(f"not a located address: {location}")
    area, size, n = m.group(1).upper(), m.group(2).upper(), int(m.group(3))
    bit = m.group(4)
    if size == "X":
        if area == "M" or bit is None:
            raise ValueError(f"{location} is not reachable over Modbus")
        table = "coil" if area == "Q" else "discrete"
        return table, mm.bit_address(n, int(bit)), 1
    if area == "I" and size == "W":
        return "input", n, 1
    if area == "Q" and size == "W":
        return "holding", mm.qw_address(n), 1
    if area == "M" and size == "W":
        return "holding", mm.mw_address(n), 1
    if area == "M" and size == "D":
        return "holding", mm.md_address(n), 2
    if area == "M" and size == "L":
        return "holding", mm.ml_address(n), 4
    raise ValueError(f"{location} is not reachable over Modbus (DESIGN.md §5.3)")


def _group_and_comment(lines: Sequence[str], line: int) -> tuple[str, str]:
    text = lines[line - 1]
    m = _COMMENT.search(text)
    description = m.group(1) if m else ""
    group = ""
    for i in range(line - 2, -1, -1):
        prev = lines[i]
        if re.match(r"^\s*VAR\b", prev, re.IGNORECASE):
            break
        bm = _BLOCK_COMMENT.match(prev)
        if bm and ":" not in prev.split("(*")[0]:
            group = bm.group(1)
            break
    return group, description


def derive(paths: Sequence[str | Path] = SOURCES, instance: str | None = None) -> list[Register]:
    """The map of the (first, or named) program instance of the sources' CONFIGURATION,
    in declaration order. Raises CompileFailed when the sources do not check."""
    prog, diags = analyse(list(paths))
    if prog is None:
        raise CompileFailed(diags.sorted())
    if prog.config is None or not prog.config.instances:
        raise ValueError("the sources have no CONFIGURATION with a program instance")
    inst = prog.config.instances[0]
    if instance is not None:
        inst = next(i for i in prog.config.instances if i.name.upper() == instance.upper())
    sources: dict[str, list[str]] = {}
    regs: list[Register] = []
    for var in inst.pou.vars.values():
        if var.address is None:
            continue
        if var.pos.file not in sources:
            sources[var.pos.file] = Path(var.pos.file).read_text(encoding="utf-8").splitlines()
        group, description = _group_and_comment(sources[var.pos.file], var.pos.line)
        table, address, count = modbus_location(var.address)
        regs.append(Register(var.name, str(var.type), var.address.upper(), table, address,
                             count, group, description))
    return regs


@cache
def controller_map() -> dict[str, Register]:
    """The controller's map by variable name (upper case), computed once per process."""
    return {r.name.upper(): r for r in derive()}


def render_markdown(regs: Sequence[Register]) -> str:
    out = [
        "# Controller register map",
        "",
        "Generated from the located variables of `plc_project/Controller.st` by",
        "`python -m armbench.registermap` -- do not edit; `tests/modbus/test_registermap.py`",
        "fails when this file is stale. Addresses are 0-based Modbus addresses of OpenPLC v3",
        "(DESIGN.md §5.3); 32-bit values take two registers, most significant word first.",
        "",
        "Handshake: write the whole command block (the `Cmd...` registers) with one",
        "function-16 request with `CmdSeq` = `AckSeq` + 1, then poll `AckSeq` until it equals",
        "`CmdSeq`; `ErrorId` is then the command's result. `SolveBatch` targets are written",
        "before the command block, its results read after the acknowledge. Commands, error",
        "codes and calibration: see the header of `Controller.st`.",
        "",
    ]
    groups: list[str] = []
    for r in regs:
        if r.group not in groups:
            groups.append(r.group)
    for g in groups:
        out += [f"## {g[:1].upper() + g[1:] if g else 'Other'}", "",
                "| Modbus | table | words | ST location | name | type | meaning |",
                "|---:|---|---:|---|---|---|---|"]
        for r in regs:
            if r.group == g:
                out.append(f"| {r.address} | {r.table} | {r.count} | `{r.location}` | "
                           f"`{r.name}` | {r.st_type} | {r.description} |")
        out.append("")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    target = Path(args[0]) if args else DOC
    target.write_text(render_markdown(derive()), encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
