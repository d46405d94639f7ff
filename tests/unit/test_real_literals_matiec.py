"""REAL arithmetic with literals on the real MatIEC + OpenPLC runtime and in the bench, bit for bit.

MatIEC writes an untyped REAL literal into its C as the decimal text, a C double, so
`360.5 + x * 44.99` with x a REAL is computed in double and rounded to float once, where it
lands in a REAL; `x > 0.1` compares in double; a function's or conversion's input is cast to
REAL first; REAL#1.5 is (REAL)1.5, a float. The programs below (written for this test, with
the kinds of expressions OSCAT BASIC's GAMMA, LANGEVIN and HEAT_INDEX have: Stirling's
formula, a hyperbolic cotangent, the Rothfusz polynomial) run one scan in OpenPLC v3's own
build (the scripts MATIEC_CHECK / MATIEC_RUN name) and in the bench; every REAL, LREAL, DINT
and BOOL the PROGRAM holds must be equal bit for bit. Skips where the real toolchain is absent.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from matiec_run import SKIP_REASON, first_scan_both, run_tool

# inputs with no short binary form, a few large (where one float rounding step is big), one
# that is exactly REAL 0.1 (above the double 0.1: `x > 0.1` is TRUE only in double),
# 3.33333325 (times 0.3: 0.99999998 in double, 1.0 once rounded to REAL, so TRUNC gives 1)
# and 1.00067592, whose cube powf rounds otherwise than the double pow
INPUTS = ["0.1", "1.7", "3.3", "12.345", "40000.0", "0.007", "123.456", "7.77", "-2.5",
          "3.33333325", "1.00067592"]

FUNCTIONS = """
FUNCTION StirlingGamma : REAL
(* Stirling's approximation of the gamma function, as OSCAT's GAMMA writes it *)
VAR_INPUT X : REAL; END_VAR
IF X > 0.0 THEN
  StirlingGamma := SQRT(6.2831853 / X)
                   * EXPT(0.36787944 * (X + 1.0 / (12.0 * X - 0.1 / X)), X);
END_IF;
END_FUNCTION

FUNCTION Langevin : REAL
(* L(x) = coth(x) - 1/x, coth from EXP *)
VAR_INPUT X : REAL; END_VAR
VAR E2 : REAL; END_VAR
IF X = 0.0 THEN
  Langevin := 0.0;
ELSE
  E2 := EXP(2.0 * X);
  Langevin := (E2 + 1.0) / (E2 - 1.0) - 1.0 / X;
END_IF;
END_FUNCTION

FUNCTION HeatIndex : REAL
(* Rothfusz regression: temperature in degrees C, relative humidity in %, result in C *)
VAR_INPUT TC : REAL; RH : REAL; END_VAR
VAR T : REAL; END_VAR
T := TC * 1.8 + 32.0;
HeatIndex := (-42.379 + 2.04901523 * T + 10.14333127 * RH - 0.22475541 * T * RH
              - 0.00683783 * T * T - 0.05481717 * RH * RH + 0.00122874 * T * T * RH
              + 0.00085282 * T * RH * RH - 1.99E-6 * T * T * RH * RH - 32.0) / 1.8;
END_FUNCTION

FUNCTION Scale : REAL
(* a user FUNCTION: its input and result are REALs *)
VAR_INPUT A : REAL; END_VAR
Scale := A * 1.5 + 0.1;
END_FUNCTION

FUNCTION_BLOCK Hold
(* an FB input written from an expression with literals *)
VAR_INPUT A : REAL; END_VAR
VAR_OUTPUT Q : REAL; END_VAR
Q := A * 0.7;
END_FUNCTION_BLOCK
"""


def _chain(x: str, terms: int) -> str:
    """A sum longer than the emitter's spill interval (a temporary every 100 operators)."""
    return " + ".join(f"{x} * 0.{k % 9 + 1}" for k in range(terms))


