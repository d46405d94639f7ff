"""A user's own ST program under test: its located variables by name, typed from their
declarations and addressed by a Modbus flavor's map (OpenPLC's by default, or the CODESYS
variant's: ``flavor="codesys"``); a soft PLC running it on a loopback port, serving that
flavor's layout; and the check that a PLC found by address runs it.

Used by the pytest plugin (:mod:`armbench.harness.pytest_plugin`), which imports this module
only when a test asks for one of its fixtures; usable on its own too::

    program = PlcProgram.load(["tank.st"])
    with serve_program(program) as plc, plc.connect() as v:
        v["LevelPct"] = 12.5
        v.wait_scans(1)
        assert v["Pump"] is True

Identity: a program that declares a located integer variable named ``Signature`` (or the name
given as ``signature``) with a non-zero literal initial value, e.g. ``Signature AT %MD0 :
UDINT := 16#7A4B0001;``, is recognised by it: a PLC whose variable at that place holds another
value runs another program (or another version of it). A program that declares a located
``ScanCount`` (or ``scan_counter``) it increments once per scan gets scan-based waiting on any
PLC, and a PLC whose counter does not move is reported as stopped. Under the CODESYS layout a
signature the program never assigns sits in a holding register, whose data overwrites the
initial value on a CODESYS PLC: it identifies nothing there, and only the scan counter is
checked (with a warning that says so).
"""

from __future__ import annotations

import contextlib
import inspect
import math
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..softplc import modbus_map as mm
from ..softplc.modbus_map import Flavor

if TYPE_CHECKING:
    from ..compiler.symbols import CheckedProgram, VarSym
    from ..softplc.codesys_device import CodesysDevice
    from ..softplc.modbus_client import PlcClient
    from ..softplc.openplc_v4 import OpenPlcV4Device
    from ..softplc.scan import SoftPlc

Value = bool | int | float

DEFAULT_SIGNATURE = "Signature"
DEFAULT_SCAN_COUNTER = "ScanCount"
# How long wait_until and wait_scans wait when the call says nothing: long enough for a few
# hundred scans of a 10 ms task on a loaded machine, short enough that a condition that never
# holds fails its test soon. The pytest plugin sets it from --plc-wait-timeout.
DEFAULT_WAIT_TIMEOUT_S = 5.0

_INTEGER_TYPES = frozenset({"INT", "UINT", "WORD", "DINT", "UDINT", "DWORD", "LINT", "ULINT",
                            "LWORD"})
# FC16 carries at most 123 registers (Modbus) and OpenPLC answers FC3 with at most 127.
_MAX_WRITE_REGS = 123


class ProgramError(Exception):
    """The program, or what a test asked of it, does not fit; the message says how to fix it."""


