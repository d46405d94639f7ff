"""Running the same ST on STruC++ and on the bench compiler, and comparing what they compute.

A :class:`ValueProgram` is a PROGRAM that calls library POUs on many inputs in one scan: its
inputs are written into its body as literals (STruC++ 0.6.1 drops the initialiser of a
PROGRAM's array variable, so nothing relies on initialisers), its outputs are
``ARRAY[1..n]`` program variables of one elementary type each. Several programs share one
CONFIGURATION (one instance each) and one source file: the library in dependency order, then
the programs.

STruC++'s side: the CLI's C++ plus a small ``main`` of ours that instantiates the
configuration as the generated header declares it (``strucpp::Configuration_CONFIG0``, one
member per program instance), runs every instance's ``run()`` once and prints every output
element, REAL with ``%.9g`` and LREAL with ``%.17g`` (both round-trip exactly). The bench's
side: ``armbench.compiler.compile_files`` of the same file, one scan of the task.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

# ST type -> (C printf format, C cast) of an output element
_PRINT = {
    "REAL": ("%.9g", "double"), "LREAL": ("%.17g", "double"),
    "BOOL": ("%d", "int"), "SINT": ("%d", "int"), "INT": ("%d", "int"), "DINT": ("%d", "int"),
    "LINT": ("%lld", "long long"), "USINT": ("%u", "unsigned"), "UINT": ("%u", "unsigned"),
    "UDINT": ("%u", "unsigned"), "BYTE": ("%u", "unsigned"), "WORD": ("%u", "unsigned"),
    "DWORD": ("%u", "unsigned"),
}
LINE = re.compile(r"^(\w+)\.(\w+) (\d+) (\S+)$", re.M)

Values = dict[str, list[float]]  # output name (upper case) -> its elements


@dataclass(frozen=True)
class Out:
    """One output: ``ARRAY[1..count] OF st_type``."""

    name: str
    st_type: str
    count: int = 1

    @property
    def real(self) -> bool:
        return self.st_type in ("REAL", "LREAL")


@dataclass(frozen=True)
class ValueProgram:
    """A PROGRAM ``name`` (instance ``name`` + ``Run``): ``locals`` are more VAR lines,
    ``body`` its statements, ``outputs`` what both compilers' answers are compared on."""

    name: str
    outputs: tuple[Out, ...]
    locals: str
    body: str

    @property
    def instance(self) -> str:
        return f"{self.name}Run"

    def st(self) -> str:
        outs = "\n".join(f"    {o.name} : ARRAY[1..{o.count}] OF {o.st_type};"
                         for o in self.outputs)
        return (f"PROGRAM {self.name}\n  VAR\n{outs}\n{self.locals.rstrip()}\n  END_VAR\n"
                f"{self.body.rstrip()}\nEND_PROGRAM\n")