def _program() -> tuple[str, dict[str, str]]:
    """The PROGRAM and the IEC type of each of its variables the test compares."""
    decls: list[str] = []
    body: list[str] = []
    types: dict[str, str] = {}

    def out(name: str, typ: str, expr: str) -> None:
        decls.append(f"    {name} : {typ};")
        types[name.upper()] = typ
        body.append(f"  {name} := {expr};")

    for i, v in enumerate(INPUTS):
        x = f"X{i}"
        decls.append(f"    {x} : REAL := {v};")
        types[x.upper()] = "REAL"
        out(f"Gam{i}", "REAL", f"StirlingGamma(ABS({x}) + 0.5)")
        out(f"Lan{i}", "REAL", f"Langevin(LIMIT(-30.0, {x} * 0.25, 30.0))")
        out(f"Hea{i}", "REAL", f"HeatIndex({x} * 0.1 + 27.0, 40.0 + {x} * 0.3)")
        out(f"Lin{i}", "REAL", f"360.5 + {x} * 44.99")
        out(f"Neg{i}", "REAL", f"-0.1 * {x} - 1.3")
        out(f"Typ{i}", "REAL", f"REAL#0.1 * {x} + REAL#1.3")
        out(f"Div{i}", "REAL", f"{x} / 3.0 * 3.0")
        out(f"Mix{i}", "REAL", f"({x} + 0.1) * ({x} - 0.1) / ({x} * 0.5 + 7.0)")
        out(f"Sin{i}", "REAL", f"SIN({x} * 0.5) * 0.3")
        out(f"Sqr{i}", "REAL", f"SQRT(ABS({x}) + 0.1)")
        out(f"Lim{i}", "REAL", f"LIMIT(0.1, {x} * 0.01, 0.9) * 3.3")
        out(f"Max{i}", "REAL", f"MAX({x} * 0.1, 0.2) * 1.1")
        out(f"Sel{i}", "REAL", f"SEL({x} > 5.0, {x} * 0.1, {x} * 0.2) * 0.3")
        out(f"Mov{i}", "REAL", f"MOVE({x} * 0.1) * 0.3")
        out(f"Ex3{i}", "REAL", f"EXPT({x} * 0.7, 3) + 0.1")
        out(f"Exd{i}", "REAL", f"EXPT({x}, 3)")
        out(f"Exf{i}", "REAL", f"EXPT({x}, 3.0)")
        out(f"Exh{i}", "REAL", f"EXPT(ABS({x}) * 0.7, 0.5) + 0.1")
        out(f"Usr{i}", "REAL", f"Scale({x} * 0.3) * 0.9")
        out(f"Cst{i}", "REAL", f"K * {x} + Z")
        out(f"Lon{i}", "REAL", _chain(x, 120))
        out(f"Gt{i}", "BOOL", f"{x} > 0.1")
        out(f"Eq{i}", "BOOL", f"{x} * 0.1 = {x} / 10.0")
        out(f"Di{i}", "DINT", f"REAL_TO_DINT({x} * 1.1 + 0.5)")
        out(f"Tr{i}", "DINT", f"TRUNC({x} * 0.3)")
        out(f"Lr{i}", "LREAL", f"REAL_TO_LREAL({x} * 0.1) * 0.1")
        out(f"Ll{i}", "LREAL", f"REAL_TO_LREAL({x}) * LREAL#0.1 + 0.2")
        decls.append(f"    Fb{i} : Hold;")
        body.append(f"  Fb{i}(A := {x} * 0.1);")
        out(f"Fbq{i}", "REAL", f"Fb{i}.Q")
    program = (FUNCTIONS + "\nPROGRAM RealLiterals\n  VAR\n" + "\n".join(decls)
               + "\n    Z : REAL := 0.1;\n  END_VAR\n  VAR CONSTANT\n    K : REAL := 0.3;\n"
               + "  END_VAR\n" + "\n".join(body) + "\nEND_PROGRAM\n"
               + "\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
               + "    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);\n"
               + "    PROGRAM instance0 WITH task0 : RealLiterals;\n"
               + "  END_RESOURCE\nEND_CONFIGURATION\n")
    return program, types


def _bits(typ: str, value: float) -> str:
    if typ == "REAL":
        return struct.pack("<f", value).hex()
    return struct.pack("<d", value).hex()


def _ulps(a: float, b: float) -> int:
    ia = struct.unpack("<i", struct.pack("<f", a))[0]
    ib = struct.unpack("<i", struct.pack("<f", b))[0]
    return abs(ia - ib)


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_real_literal_arithmetic_is_bit_identical_with_matiec(tmp_path: Path) -> None:
    program, types = _program()
    real, prog = first_scan_both(tmp_path, "real_literals.st", [], program)
    assert set(types) <= set(real), sorted(set(types) - set(real))
    differ: list[str] = []
    for name, typ in types.items():
        ours = prog.get(name)
        theirs = real[name]
        if typ in ("REAL", "LREAL"):
            t = float(theirs)
            assert not math.isnan(t), name
            if _bits(typ, float(ours)) != _bits(typ, t):
                extra = f" ({_ulps(float(ours), t)} ulp)" if typ == "REAL" else ""
                differ.append(f"{name}: bench {float(ours)!r}, MatIEC {t!r}{extra}")
        elif typ == "BOOL":
            if bool(ours) != (theirs == "1"):
                differ.append(f"{name}: bench {bool(ours)}, MatIEC {theirs}")
        elif int(ours) != int(theirs):
            differ.append(f"{name}: bench {int(ours)}, MatIEC {theirs}")
    assert not differ, f"{len(differ)} of {len(types)} values differ:\n" + "\n".join(differ)