class UnknownVariable(ProgramError, KeyError):
    """No located variable of that name in the program."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class ReadOnlyVariable(ProgramError):
    """Modbus reads it, nothing over Modbus writes it: an input (%IX, %IW) under OpenPLC, whose
    I/O writes it; an output of the program (an input register or discrete input) under
    CODESYS."""


@dataclass(frozen=True)
class Variable:
    """One located variable as seen over Modbus, on a flavor's server (OpenPLC's map,
    docs/modbus-parity.md, or the CODESYS variant's layout)."""

    name: str
    st_type: str  # elementary type, upper case
    location: str  # where the flavor has it: "%MD2" (OpenPLC), "%QD2" (CODESYS)
    table: str  # "coil" | "discrete" | "input" | "holding"
    address: int  # first Modbus address (0-based)
    count: int  # bits or registers it takes
    instance: str | None  # the program instance declaring it; None for a global
    description: str  # the comment on its declaration line
    flavor: Flavor = mm.OPENPLC
    declared: str = ""  # the address in the source when the flavor moved it ("": location)

    @property
    def source_location(self) -> str:
        """The address the program declares."""
        return self.declared or self.location

    @property
    def writable(self) -> bool:
        """Coils and holding registers (OpenPLC: %QX, %QW, %MW, %MD, %ML; CODESYS: what the
        program never assigns); the other tables are read-only."""
        return self.table in ("coil", "holding")

    def encode(self, value: Value) -> list[int]:
        """The registers of ``value`` in the flavor's word order; TypeError/ValueError when
        the value does not fit the variable's type."""
        code = self._code()
        if self.st_type in _INTEGER_TYPES:
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"{self.name} is {self.st_type}: give an int, not "
                                f"{type(value).__name__} {value!r}")
            bits = 16 * self.count
            low, high = ((-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if code.islower()
                         else (0, (1 << bits) - 1))
            if not low <= value <= high:
                raise ValueError(f"{self.name} is {self.st_type} ({low}..{high}): {value} "
                                 "does not fit")
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{self.name} is {self.st_type}: give a number, not "
                                f"{type(value).__name__} {value!r}")
            if (self.st_type == "REAL" and math.isfinite(value)
                    and abs(value) > 3.4028234663852886e38):
                raise ValueError(f"{self.name} is REAL: {value} is beyond its range")
        return self.flavor.encode(self.st_type, value)

    def decode(self, words: Sequence[int]) -> Value:
        self._code()
        return self.flavor.decode(self.st_type, list(words))

    def _code(self) -> str:
        code = mm.struct_code(self.st_type)
        if code is None or self.table in ("coil", "discrete"):
            raise TypeError(f"{self.name} ({self.st_type} at {self.location}) has no Modbus "
                            "register encoding that the PLCs and the bench share")
        return code


@dataclass(frozen=True)
class Signature:
    """The program's identity: a located integer variable and its declared initial value."""

    variable: Variable
    value: int

    @property
    def readable(self) -> bool:
        """The PLC shows the initial value over Modbus: always under OpenPLC (the variable is
        the register); under CODESYS only in the %Q area (the program assigns it), as the
        holding registers' data overwrites the %I variables, initial values and all."""
        return self.variable.flavor.openplc_map or not self.variable.writable


