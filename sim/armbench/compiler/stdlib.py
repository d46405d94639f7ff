"""The IEC standard functions and function blocks the bench provides, as MatIEC spells them."""

from __future__ import annotations

from dataclasses import dataclass

from .types import ELEMENTARY, ElemType


@dataclass(frozen=True)
class StdFunc:
    name: str
    kind: str  # see resolve.Checker.std_call for the typing rule of each kind
    params: tuple[str, ...]  # names for named calls; "*" = variadic IN1..INn


STD_FUNCS: dict[str, StdFunc] = {}
for _n in ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"):
    STD_FUNCS[_n] = StdFunc(_n, "real1", ("IN",))
STD_FUNCS["ABS"] = StdFunc("ABS", "num1", ("IN",))
STD_FUNCS["EXPT"] = StdFunc("EXPT", "expt", ("IN1", "IN2"))
STD_FUNCS["MIN"] = StdFunc("MIN", "same_n", ("*",))
STD_FUNCS["MAX"] = StdFunc("MAX", "same_n", ("*",))
STD_FUNCS["LIMIT"] = StdFunc("LIMIT", "limit", ("MN", "IN", "MX"))
STD_FUNCS["SEL"] = StdFunc("SEL", "sel", ("G", "IN0", "IN1"))
STD_FUNCS["MUX"] = StdFunc("MUX", "mux", ("K", "*"))
STD_FUNCS["MOD"] = StdFunc("MOD", "int2", ("IN1", "IN2"))
for _n in ("SHL", "SHR", "ROL", "ROR"):
    STD_FUNCS[_n] = StdFunc(_n, "shift", ("IN", "N"))
for _n in ("AND", "OR", "XOR"):
    STD_FUNCS[_n] = StdFunc(_n, "bits_n", ("*",))
STD_FUNCS["NOT"] = StdFunc("NOT", "bits1", ("IN",))
STD_FUNCS["TRUNC"] = StdFunc("TRUNC", "trunc", ("IN",))
STD_FUNCS["MOVE"] = StdFunc("MOVE", "move", ("IN",))

# MatIEC's character string functions (its iec_std_functions.h, OpenPLC v3): the kind names
# the typing rule in resolve_std.py, the C lives in runtime/iec_runtime.h (plc__str_*).
STD_FUNCS["LEN"] = StdFunc("LEN", "str_len", ("IN",))
STD_FUNCS["LEFT"] = StdFunc("LEFT", "str_cut", ("IN", "L"))
STD_FUNCS["RIGHT"] = StdFunc("RIGHT", "str_cut", ("IN", "L"))
STD_FUNCS["MID"] = StdFunc("MID", "str_cut", ("IN", "L", "P"))
STD_FUNCS["CONCAT"] = StdFunc("CONCAT", "str_concat", ("*",))
STD_FUNCS["INSERT"] = StdFunc("INSERT", "str_edit", ("IN1", "IN2", "P"))
STD_FUNCS["DELETE"] = StdFunc("DELETE", "str_cut", ("IN", "L", "P"))
STD_FUNCS["REPLACE"] = StdFunc("REPLACE", "str_edit", ("IN1", "IN2", "L", "P"))
STD_FUNCS["FIND"] = StdFunc("FIND", "str_find", ("IN1", "IN2"))

# The operators' standard functions in call form, as the OpenPLC editor writes LD/FBD into ST
# (ADD(IN1 := a, IN2 := b), GT(a, b, c)): name -> (operator, least and most arguments; 0 = any)
CALL_FORM_OPERATORS: dict[str, tuple[str, int, int]] = {
    "ADD": ("+", 2, 0), "MUL": ("*", 2, 0), "SUB": ("-", 2, 2), "DIV": ("/", 2, 2),
    "GT": (">", 2, 0), "GE": (">=", 2, 0), "EQ": ("=", 2, 0), "LE": ("<=", 2, 0),
    "LT": ("<", 2, 0), "NE": ("<>", 2, 2),
    "ADD_TIME": ("+", 2, 2), "SUB_TIME": ("-", 2, 2), "MULTIME": ("*", 2, 2),
    "DIVTIME": ("/", 2, 2),
}

# Conversions X_TO_Y between elementary types; STRING converts to and from each of the others
CONVERSIONS: dict[str, tuple[ElemType, ElemType]] = {}
for _a in ELEMENTARY.values():
    for _b in ELEMENTARY.values():
        if _a is not _b:
            CONVERSIONS[f"{_a.name}_TO_{_b.name}"] = (_a, _b)


@dataclass(frozen=True)
class StdFbVar:
    name: str
    type: str
    kind: str  # VAR_INPUT | VAR_OUTPUT | VAR