def configuration(programs: Sequence[ValueProgram]) -> str:
    insts = "\n".join(f"    PROGRAM {p.instance} WITH ValueTask : {p.name};" for p in programs)
    return ("CONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            "    TASK ValueTask(INTERVAL := T#20ms, PRIORITY := 0);\n"
            f"{insts}\n  END_RESOURCE\nEND_CONFIGURATION\n")


def source_text(library: str, programs: Sequence[ValueProgram]) -> str:
    """The one ST file both compilers get."""
    return "\n".join([library, *(p.st() for p in programs), configuration(programs)])


def cpp_main(header: str, programs: Sequence[ValueProgram]) -> str:
    """A main that runs one scan of every instance and prints its outputs, one element a
    line: ``INSTANCE.NAME INDEX VALUE``."""
    lines = [f'#include "{header}"', "#include <cstdio>", "",
             "// static: the configuration holds every FB instance of every program",
             "static strucpp::Configuration_CONFIG0 config;", "", "int main() {"]
    for p in programs:
        inst = p.instance.upper()
        lines.append(f"    config.{inst}.run();")
        for o in p.outputs:
            fmt, cast = _PRINT[o.st_type]
            lines.append(f"    for (int i = 1; i <= {o.count}; ++i) "
                         f'std::printf("{p.instance}.{o.name.upper()} %d {fmt}\\n", i, '
                         f"({cast})config.{inst}.{o.name.upper()}.at(i));")
    lines += ["    return 0;", "}", ""]
    return "\n".join(lines)


def parse_printed(stdout: str, programs: Sequence[ValueProgram]) -> dict[str, Values]:
    """What :func:`cpp_main`'s binary printed, by instance, then by output name."""
    wanted = {p.instance.upper(): {o.name.upper(): o for o in p.outputs} for p in programs}
    out: dict[str, Values] = {inst: {name: [math.nan] * o.count for name, o in outs.items()}
                              for inst, outs in wanted.items()}
    for m in LINE.finditer(stdout):
        inst, name, index, text = m[1].upper(), m[2].upper(), int(m[3]), m[4]
        o = wanted[inst][name]
        # %.9g round-trips a float32 only when read back as a float32: as a double it can
        # be off by nearly half a float32 ulp
        value = float(np.float32(text)) if o.st_type == "REAL" else float(text)
        out[inst][name][index - 1] = value if o.real else int(text)
    return out


def bench_values(module: object, programs: Sequence[ValueProgram]) -> dict[str, Values]:
    """One scan of the bench's build of the same file, the outputs by instance and name."""
    module.config_init()  # type: ignore[attr-defined]
    module.run_task_index(0, 0)  # type: ignore[attr-defined]
    out: dict[str, Values] = {}
    for p in programs:
        inst = module.instance(p.instance)  # type: ignore[attr-defined]
        out[p.instance.upper()] = {
            o.name.upper(): [float(v) if o.real else int(v) for v in inst.get(o.name)]
            for o in p.outputs}
    return out


# ------------------------------------------------------------------ ST literals
def st_real(x: float) -> str:
    """An ST real literal of exactly ``x`` (a float32 value, or any float64 for LREAL):
    Python's shortest repr round-trips, and the ST spelling needs digits around the point."""
    if not math.isfinite(x):
        raise ValueError(f"no ST literal for {x}")
    text = repr(float(x))
    mant, _, expo = text.partition("e")
    if "." not in mant:
        mant += ".0"
    return f"{mant}E{expo}" if expo else mant


def st_lint(v: int) -> str:
    """An exact LINT literal: typed (``LINT#``) above 2^31, since STruC++ passes an untyped
    decimal through a JavaScript double (wrong above 2^53)."""
    if v == -(2**63):
        return "(-LINT#9223372036854775807 - LINT#1)"
    if abs(v) < 2**31:
        return str(v)
    return f"-LINT#{-v}" if v < 0 else f"LINT#{v}"


def assign_list(name: str, values: Sequence[float | int], literal: object = st_real) -> str:
    """``Name[1] := v1;`` ... one statement a line."""
    fmt = literal if callable(literal) else st_real
    return "\n".join(f"  {name}[{k}] := {fmt(v)};" for k, v in enumerate(values, start=1))


# ------------------------------------------------------------------ differences
def f32_ulp(x: float) -> float:
    """The spacing of float32 numbers at |x| (the smallest subnormal spacing at 0)."""
    x = abs(x)
    if x < 2.0**-126:
        return 2.0**-149
    return 2.0 ** (math.frexp(x)[1] - 24)


def f64_ulp(x: float) -> float:
    return math.ulp(abs(x)) if x != 0.0 else 5e-324


@dataclass
class Agreement:
    """How far one output of two compilers lies apart: exact elements, the largest
    difference in units in the last place at the larger magnitude (no smaller than
    ``scale``), the largest absolute difference, and where."""

    out: Out
    scale: float
    elements: int = 0
    exact: int = 0
    worst_ulps: float = 0.0
    worst_abs: float = 0.0
    worst_at: int = 0
    mismatches: list[str] = field(default_factory=list)

    def add(self, k: int, a: float, b: float) -> None:
        self.elements += 1
        if not self.out.real:
            if a == b:
                self.exact += 1
            else:
                self.mismatches.append(f"[{k}] {a} != {b}")
            return
        if (math.isnan(a) and math.isnan(b)) or a == b:
            self.exact += 1
            return
        if not (math.isfinite(a) and math.isfinite(b)):
            self.mismatches.append(f"[{k}] {a!r} vs {b!r}")
            return
        ulp = f32_ulp if self.out.st_type == "REAL" else f64_ulp
        units = abs(a - b) / ulp(max(abs(a), abs(b), self.scale))
        if units > self.worst_ulps:
            self.worst_ulps, self.worst_at = units, k
        self.worst_abs = max(self.worst_abs, abs(a - b))

    def line(self) -> str:
        kind = "float32" if self.out.st_type == "REAL" else "float64"
        if not self.out.real:
            return (f"{self.out.name:14} {self.out.st_type:6} {self.exact}/{self.elements} "
                    "equal")
        return (f"{self.out.name:14} {self.out.st_type:6} {self.exact}/{self.elements} "
                f"bit-equal, worst {self.worst_ulps:.3g} {kind} ulp (|d| {self.worst_abs:.3g},"
                f" element {self.worst_at})")


def agreement(program: ValueProgram, a: Values, b: Values,
              scales: dict[str, float] | None = None) -> list[Agreement]:
    """Per output, how STruC++'s answers ``a`` and the bench's ``b`` differ; ``scales``
    names the magnitude below which a difference counts in the ulps of that magnitude (an
    output that passes through zero, e.g. a coordinate, is judged at its scale)."""
    scales = scales or {}
    out = []
    for o in program.outputs:
        agr = Agreement(o, scales.get(o.name, 0.0))
        for k, (x, y) in enumerate(zip(a[o.name.upper()], b[o.name.upper()], strict=True), 1):
            agr.add(k, x, y)
        out.append(agr)
    return out