@dataclass(frozen=True)
class PlcProgram:
    """The program a PLC under test runs: the ST files, the map of its located variables by
    (case-insensitive) name, its identity and scan counter when it declares them."""

    given: tuple[Path, ...]  # the user's files
    files: tuple[Path, ...]  # what is compiled: the user's files, then library files
    variables: Mapping[str, Variable]  # upper-case name (or INSTANCE.NAME) -> variable
    unreachable: Mapping[str, str]  # upper-case name -> location Modbus cannot reach
    signature: Signature | None
    scan_counter: Variable | None
    scan_task: str  # the TASK of the first program instance: what "a scan" means
    scan_interval_ns: int
    notes: tuple[str, ...] = ()  # library files left out, and why
    checked: CheckedProgram | None = field(default=None, repr=False, compare=False)
    flavor: Flavor = mm.OPENPLC  # whose Modbus layout the variables' tables and addresses are

    @property
    def name(self) -> str:
        """The user's files, for messages: ``tank.st`` or ``a.st, b.st``."""
        return ", ".join(p.name for p in self.given)

    @classmethod
    def load(cls, files: Sequence[str | Path], *, library: bool = True,
             signature: str | None = None, scan_counter: str | None = None,
             flavor: str | Flavor = mm.OPENPLC) -> PlcProgram:
        """Check ``files`` (with the armbench ST library, as ``armbench run`` does, unless
        ``library`` is False) and read the map from their declarations, as ``flavor``'s
        server lays them out. ``signature`` and ``scan_counter`` name those variables when
        they are not called ``Signature`` and ``ScanCount``; a name given here must exist.
        Raises CompileFailed with the diagnostics when the files do not check, ProgramError
        when the program cannot be tested over Modbus."""
        from ..compiler.driver import expand

        given = tuple(expand(files))
        if not given:
            raise ProgramError(f"no .st files in {', '.join(map(str, files))}")
        missing = [str(p) for p in given if not p.is_file()]
        if missing:
            raise ProgramError(f"no such file: {', '.join(missing)}")
        checked, compiled, notes = _analysed(given, library)
        return cls.from_checked(checked, given, compiled, notes=notes, signature=signature,
                                scan_counter=scan_counter, flavor=flavor)

    @classmethod
    def from_checked(cls, checked: CheckedProgram, given: Sequence[Path],
                     compiled: Sequence[Path], *, notes: Sequence[str] = (),
                     signature: str | None = None, scan_counter: str | None = None,
                     flavor: str | Flavor = mm.OPENPLC) -> PlcProgram:
        from ..registermap import program_map

        if checked.config is None or not checked.config.instances:
            raise ProgramError("the program has no CONFIGURATION with a program instance: a "
                               "PLC runs CONFIGURATION Config0 / RESOURCE Res0 / TASK / "
                               "PROGRAM ... WITH")
        fl = mm.flavor(flavor)
        pmap = program_map(checked, fl)
        spelled = Counter(reg.name.upper() for reg in pmap.registers)
        variables: dict[str, Variable] = {}
        for reg, inst in zip(pmap.registers, pmap.instances, strict=True):
            var = Variable(reg.name, reg.st_type.upper(), reg.location, reg.table, reg.address,
                           reg.count, inst, reg.description, fl, reg.declared)
            if spelled[reg.name.upper()] == 1:  # else reached as INSTANCE.NAME only
                variables[reg.name.upper()] = var
            if inst is not None:
                variables[f"{inst.upper()}.{reg.name.upper()}"] = var
        first = checked.config.instances[0]
        task = next((t for t in checked.config.tasks
                     if first.task is not None and t.name.upper() == first.task.upper()),
                     checked.config.tasks[0])
        sig = _signature(checked, variables, signature)
        counter = _scan_counter(variables, scan_counter)
        return cls(tuple(given), tuple(compiled), variables,
                   {u.name.upper(): u.location for u in pmap.unreachable}, sig, counter,
                   task.name, task.interval_ns, tuple(notes), checked, fl)

    def with_flavor(self, flavor: str | Flavor) -> PlcProgram:
        """The same program as ``flavor``'s server lays it out."""
        fl = mm.flavor(flavor)
        if fl == self.flavor:
            return self
        if self.checked is None:
            raise ProgramError("the program was not checked: build it with PlcProgram.load")
        return PlcProgram.from_checked(
            self.checked, self.given, self.files, notes=self.notes,
            signature=None if self.signature is None else self.signature.variable.name,
            scan_counter=None if self.scan_counter is None else self.scan_counter.name,
            flavor=fl)

    def names(self) -> list[str]:
        """Every located variable Modbus reaches, once, in declaration order: by its name, or
        as Instance.Name when two program instances declare that name."""
        out: list[str] = []
        seen: set[int] = set()
        for var in self.variables.values():
            if id(var) in seen:
                continue
            seen.add(id(var))
            plain = self.variables.get(var.name.upper())
            out.append(var.name if plain is var else f"{var.instance}.{var.name}")
        return out

    def variable(self, name: str) -> Variable:
        """The located variable ``name`` (case-insensitive; Instance.Name also works)."""
        key = name.upper()
        var = self.variables.get(key)
        if var is not None:
            return var
        if key in self.unreachable:
            server = ("OpenPLC does not serve over Modbus (it serves %IX %QX %IW %QW %MW %MD "
                      "%ML)" if self.flavor.openplc_map else
                      f"the {self.flavor.title} layout does not serve over Modbus (it places "
                      "only the programs' own located variables)")
            raise UnknownVariable(f"{name} is located at {self.unreachable[key]}, which "
                                  f"{server}")
        owners = [f"{v.instance}.{v.name}" for k, v in self.variables.items()
                  if k.endswith(f".{key}")]
        if owners:
            raise UnknownVariable(f"{name} is declared by {len(owners)} program instances: "
                                  f"say which, {' or '.join(owners)}")
        names = self.names()
        near = [n for n in names if key in n.upper() or n.upper() in key]
        hint = f" (did you mean {', '.join(near[:3])}?)" if near else ""
        listed = ", ".join(names)
        raise UnknownVariable(f"{self.name} declares no located variable {name}{hint}; it has "
                              f"{len(names)}: {listed if len(listed) < 300 else listed[:300]}")


