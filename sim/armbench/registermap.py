"""The controller's Modbus register map, derived from the located variables of
``plc_project/Controller.st`` (the program is the single source of truth).

Each located variable of the program instance becomes a :class:`Register` with its Modbus
table and address, its ST type and the comment written on its declaration line; its group is
the ``(* ... *)`` comment that opens its VAR block. Table and address are those of a Modbus
flavor: OpenPLC v3's map of the declared address (docs/matiec-facts.md) by default, or, with
``flavor="codesys"``, the place ``armbench export`` gives the variable in the CODESYS variant
(:func:`armbench.export.codesys.layout`, the code that writes
plc_project/codesys/register-map.md) and its register on the Modbus TCP Server Device there.
:func:`render_markdown` produces ``docs/register-map.md``; ``python -m armbench.registermap``
rewrites it, and a test fails when the file is stale.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from .compiler import ast as A
from .compiler.ast import Literal
from .compiler.diagnostics import CompileFailed
from .compiler.driver import analyse
from .compiler.symbols import CheckedProgram, InstanceModel, PouSym, VarSym
from .compiler.targets import OPENPLC_ONLY
from .compiler.types import PouType, StructType
from .locate import LocateError, default_project, find_checkout, package_checkout
from .mailbox_check import check_word
from .softplc import modbus_map as mm
from .softplc.modbus_map import Flavor

if TYPE_CHECKING:  # imported when a CODESYS map is asked for: it loads the exporters
    from .export.codesys import Placed

# The program the tools use (the wheel's copy, or the checkout's: armbench.locate).
_PROJECT = default_project()
# The whole library, as in the OpenPLC export: the controller may use any of it (the LUT
# commands need KinematicsFixed.st), and the soft PLC then runs what the real PLC runs.
LIBRARY_FILES = tuple(_PROJECT.library())
COMPONENTS = tuple(_PROJECT.components())
CONTROLLER = _PROJECT.controller
SOURCES = tuple(_PROJECT.sources())
# The page lives in the repository only; None for an installed package (main() then looks
# for the checkout it is run from).
_CHECKOUT = package_checkout()
DOC = None if _CHECKOUT is None else _CHECKOUT.root / "docs" / "register-map.md"

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
    flavor: Flavor = mm.OPENPLC  # whose server the table and address are of
    declared: str = ""  # the address in the source, when the flavor moved it ("": location)

    @property
    def index(self) -> int:
        """The n of %XYn (the %MD index for the client's read_real/write_real helpers)."""
        m = _ADDRESS.match(self.location)
        assert m is not None
        return int(m.group(3))

    @property
    def source_location(self) -> str:
        """The address the program declares (the soft PLC's image holds it there)."""
        return self.declared or self.location

    @property
    def writable(self) -> bool:
        """A client can write it: a coil or a holding register."""
        return self.table in ("coil", "holding")

    def encode(self, value: int | float) -> list[int]:
        """Its registers holding ``value``, in the flavor's word order."""
        return self.flavor.encode(self.st_type, value)

    def decode(self, words: Sequence[int]) -> int | float:
        """Its value from its registers, in the flavor's word order."""
        return self.flavor.decode(self.st_type, list(words))


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
    raise ValueError(f"{location} is not reachable over Modbus (OpenPLC v3 maps only %IX, %QX, "
                     "%IW, %QW, %MW, %MD and %ML; docs/matiec-facts.md)")


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
        if bm and bm.group(1).startswith(("generated by ", "end of generated ")):
            continue  # armbench.batchgen's region markers are not group titles
        if bm and ":" not in prev.split("(*")[0]:
            group = bm.group(1)
            break
    return group, description


def _analysed(paths: Sequence[str | Path],
              instance: str | None) -> tuple[CheckedProgram, InstanceModel]:
    prog, diags = analyse(list(paths), target=OPENPLC_ONLY)
    if prog is None:
        raise CompileFailed(diags.sorted())
    if prog.config is None or not prog.config.instances:
        raise ValueError("the sources have no CONFIGURATION with a program instance")
    inst = prog.config.instances[0]
    if instance is not None:
        inst = next(i for i in prog.config.instances if i.name.upper() == instance.upper())
    return prog, inst


def _instance(paths: Sequence[str | Path], instance: str | None) -> InstanceModel:
    return _analysed(paths, instance)[1]


def derive(paths: Sequence[str | Path] = SOURCES, instance: str | None = None,
           flavor: str | Flavor = mm.OPENPLC) -> list[Register]:
    """The map of the (first, or named) program instance of the sources' CONFIGURATION,
    in declaration order, on a ``flavor`` server. Raises CompileFailed when the sources do not
    check."""
    prog, inst = _analysed(paths, instance)
    return _registers(prog, inst, mm.flavor(flavor))


def _registers(prog: CheckedProgram, inst: InstanceModel, flavor: Flavor) -> list[Register]:
    return _located(inst.pou.vars.values(), {}, None,
                    _Placer(flavor, inst.pou.name, _placements(prog, flavor)))


@dataclass(frozen=True)
class _Placer:
    """Where the located variables of one POU (or of the CONFIGURATION) are on a flavor's
    server: OpenPLC's map of the declared address (``flavor.layout`` "openplc": OpenPLC v3
    and v4), or the CODESYS variant's place, keyed by (POU, name) upper case."""

    flavor: Flavor
    pou: str | None  # None: the CONFIGURATION's globals
    codesys: dict[tuple[str, str], Placed] | None = None

    def __call__(self, var: VarSym) -> tuple[str, str, int, int]:
        """(location, table, first address, count); ValueError when it is not on Modbus."""
        assert var.address is not None
        if self.codesys is None:
            return (var.address.upper(), *modbus_location(var.address))
        p = None if self.pou is None else self.codesys.get((self.pou.upper(),
                                                            var.name.upper()))
        if p is None:
            raise ValueError(f"{var.address} is a located global of the CONFIGURATION: the "
                             "CODESYS variant places only the programs' located variables")
        kind, address, count = p.modbus
        return str(p.codesys), _CODESYS_TABLES[kind], address, count


def _placements(prog: CheckedProgram, flavor: Flavor
                ) -> dict[tuple[str, str], Placed] | None:
    """The CODESYS variant's placement of every located variable for ``flavor`` codesys
    (None for openplc: the declared addresses are the map)."""
    if flavor.openplc_map:  # OpenPLC v3, and v4 set up to keep v3's map
        return None
    from .export.codesys import layout

    return {(p.pou.upper(), p.name.upper()): p for p in layout(prog)}


# export.codesys's names of the Modbus tables -> Register.table's
_CODESYS_TABLES = {"holding register": "holding", "input register": "input", "coil": "coil",
                   "discrete input": "discrete"}


@dataclass(frozen=True)
class Unreachable:
    """A located variable OpenPLC's Modbus map does not cover (e.g. ``%MX``)."""

    name: str
    st_type: str
    location: str
    reason: str


@dataclass(frozen=True)
class ProgramMap:
    """Every located variable of a program's CONFIGURATION as seen over Modbus: the located
    globals, then each program instance's, in declaration order. ``instances`` says which
    instance declares each register (None: a global); ``unreachable`` lists the located
    variables OpenPLC does not serve (%IB, %QD, %MX, ...)."""

    registers: tuple[Register, ...]
    instances: tuple[str | None, ...]
    unreachable: tuple[Unreachable, ...]


def program_map(source: CheckedProgram | Sequence[str | Path],
                flavor: str | Flavor = mm.OPENPLC) -> ProgramMap:
    """The Modbus map of any program (the controller's is one case of it) on a ``flavor``
    server, from a checked program or from its source files. Unlike :func:`derive`, a
    variable outside the flavor's Modbus map is listed in ``unreachable`` instead of failing
    the whole program. Raises CompileFailed when the sources do not check, ValueError without
    a CONFIGURATION."""
    fl = mm.flavor(flavor)
    if isinstance(source, CheckedProgram):
        prog = source
    else:
        checked, diags = analyse(list(source), target=OPENPLC_ONLY)
        if checked is None:
            raise CompileFailed(diags.sorted())
        prog = checked
    if prog.config is None or not prog.config.instances:
        raise ValueError("the sources have no CONFIGURATION with a program instance: OpenPLC "
                         "and the soft PLC run CONFIGURATION Config0 / RESOURCE Res0 / TASK / "
                         "PROGRAM ... WITH")
    sources: dict[str, list[str]] = {}
    unreachable: list[Unreachable] = []
    placements = _placements(prog, fl)
    regs = _located(prog.config.globals.values(), sources, unreachable,
                    _Placer(fl, None, placements))
    owners: list[str | None] = [None] * len(regs)
    seen: set[str] = set()
    for inst in prog.config.instances:
        if inst.pou.key in seen:
            continue  # a second instance of a PROGRAM shares its located variables
        seen.add(inst.pou.key)
        mine = _located(inst.pou.vars.values(), sources, unreachable,
                        _Placer(fl, inst.pou.name, placements))
        regs += mine
        owners += [inst.name] * len(mine)
    return ProgramMap(tuple(regs), tuple(owners), tuple(unreachable))


def _located(variables: Iterable[VarSym], sources: dict[str, list[str]],
             unreachable: list[Unreachable] | None, place: _Placer) -> list[Register]:
    """The located ones among ``variables`` as Registers, where ``place`` puts them. A
    location Modbus cannot reach raises ValueError, or goes to ``unreachable`` when that is
    given."""
    regs: list[Register] = []
    for var in variables:
        if var.address is None:
            continue
        try:
            location, table, address, count = place(var)
        except ValueError as exc:
            if unreachable is None:
                raise
            unreachable.append(Unreachable(var.name, str(var.type), var.address.upper(),
                                           str(exc)))
            continue
        if var.pos.file not in sources:
            sources[var.pos.file] = Path(var.pos.file).read_text(
                encoding="utf-8", errors="replace").splitlines()
        group, description = _group_and_comment(sources[var.pos.file], var.pos.line)
        declared = var.address.upper()
        regs.append(Register(var.name, str(var.type), location, table, address, count, group,
                             description, place.flavor,
                             "" if location == declared else declared))
    return regs


def constants(paths: Sequence[str | Path] = SOURCES,
              instance: str | None = None) -> dict[str, int]:
    """The program's integer VAR CONSTANTs (command codes, states, ...) by name, and the
    fields of its code STRUCTs as `Var.Field` (error codes), from the ST itself."""
    prog, inst = _analysed(paths, instance)
    return _pou_constants(inst.pou, prog.pous)


def _root_name(e: A.Expr) -> str | None:
    while isinstance(e, (A.Member, A.Index)):
        e = e.obj
    return e.name.upper() if isinstance(e, A.Name) else None


def _callee(call: A.Call, pou: PouSym, pous: Mapping[str, PouSym]) -> PouSym | None:
    """The user POU a call runs: a FUNCTION by name, or an FB instance's block."""
    name = _root_name(call.callee) if isinstance(call.callee, A.Name) else None
    if name is None:
        return None
    var = pou.vars.get(name)
    if var is not None and isinstance(var.type, PouType):
        return var.type.symbol if isinstance(var.type.symbol, PouSym) else None
    return pous.get(name)


def _written(pou: PouSym, pous: Mapping[str, PouSym]) -> set[str]:
    """Variables the POU's body may change: assignment targets, outputs (`=>`) and what it
    binds to a callee's VAR_IN_OUT."""
    assert pou.node is not None
    names: set[str] = set()
    for node in A.walk(pou.node.body):
        if isinstance(node, A.Assign):
            names.add(_root_name(node.target) or "")
        elif isinstance(node, A.Call):
            callee = _callee(node, pou, pous)
            formals = [] if callee is None else \
                [v for v in callee.vars.values() if v.kind in (A.VAR_INPUT, A.VAR_IN_OUT)]
            for k, arg in enumerate(node.args):
                param = None if callee is None else \
                    callee.vars.get(arg.name.upper()) if arg.name else \
                    formals[k] if k < len(formals) else None
                if arg.is_output or (param is not None and param.kind == A.VAR_IN_OUT):
                    names.add(_root_name(arg.value) or "")
    return names


def _pou_constants(pou: PouSym, pous: Mapping[str, PouSym]) -> dict[str, int]:
    """Integer constants, and the fields of the code STRUCTs (error codes, registers) the POU
    reads: plain VARs without an initialiser (STruC++ takes no STRUCT constant without an
    initialiser, and no dialect but MatIEC's takes a STRUCT initialiser everywhere), whose
    values are the type's field defaults as long as the POU never writes them."""
    out: dict[str, int] = {}
    written = _written(pou, pous) if pou.node is not None else set()
    for var in pou.vars.values():
        if var.constant and isinstance(var.init, Literal) and var.init.kind == "int":
            out[var.name] = int(var.init.value)
        elif isinstance(var.type, StructType) and var.init is None and (
                var.constant or (var.kind == A.VAR and var.key not in written)):
            for key, (spelling, _) in var.type.fields.items():
                init = var.type.inits.get(key)
                if isinstance(init, Literal) and init.kind == "int":
                    out[f"{var.name}.{spelling}"] = int(init.value)
    return out


@cache
def _controller_analysis() -> tuple[CheckedProgram, InstanceModel]:
    # one analysis of the library + controller serves both the map and the constants
    return _analysed(SOURCES, None)


@cache
def controller_constants() -> dict[str, int]:
    """The controller's integer constants, computed once per process: the program's, and
    those of its blocks (plc_project/controller/*.st), where each command's code is declared
    by the block that runs it. A name two blocks give different values (a block's private
    constant, e.g. a call mode) is left out unless the program declares it."""
    prog, inst = _controller_analysis()
    out = _pou_constants(inst.pou, prog.pous)
    merged: dict[str, int] = {}
    ambiguous: set[str] = set()
    parts = {str(Path(p).resolve()) for p in COMPONENTS}
    for pou in prog.pous.values():
        if pou.node is None or str(Path(pou.node.pos.file).resolve()) not in parts:
            continue
        for name, value in _pou_constants(pou, prog.pous).items():
            if merged.setdefault(name, value) != value:
                ambiguous.add(name)
    for name, value in merged.items():
        if name not in ambiguous:
            out.setdefault(name, value)
    return out


def controller_map(flavor: str | Flavor = mm.OPENPLC) -> dict[str, Register]:
    """The controller's map on a ``flavor`` server by variable name (upper case), computed
    once per process and flavor."""
    return _controller_map(mm.flavor(flavor))


@cache
def _controller_map(flavor: Flavor) -> dict[str, Register]:
    prog, inst = _controller_analysis()
    return {r.name.upper(): r for r in _registers(prog, inst, flavor)}


def _header_sections(names: Sequence[str]) -> list[str]:
    """The named sections of Controller.st's header comment, verbatim (one source)."""
    text = CONTROLLER.read_text(encoding="utf-8")
    header = text[text.index("(*") + 2: text.index("*)")].splitlines()
    out: list[str] = []
    keep = False
    for line in header:
        body = line[3:] if line.startswith("   ") else line.strip()
        heading = re.match(r"^([A-Z][A-Z -]+[A-Z])(:|\b)", body)
        if heading and not body.startswith(" ") and body.split(":")[0].split(" (")[0] == \
                body.split(":")[0].split(" (")[0].upper():
            keep = any(body.startswith(n) for n in names)
        if keep and not body.startswith("====="):
            out.append(body.rstrip())
    while out and not out[-1]:
        out.pop()
    return out


def _example(regs: dict[str, Register]) -> list[str]:
    """A MoveJoints command in mailbox 1, word by word, from the map itself."""
    first = regs["MBX01SEQ"]
    seq, session, code = 1, 1234, 2
    values = {"SEQ": seq, "SESSION": session, "CODE": code, "INT1": 0, "INT2": 0,
              "ARG1": 10.0, "ARG2": 70.0, "ARG3": 65.0, "ARG4": 0.0, "ARG5": 0.0, "ARG6": 0.0,
              "CHECK": check_word(seq, session, code, 0, 0, (10.0, 70.0, 65.0))}
    words: list[int] = []
    for field, value in values.items():
        r = regs[f"MBX01{field}"]
        t = r.st_type.upper()
        words += (mm.real_to_words(float(value)) if t == "REAL" else
                  mm.udint_to_words(int(value)) if t == "UDINT" else
                  mm.dint_to_words(int(value)))
    answer = regs["MBX01OWNER"]
    return [
        "Example: a client with session 1234 moves the joints to (10, 70, 65) deg through",
        f"mailbox 1. One function-16 request at holding register {first.address} with "
        f"{len(words)} registers:",
        "",
        "```",
        " ".join(f"{w:04X}" for w in words),
        "```",
        "",
        "(Seq 1, Session 1234, Code 2, Int1 0, Int2 0, Arg1..Arg3 10.0/70.0/65.0 as REALs, "
        "Arg4..Arg6 0.0,",
        "Check = the CRC-32 (zlib's crc32) of the first 22 of these registers as sent, 44 "
        "bytes: in Python",
        f"`zlib.crc32(struct.pack(\">5i6f\", 1, 1234, 2, 0, 0, 10.0, 70.0, 65.0, 0.0, 0.0, 0.0))` "
        f"= {values['CHECK']} = 0x{values['CHECK']:08X}). "
        f"Then read the 8 registers at {answer.address} (Owner,",
        f"AckSeq, Result, AckCheck) until Owner = 1234, AckSeq = 1 and AckCheck = "
        f"{values['CHECK']}: Result is the command's result.",
        "",
    ]


def _v4_counts() -> str:
    """The OpenPLC v4 Modbus counts the controller's map needs (openplc_v4.required_counts)."""
    from .softplc.openplc_v4 import required_counts

    pm = program_map(list(SOURCES))
    needed = required_counts([r.location for r in pm.registers]
                             + [u.location for u in pm.unreachable])
    return ",".join(f"{k}={v}" for k, v in needed.items())


def render_markdown(regs: Sequence[Register]) -> str:
    out = [
        "# Controller register map",
        "",
        "Generated from the located variables of `plc_project/Controller.st` by",
        "`python -m armbench.registermap` -- do not edit; `tests/modbus/test_registermap.py`",
        "fails when this file is stale. Addresses are 0-based Modbus addresses of OpenPLC v3",
        "(docs/matiec-facts.md); 32-bit values take two registers, most significant word first.",
        "The protocol below is the header of `Controller.st`, copied verbatim.",
        "`armbench.controller_client.ArmControllerClient` implements the client side.",
        "",
        "OpenPLC v4 serves these addresses only with its Modbus server's counts",
        f"`{_v4_counts()}` (shorter %QW or %MW segments move %MW and %MD down); the",
        "exported v4 project carries them ([docs/raspberry-pi.md](raspberry-pi.md), step 4):",
        "[OpenPLC v3 and v4 side by side](modbus-parity.md#openplc-v3-and-v4-side-by-side).",
        "",
        "```text",
        *_header_sections(("SELF-DEFENCE", "HANDSHAKE", "COMMANDS", "MOTION",
                           "PWM DRIVER FAULT", "RESULT CODES", "LUT COMMANDS",
                           "IMU COMMANDS")),
        "```",
        "",
        *_example({r.name.upper(): r for r in regs}),
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
    try:
        checkout = find_checkout()
    except LocateError as exc:
        print(f"python -m armbench.registermap: {exc}", file=sys.stderr)
        return 2
    sources = checkout.sources()
    target = Path(args[0]) if args else checkout.root / "docs" / "register-map.md"
    target.write_text(render_markdown(derive(sources)), encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