# Standard FBs: their C implementations live in runtime/iec_runtime.h with these fields.
STD_FBS: dict[str, tuple[StdFbVar, ...]] = {
    "TON": (StdFbVar("IN", "BOOL", "VAR_INPUT"), StdFbVar("PT", "TIME", "VAR_INPUT"),
            StdFbVar("Q", "BOOL", "VAR_OUTPUT"), StdFbVar("ET", "TIME", "VAR_OUTPUT"),
            StdFbVar("START", "TIME", "VAR"), StdFbVar("PREV_IN", "BOOL", "VAR"),
            StdFbVar("RUNNING", "BOOL", "VAR")),
    "TOF": (StdFbVar("IN", "BOOL", "VAR_INPUT"), StdFbVar("PT", "TIME", "VAR_INPUT"),
            StdFbVar("Q", "BOOL", "VAR_OUTPUT"), StdFbVar("ET", "TIME", "VAR_OUTPUT"),
            StdFbVar("START", "TIME", "VAR"), StdFbVar("PREV_IN", "BOOL", "VAR"),
            StdFbVar("RUNNING", "BOOL", "VAR")),
    "TP": (StdFbVar("IN", "BOOL", "VAR_INPUT"), StdFbVar("PT", "TIME", "VAR_INPUT"),
           StdFbVar("Q", "BOOL", "VAR_OUTPUT"), StdFbVar("ET", "TIME", "VAR_OUTPUT"),
           StdFbVar("START", "TIME", "VAR"), StdFbVar("PREV_IN", "BOOL", "VAR"),
            StdFbVar("RUNNING", "BOOL", "VAR")),
    "R_TRIG": (StdFbVar("CLK", "BOOL", "VAR_INPUT"), StdFbVar("Q", "BOOL", "VAR_OUTPUT"),
               StdFbVar("M", "BOOL", "VAR")),
    "F_TRIG": (StdFbVar("CLK", "BOOL", "VAR_INPUT"), StdFbVar("Q", "BOOL", "VAR_OUTPUT"),
               StdFbVar("M", "BOOL", "VAR")),
    "CTU": (StdFbVar("CU", "BOOL", "VAR_INPUT"), StdFbVar("R", "BOOL", "VAR_INPUT"),
            StdFbVar("PV", "INT", "VAR_INPUT"), StdFbVar("Q", "BOOL", "VAR_OUTPUT"),
            StdFbVar("CV", "INT", "VAR_OUTPUT"), StdFbVar("PREV_CU", "BOOL", "VAR")),
    "CTD": (StdFbVar("CD", "BOOL", "VAR_INPUT"), StdFbVar("LD", "BOOL", "VAR_INPUT"),
            StdFbVar("PV", "INT", "VAR_INPUT"), StdFbVar("Q", "BOOL", "VAR_OUTPUT"),
            StdFbVar("CV", "INT", "VAR_OUTPUT"), StdFbVar("PREV_CD", "BOOL", "VAR")),
    "SR": (StdFbVar("S1", "BOOL", "VAR_INPUT"), StdFbVar("R", "BOOL", "VAR_INPUT"),
           StdFbVar("Q1", "BOOL", "VAR_OUTPUT")),
    "RS": (StdFbVar("S", "BOOL", "VAR_INPUT"), StdFbVar("R1", "BOOL", "VAR_INPUT"),
           StdFbVar("Q1", "BOOL", "VAR_OUTPUT")),
}

# C bodies of the standard FBs (IEC 61131-3 semantics); `s` is the instance, plc__now_ns the
# scan time. Kept beside the field table above so the two cannot drift apart.
STD_FB_BODIES: dict[str, str] = {
    "TON": """
    if (s->IN) {
        if (!s->PREV_IN) { s->START = plc__now_ns; s->RUNNING = 1; }
        int64_t et = plc__now_ns - s->START;
        s->ET = et < s->PT ? et : s->PT;
        s->Q = s->ET >= s->PT;
    } else { s->Q = 0; s->ET = 0; s->RUNNING = 0; }
    s->PREV_IN = s->IN;""",
    "TOF": """
    if (s->IN) { s->Q = 1; s->ET = 0; s->RUNNING = 0; }
    else {
        if (s->PREV_IN) { s->START = plc__now_ns; s->RUNNING = 1; }
        if (s->RUNNING) {
            int64_t et = plc__now_ns - s->START;
            s->ET = et < s->PT ? et : s->PT;
            if (s->ET >= s->PT) { s->Q = 0; s->RUNNING = 0; }
        }
    }
    s->PREV_IN = s->IN;""",
    "TP": """
    if (!s->RUNNING && s->IN && !s->PREV_IN && !s->Q) {
        s->START = plc__now_ns; s->RUNNING = 1; s->Q = 1;
    }
    if (s->RUNNING) {
        int64_t et = plc__now_ns - s->START;
        s->ET = et < s->PT ? et : s->PT;
        if (s->ET >= s->PT) { s->Q = 0; s->RUNNING = 0; }
    } else if (!s->IN) { s->ET = 0; }
    s->PREV_IN = s->IN;""",
    "R_TRIG": """
    s->Q = s->CLK && !s->M; s->M = s->CLK;""",
    "F_TRIG": """
    s->Q = !s->CLK && !s->M; s->M = !s->CLK;""",
    "CTU": """
    if (s->R) s->CV = 0;
    else if (s->CU && !s->PREV_CU && s->CV < 32767) s->CV = (int16_t)(s->CV + 1);
    s->Q = s->CV >= s->PV; s->PREV_CU = s->CU;""",
    "CTD": """
    if (s->LD) s->CV = s->PV;
    else if (s->CD && !s->PREV_CD && s->CV > -32768) s->CV = (int16_t)(s->CV - 1);
    s->Q = s->CV <= 0; s->PREV_CD = s->CD;""",
    "SR": """
    s->Q1 = s->S1 || (!s->R && s->Q1);""",
    "RS": """
    s->Q1 = !s->R1 && (s->S || s->Q1);""",
}