def _analysed(given: Sequence[Path], library: bool
              ) -> tuple[CheckedProgram, tuple[Path, ...], tuple[str, ...]]:
    """The user's files checked with what they use of the armbench library, as ``armbench
    run/serve`` do (so a program that runs there runs here; the names OpenPLC's upload needs
    are not asked for): the checked program, the files it was compiled from, and the
    library's note. Raises CompileFailed."""
    from ..compiler.diagnostics import CompileFailed
    from ..compiler.driver import analyse_program
    from ..compiler.targets import SOFT_PLC
    from ..locate import select_library

    selection = select_library(given, library)
    analysis = analyse_program(selection.given, selection.library, SOFT_PLC)
    files = (*selection.given, *map(Path, analysis.library.files))
    if analysis.program is None:
        raise CompileFailed(analysis.diagnostics.sorted())
    note = analysis.library.note()
    return analysis.program, files, () if note is None else (note,)


def _signature(checked: CheckedProgram, variables: Mapping[str, Variable],
               name: str | None) -> Signature | None:
    from ..compiler.ast import Literal

    var = variables.get((name or DEFAULT_SIGNATURE).upper())
    if var is None:
        if name is not None:
            raise ProgramError(f"the program declares no located variable {name} to check "
                               "its identity by (--plc-signature)")
        return None
    sym = _symbol(checked, var)
    if var.st_type not in _INTEGER_TYPES:
        raise ProgramError(f"the signature {var.name} is {var.st_type}: declare it as an "
                           "integer (UDINT, DINT, ...) at a %MD, %MW, %QW or %ML location")
    init = None if sym is None else sym.init
    where = var.source_location
    if not isinstance(init, Literal) or init.kind != "int" or int(init.value) == 0:
        raise ProgramError(f"the signature {var.name} ({where}) needs a non-zero "
                           f"literal initial value, e.g. `{var.name} AT {where} : "
                           f"{var.st_type} := 16#5EED0001;` (0 is what an empty PLC reads)")
    return Signature(var, int(init.value))


def _symbol(checked: CheckedProgram, var: Variable) -> VarSym | None:
    assert checked.config is not None
    if var.instance is None:
        return checked.config.globals.get(var.name.upper())
    inst = next(i for i in checked.config.instances if i.name == var.instance)
    return inst.pou.vars.get(var.name.upper())


def _scan_counter(variables: Mapping[str, Variable], name: str | None) -> Variable | None:
    var = variables.get((name or DEFAULT_SCAN_COUNTER).upper())
    if var is None:
        if name is not None:
            raise ProgramError(f"the program declares no located variable {name} to count "
                               "scans by (--plc-scan-counter)")
        return None
    if var.st_type not in _INTEGER_TYPES:
        raise ProgramError(f"the scan counter {var.name} is {var.st_type}: declare it as an "
                           "integer the program increments every scan")
    return var


class PlcVariables(Mapping[str, Value]):
    """Typed access to a program's located variables over Modbus: ``v["Level"]`` reads,
    ``v["Level"] = 12.5`` writes (BOOL as a coil, the rest in registers, 32/64-bit values in
    one request), by the names and types the program declares.

    ``scans`` counts the PLC's scans when the program has no scan counter (the soft PLC's
    own count); ``fault`` reports a soft PLC's fault so a wait does not run into a timeout;
    ``wait_timeout_s`` is how long :meth:`wait_until` and :meth:`wait_scans` wait when the
    call gives no ``timeout_s`` (default 5 s; the plugin's ``--plc-wait-timeout``).
    """

    def __init__(self, client: PlcClient, program: PlcProgram, *,
                 scans: Callable[[], int] | None = None,
                 fault: Callable[[], str | None] | None = None,
                 owns_client: bool = False,
                 wait_timeout_s: float = DEFAULT_WAIT_TIMEOUT_S) -> None:
        self.client = client
        self.program = program
        self._scans = scans
        self._fault = fault
        self._owns_client = owns_client
        self.wait_timeout_s = _timeout(wait_timeout_s, "wait_timeout_s")

    def __enter__(self) -> PlcVariables:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._owns_client:
            self.client.close()

    # -- Mapping -----------------------------------------------------------------------------

    def __getitem__(self, name: str) -> Value:
        return self.read_variable(self.program.variable(name))

    def __setitem__(self, name: str, value: Value) -> None:
        self.write({name: value})

    def __iter__(self) -> Iterator[str]:
        return iter(self.program.names())

    def __len__(self) -> int:
        return len(self.program.names())

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.upper() in self.program.variables

    # -- reads and writes --------------------------------------------------------------------

    def read_variable(self, var: Variable) -> Value:
        c = self.client
        if var.table == "coil":
            return bool(c.read_coils(var.address, 1)[0])
        if var.table == "discrete":
            return bool(c.read_discrete_inputs(var.address, 1)[0])
        if var.table == "input":
            return var.decode(c.read_input_registers(var.address, var.count))
        return var.decode(c.read_holding_registers(var.address, var.count))

    def read(self, *names: str) -> dict[str, Value]:
        """Several variables by name (every one when no name is given), one request each."""
        return {n: self[n] for n in (names or tuple(self))}

    def write(self, values: Mapping[str, Value] | None = None, /, **named: Value) -> None:
        """Write variables by name; neighbours in one table go in one request (function 15
        or 16, which OpenPLC applies between two scans), so a scan sees all or none of them.
        Every value is checked against its variable's type before anything is sent."""
        items = [*(values or {}).items(), *named.items()]
        coils: list[tuple[int, bool]] = []
        regs: list[tuple[int, list[int]]] = []
        for name, value in items:
            var = self.program.variable(name)
            if not var.writable:
                raise ReadOnlyVariable(_read_only(var))
            if var.table == "coil":
                if not isinstance(value, bool):
                    raise TypeError(f"{var.name} is BOOL: give True or False, not {value!r}")
                coils.append((var.address, value))
            else:
                regs.append((var.address, var.encode(value)))
        for address, run in _runs([(a, [v]) for a, v in coils]):
            self.client.write_coils(address, run)
        for address, run in _runs(regs, limit=_MAX_WRITE_REGS):
            self.client.write_registers(address, run)

    # -- waiting -----------------------------------------------------------------------------

    def scan_count(self) -> int:
        """The PLC's scans so far: the program's scan counter, else the soft PLC's count."""
        counter = self.program.scan_counter
        if counter is not None:
            value = self.read_variable(counter)
            return int(value) % (1 << (16 * counter.count))
        if self._scans is not None:
            return self._scans()
        raise ProgramError(
            f"{self.program.name} declares no scan counter, so scans of a PLC found by address "
            f"cannot be counted: declare e.g. `{DEFAULT_SCAN_COUNTER} AT %MD1 : UDINT;` and "
            f"`{DEFAULT_SCAN_COUNTER} := {DEFAULT_SCAN_COUNTER} + 1;` in the program, or use "
            "wait_until")

    def wait_scans(self, scans: int = 1, timeout_s: float | None = None) -> None:
        """Return once the PLC has run ``scans`` whole scans after the call: after a write,
        ``wait_scans(1)`` means the program has run on the new value at least once (a write
        lands between two scans). Raises TimeoutError when the PLC has not run them within
        ``timeout_s`` seconds (default :attr:`wait_timeout_s`, 5 s unless set: a PLC that
        stopped scanning)."""
        if scans < 0:
            raise ValueError(f"cannot wait for {scans} scans")
        limit = self.wait_timeout_s if timeout_s is None else _timeout(timeout_s, "timeout_s")
        counter = self.program.scan_counter
        modulus = 1 << (16 * counter.count) if counter is not None else 1 << 64
        start = self.scan_count()
        deadline = time.monotonic() + limit
        pause = min(0.002, self.program.scan_interval_ns / 4e9)
        while (self.scan_count() - start) % modulus < scans:
            self._raise_fault()
            if time.monotonic() > deadline:
                raise TimeoutError(f"wait_scans({scans}) gave up after {limit:g} s: the PLC ran "
                                   f"fewer scans ({self.program.name}: is it running?); "
                                   f"{_raise_the_limit(limit)}")
            time.sleep(pause)

    def wait_until(self, name: str, condition: Callable[[Value], bool] | Value,
                   timeout_s: float | None = None) -> Value:
        """Read ``name`` again and again (a few times per scan) until it equals
        ``condition``, or until ``condition(value)`` is true when ``condition`` is callable;
        return the value that satisfied it.

        Gives up after ``timeout_s`` seconds, by default :attr:`wait_timeout_s`: 5 s unless
        the pytest plugin's ``--plc-wait-timeout S`` (or ``plc_wait_timeout = S`` in the ini
        file) set another. Then it raises TimeoutError naming the variable, the condition and
        the last value read. A soft PLC in FAULT ends the wait at once with ProgramError."""
        limit = self.wait_timeout_s if timeout_s is None else _timeout(timeout_s, "timeout_s")
        test: Callable[[Value], bool] = (condition if callable(condition)
                                         else lambda v: v == condition)
        var = self.program.variable(name)
        deadline = time.monotonic() + limit
        pause = min(0.005, self.program.scan_interval_ns / 2e9)
        while True:
            value = self.read_variable(var)
            if test(value):
                return value
            self._raise_fault()
            if time.monotonic() > deadline:
                what = describe_condition(condition) if callable(condition) else repr(condition)
                raise TimeoutError(f"wait_until({var.name!r}, {what}) gave up after {limit:g} "
                                   f"s: {var.name} last read {value!r}; "
                                   f"{_raise_the_limit(limit)}")
            time.sleep(pause)

    def _raise_fault(self) -> None:
        reason = self._fault() if self._fault is not None else None
        if reason is not None:
            raise ProgramError(f"the soft PLC running {self.program.name} is in FAULT: {reason}")


def _timeout(value: float, what: str) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{what} must be a number of seconds above 0, not {value!r}")
    return float(value)


def _raise_the_limit(limit: float) -> str:
    more = f"{limit * 4:g}"
    return (f"if it only needs longer, raise the limit: timeout_s={more} on this call, or for "
            f"every wait the pytest option --plc-wait-timeout {more} (plc_wait_timeout = "
            f"{more} in the ini file)")


def describe_condition(condition: Callable[..., object]) -> str:
    """A wait's predicate as the test spells it: a lambda's source (``lambda v: v > 50.0``),
    else its name, with the file and line where it is defined."""
    code = getattr(condition, "__code__", None)
    where = f" ({Path(code.co_filename).name}:{code.co_firstlineno})" if code is not None else ""
    name = getattr(condition, "__name__", None)
    if name == "<lambda>":
        return (_lambda_source(condition) or "a lambda") + where
    if name is None:
        return repr(condition)
    return str(getattr(condition, "__qualname__", name)) + where


def _lambda_source(fn: Callable[..., object]) -> str | None:
    """The text of the first lambda on the line ``fn`` is defined on, up to the comma, the
    closing bracket or the end of line that ends it (None when the source is not at hand)."""
    try:
        lines, _ = inspect.getsourcelines(fn)
    except (OSError, TypeError):
        return None
    line = lines[0] if lines else ""
    start = line.find("lambda")
    if start < 0:
        return None
    text = line[start:].rstrip()
    depth = 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
        elif ch in ")]}" or ch == ",":
            if depth == 0:
                return text[:i].strip()
            if ch != ",":
                depth -= 1
    return text.strip()


def _read_only(var: Variable) -> str:
    """Why ``var`` cannot be written over Modbus, and what writes it."""
    if var.flavor.openplc_map:
        return (f"{var.name} at {var.location} is an input: Modbus reads it, the PLC's I/O "
                "writes it (on the soft PLC, ProgramPlc.set_input writes it)")
    kind = "a discrete input" if var.table == "discrete" else "an input register"
    return (f"{var.name} ({var.source_location}) is an output of the program in the "
            f"{var.flavor.title} layout, {var.location}: {kind}, which Modbus reads and only "
            "the program writes")


def _runs(items: Sequence[tuple[int, list[Any]]],
          limit: int = 1968) -> Iterator[tuple[int, list[Any]]]:
    """Values at addresses merged into runs of neighbours (at most ``limit`` long)."""
    start = -1
    run: list[Any] = []
    for address, values in sorted(items, key=lambda item: item[0]):
        if run and address == start + len(run) and len(run) + len(values) <= limit:
            run += values
            continue
        if run:
            yield start, run
        start, run = address, list(values)
    if run:
        yield start, run


def check_identity(client: PlcClient, program: PlcProgram, timeout_s: float = 3.0) -> str | None:
    """None when the PLC on ``client`` runs ``program`` as far as its signature (where the
    flavor shows it: :attr:`Signature.readable`) and scan counter tell (nothing to tell:
    None); else why not, in one line. A Modbus exception reply raises ModbusError."""
    v = PlcVariables(client, program)
    sig = program.signature
    if sig is not None and sig.readable:
        seen = v.read_variable(sig.variable)
        if seen != sig.value:
            return (f"runs another program (or another version of {program.name}): "
                    f"{sig.variable.name} at {sig.variable.location} reads "
                    f"{_show(seen, sig.value)}, {program.name} declares {_show(sig.value)}")
    counter = program.scan_counter
    if counter is not None:
        first = v.scan_count()
        deadline = time.monotonic() + timeout_s
        while v.scan_count() == first:
            if time.monotonic() > deadline:
                return (f"does not scan {program.name}: its scan counter {counter.name} "
                        f"({counter.location}) stays at {first} for {timeout_s:g} s")
            time.sleep(min(0.01, program.scan_interval_ns / 2e9))
    return None


def other_flavor(client: PlcClient, program: PlcProgram,
                 timeout_s: float = 3.0) -> Flavor | None:
    """The flavor other than ``program``'s whose layout the PLC on ``client`` shows the program
    in (for a session that speaks the wrong one): its signature matches there and its scan
    counter moves, whichever of the two it can be told by; None when no other flavor does, or
    nothing tells (no readable signature, no scan counter)."""
    from ..softplc.modbus_client import ModbusError, ModbusIoError

    # A quick look: a counter that moves at all moves within a few dozen scans; the session's
    # own flavor has had the whole timeout already.
    look_s = min(timeout_s, max(0.5, 20 * program.scan_interval_ns / 1e9))
    for fl in mm.FLAVORS.values():
        if fl.layout == program.flavor.layout:  # the same addresses tell nothing apart
            continue
        other = program.with_flavor(fl)
        sig = other.signature
        if (sig is None or not sig.readable) and other.scan_counter is None:
            continue
        try:
            if check_identity(client, other, look_s) is None:
                return fl
        except (ModbusError, ModbusIoError):
            continue
    return None


def openplc_generation(host: str, port: int, timeout_s: float = 3.0) -> str | None:
    """Which OpenPLC's Modbus server answers at host:port, told by a read of holding register
    0 for unit id 2: "openplc" when it is answered (v3 ignores the unit id), "openplc-v4" when
    it gets exception 0x0B (v4's plugin serves unit id 1 only); None for anything else."""
    from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient

    try:
        with PlcClient(host, port, timeout_s=timeout_s, device_id=2) as client:
            client.read_holding_registers(0, 1)
    except ModbusError as exc:
        return "openplc-v4" if exc.code == 0x0B else None
    except ModbusIoError:
        return None
    return "openplc"


def _show(value: Value, like: Value | None = None) -> str:
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0 and \
            (like is None or isinstance(like, int)):
        return f"16#{value:X}"
    return repr(value)


# -- a soft PLC running the program -------------------------------------------------------------


@dataclass
class ProgramPlc:
    """A PLC running a :class:`PlcProgram`: a soft PLC this process started (``soft``) or a
    PLC found by address."""

    host: str
    port: int
    program: PlcProgram
    soft: SoftPlc | None = None
    # the soft PLC's Modbus device: CODESYS layout, or OpenPLC v4's plugin
    device: CodesysDevice | OpenPlcV4Device | None = None
    _clients: list[PlcVariables] = field(default_factory=list, repr=False)

    @property
    def address(self) -> tuple[str, int]:
        return self.host, self.port

    def connect(self, timeout_s: float = 3.0,
                wait_timeout_s: float = DEFAULT_WAIT_TIMEOUT_S) -> PlcVariables:
        """Typed access on a connection of its own (closed by ``with`` or :meth:`close`);
        ``timeout_s``: of one Modbus request, ``wait_timeout_s``: of its waits by default."""
        from ..softplc.modbus_client import PlcClient

        _timeout(wait_timeout_s, "wait_timeout_s")  # before a connection is opened
        client = PlcClient(self.host, self.port, timeout_s=timeout_s)
        client.connect()
        v = PlcVariables(client, self.program, owns_client=True,
                         scans=self.scans if self.soft is not None else None,
                         fault=self.fault if self.soft is not None else None,
                         wait_timeout_s=wait_timeout_s)
        self._clients.append(v)
        return v

    def close(self) -> None:
        """Close the connections :meth:`connect` opened."""
        for v in self._clients:
            v.__exit__()
        self._clients.clear()

    def scans(self) -> int:
        """The soft PLC's scans of the program's task so far (:attr:`PlcProgram.scan_task`)."""
        stats = self._soft().stats()
        task = self.program.scan_task.upper()
        return next(st.scans for name, st in stats.items() if name.upper() == task)

    def fault(self) -> str | None:
        """The soft PLC's fault as ``file:line:col: message``, None while it runs."""
        info = self._soft().fault
        return None if info is None else f"{info.location}: {info.message}"

    def set_input(self, name: str, value: Value) -> None:
        """Soft PLC only: write an input (%IX, %IW), as the PLC's I/O would, between scans
        (under the CODESYS layout, where inputs are holding registers and coils: into the
        Modbus device's data, which the next scan copies in)."""
        var = self.program.variable(name)
        plc = self._soft()
        if not var.source_location.upper().startswith("%I"):
            raise ProgramError(f"{var.name} at {var.source_location} is not an input: write it "
                               "over Modbus (plc_vars[name] = value)")
        if var.table in ("coil", "discrete") and not isinstance(value, bool):
            raise TypeError(f"{var.name} is BOOL: give True or False, not {value!r}")
        from ..softplc.codesys_device import CodesysDevice

        # OpenPLC v4's I/O plugins write inputs through its journal, which the next scan
        # drains: the same as this write under the scan lock, between two scans
        if isinstance(self.device, CodesysDevice):
            if var.table == "coil":
                self.device.store_coil(var.address, bool(value))
            else:
                self.device.store_registers(var.address, var.encode(value))
        elif var.table == "discrete":
            with plc.lock:
                plc.image.ix[var.address] = int(value)
        else:
            (word,) = var.encode(value)
            with plc.lock:
                plc.image.iw[var.address] = word

    def _soft(self) -> SoftPlc:
        if self.soft is None:
            raise ProgramError(f"the PLC at {self.host}:{self.port} was found by address: only "
                               "a soft PLC this process runs has this")
        return self.soft


@contextlib.contextmanager
def serve_program(program: PlcProgram, host: str = "127.0.0.1",
                  port: int = 0) -> Iterator[ProgramPlc]:
    """Compile ``program``, run it in a soft PLC (real-time thread) with its Modbus server on
    ``host:port`` (0: a free port), serving the program's flavor's layout; stops both on
    exit."""
    from ..compiler.build import build
    from ..compiler.emit_c import emit
    from ..compiler.ffi import Module
    from ..softplc.loader import LoadedProgram
    from ..softplc.serving import soft_plc

    checked = program.checked
    if checked is None:
        raise ProgramError("the program was not checked: build it with PlcProgram.load")
    unit = emit(checked)
    loaded = LoadedProgram(Module(checked, build(unit), unit.decls))
    try:
        plc, server = soft_plc(loaded, program.flavor, host=host, port=port)
    except ValueError as exc:  # a variable the CODESYS layout cannot bind to the image
        raise ProgramError(str(exc)) from exc
    server.start()
    running = ProgramPlc(host, server.port, program, plc, server.device)
    try:
        plc.start()
        try:
            yield running
        finally:
            running.close()
            plc.stop()
    finally:
        server.stop()
