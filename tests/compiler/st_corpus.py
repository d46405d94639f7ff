"""Shared helpers of the compiler tests: the semantics corpus's CHECK comments and MatIEC access.

CHECK syntax (inside a `(* ... *)` comment anywhere in a tests/corpus/semantics/*.st file):

    (* SCANS: N *)                  run the configured task N times (default 1); scan k (0-based)
                                    runs at time k * INTERVAL of the first TASK
    (* CHECK: path = value *)       exact comparison, after the last scan
    (* CHECK: path ≈ value *)       approximate: |actual - value| <= 1e-5 * max(1, |value|)
    (* CHECK: path ≈ value ± tol *) approximate with an explicit absolute tolerance

`path` names a variable of the program instance `instance0` (case-insensitive), with `.field`
for STRUCT fields and FB instance members and `[i]` / `[i, j]` for array elements (ST indices,
literal integers or a name of another integer variable of the instance).

`value` is one of
    TRUE / FALSE
    an integer: 42, -7, 16#FF, 2#1010, 8#17 (underscores allowed)
    a real literal: 1.5, -2.5E-3 -- compared exactly with `=`, as a double
    REAL#x: x rounded to float32, compared exactly (bit equality for REAL results)
    INF, -INF, NAN
    a duration: T#20ms, T#1s500ms, T#-500ms -- compared in nanoseconds
    a STRING as run-st.sh prints it: 'text' with $$, $' and $hh (hex) escapes -- compared
    byte for byte (as latin-1 characters)

Every CHECK is a statement about the values after the last scan, wherever it sits in the file.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

CORPUS = Path(__file__).resolve().parents[1] / "corpus"
SEMANTICS = CORPUS / "semantics"
DIAGNOSTICS = CORPUS / "diagnostics"
INSTANCE = "instance0"

_CHECK_RE = re.compile(r"\(\*\s*CHECK:\s*(?P<path>[^=≈*]+?)\s*(?P<op>=|≈)\s*(?P<value>.+?)"
                       r"(?:\s*±\s*(?P<tol>\S+))?\s*\*\)")
_SCANS_RE = re.compile(r"\(\*\s*SCANS:\s*(\d+)\s*\*\)")
_TIME_RE = re.compile(r"(?i)^(?:T|TIME)#(-)?((?:\d+(?:\.\d+)?(?:d|h|ms|m|s|us|ns)_?)+)$")
_UNIT_NS = {"d": 86400 * 10**9, "h": 3600 * 10**9, "m": 60 * 10**9, "s": 10**9,
            "ms": 10**6, "us": 10**3, "ns": 1}


@dataclass(frozen=True)
class Check:
    path: str
    op: str  # "=" or "≈"
    text: str  # the value as written
    value: Any
    tol: float | None
    line: int

    def __str__(self) -> str:
        tol = f" ± {self.tol}" if self.tol is not None else ""
        return f"line {self.line}: {self.path} {self.op} {self.text}{tol}"


def f32(x: float) -> float:
    return float(struct.unpack("f", struct.pack("f", x))[0])


_STR_ESC = re.compile(r"\$([0-9A-Fa-f]{2}|[$'NnTtRrPp])")
_STR_NAMED = {"N": "\n", "T": "\t", "R": "\r", "P": "\f"}


def parse_string(text: str) -> str:
    """'a$27b$0A' -> the characters (bytes as latin-1) it stands for."""
    body = text.strip()[1:-1]
    return _STR_ESC.sub(lambda m: _STR_NAMED.get(m.group(1).upper(), m.group(1))
                        if len(m.group(1)) == 1 else chr(int(m.group(1), 16)), body)


def parse_value(text: str) -> Any:
    t = text.strip()
    if len(t) >= 2 and t[0] == t[-1] == "'":
        return parse_string(t)
    u = t.upper()
    if u in ("TRUE", "FALSE"):
        return u == "TRUE"
    if u in ("INF", "+INF"):
        return math.inf
    if u == "-INF":
        return -math.inf
    if u == "NAN":
        return math.nan
    m = _TIME_RE.match(t)
    if m:
        total = 0.0
        for num, unit in re.findall(r"(\d+(?:\.\d+)?)(ms|us|ns|d|h|m|s)", m.group(2).lower()):
            total += float(num) * _UNIT_NS[unit]
        ns = round(total)
        return _Dur(-ns if m.group(1) else ns)
    if u.startswith("REAL#"):
        return f32(float(t[5:]))
    m = re.fullmatch(r"([+-]?)(2|8|16)#([0-9A-Fa-f_]+)", t)
    if m:
        v = int(m.group(3).replace("_", ""), int(m.group(2)))
        return -v if m.group(1) == "-" else v
    if re.fullmatch(r"[+-]?[\d_]+", t):
        return int(t.replace("_", ""))
    try:
        return float(t)
    except ValueError:
        raise ValueError(f"cannot parse CHECK value {text!r}") from None


class _Dur(int):
    """A TIME value in nanoseconds (an int that remembers it was written as a duration)."""


def parse_checks(path: Path) -> tuple[int, list[Check]]:
    text = path.read_text(encoding="utf-8")
    m = _SCANS_RE.search(text)
    scans = int(m.group(1)) if m else 1
    checks = []
    for cm in _CHECK_RE.finditer(text):
        line = text.count("\n", 0, cm.start()) + 1
        tol = float(cm.group("tol")) if cm.group("tol") else None
        checks.append(Check(cm.group("path").strip(), cm.group("op"), cm.group("value").strip(),
                            parse_value(cm.group("value")), tol, line))
    return scans, checks


def compare(check: Check, actual: Any) -> str | None:
    """None when `actual` satisfies the check, else a message."""
    exp = check.value
    bad = f"{check}: got {actual!r}"
    if isinstance(exp, str):
        return None if actual == exp else bad
    if isinstance(exp, bool):
        return None if isinstance(actual, bool | int) and bool(actual) == exp and \
            int(actual) in (0, 1) else bad
    if isinstance(actual, bool):
        return bad
    if isinstance(exp, int):
        return None if isinstance(actual, int) and actual == exp else bad
    if not isinstance(actual, int | float):
        return bad
    actual = float(actual)
    if math.isnan(exp):
        return None if math.isnan(actual) else bad
    if check.op == "≈":
        tol = check.tol if check.tol is not None else 1e-5 * max(1.0, abs(exp))
        return None if abs(actual - exp) <= tol else bad
    return None if actual == exp else bad


# ------------------------------------------------------------------ paths into instance values
_SEG_RE = re.compile(r"\s*(?:\.?\s*([A-Za-z_]\w*)|\[([^\]]*)\])")


def split_path(path: str) -> list[str | tuple[str, ...]]:
    """'a.b[1, k].c' -> ['a', 'b', ('1', 'k'), 'c']"""
    out: list[str | tuple[str, ...]] = []
    pos = 0
    while pos < len(path):
        m = _SEG_RE.match(path, pos)
        if not m or m.end() == pos:
            raise ValueError(f"bad CHECK path {path!r}")
        if m.group(1):
            out.append(m.group(1))
        else:
            out.append(tuple(x.strip() for x in m.group(2).split(",")))
        pos = m.end()
    return out


def _ci(d: dict[str, Any], name: str) -> Any:
    for k, v in d.items():
        if k.upper() == name.upper():
            return v
    raise KeyError(f"no {name!r} (have {', '.join(d)})")


def _index(idx: str, top: dict[str, Any]) -> int:
    if re.fullmatch(r"-?\d+", idx):
        return int(idx)
    v = _ci(top, idx)
    if not isinstance(v, int) or isinstance(v, bool):
        raise ValueError(f"index {idx!r} is not an integer variable")
    return v


def walk(top_vars: dict[str, Any], top_types: dict[str, Any], path: str) -> tuple[Any, Any]:
    """(value, type) of `path` in an instance's vars() dict, guided by the compiler's types."""
    from armbench.compiler.types import ArrayType, PouType, StructType

    segs = split_path(path)
    first = segs[0]
    assert isinstance(first, str)
    value = _ci(top_vars, first)
    typ = _ci(top_types, first)
    for seg in segs[1:]:
        if isinstance(seg, tuple):
            assert isinstance(typ, ArrayType), f"{path}: not an array"
            if len(seg) != len(typ.dims):
                raise ValueError(f"{path}: {len(typ.dims)} indices needed")
            for idx, (lo, hi) in zip(seg, typ.dims, strict=True):
                i = _index(idx, top_vars)
                if not lo <= i <= hi:
                    raise IndexError(f"{path}: index {i} outside {lo}..{hi}")
                value = value[i - lo]
            typ = typ.element
        elif isinstance(typ, StructType):
            value = _ci(value, seg)
            typ = typ.fields[seg.upper()][1]
        elif isinstance(typ, PouType):
            value = _ci(value, seg)
            typ = typ.symbol.vars[seg.upper()].type  # type: ignore[attr-defined]
        else:
            raise ValueError(f"{path}: {typ} has no member {seg!r}")
    return value, typ


def instance_types(mod_or_prog: Any, instance: str = INSTANCE) -> dict[str, Any]:
    prog = getattr(mod_or_prog, "program", mod_or_prog)
    for inst in prog.config.instances:
        if inst.name.upper() == instance.upper():
            return {v.name: v.type for v in inst.pou.vars.values()}
    raise KeyError(f"no program instance {instance!r}")


# ------------------------------------------------------------------ the real MatIEC
MATIEC_HELP = ("no real iec2c (none on PATH): set IEC2C=/path/to/iec2c or "
               "MATIEC_CHECK=/path/to/check-st.sh (e.g. /opt/realplc/check-st.sh) to "
               "cross-check")


@dataclass(frozen=True)
class Matiec:
    """How to reach a real MatIEC: a check-st.sh (+ its sibling run-st.sh), or a bare iec2c."""

    check_script: Path | None
    run_script: Path | None
    iec2c: Path | None
    libdir: Path | None

    def verdict(self, st: Path) -> tuple[bool, bool, str]:
        """(accepted, c_stage_checked, output). c_stage_checked is False for a bare iec2c."""
        if self.check_script is not None:
            p = subprocess.run([str(self.check_script), str(st)], capture_output=True,
                               text=True, timeout=300)
            return p.returncode == 0, True, p.stdout + p.stderr
        assert self.iec2c is not None
        import tempfile
        with tempfile.TemporaryDirectory(prefix="iec2c-") as tmp:
            shutil.copy(st, Path(tmp) / st.name)
            if self.libdir is not None:
                os.symlink(self.libdir, Path(tmp) / "lib")
            p = subprocess.run([str(self.iec2c), "-f", "-l", "-p", "-r", "-R", "-a", st.name],
                               cwd=tmp, capture_output=True, text=True, timeout=300)
        return p.returncode == 0, False, p.stdout + p.stderr

    def run(self, st: Path, scans: int, exprs: list[str]) -> tuple[int, str]:
        assert self.run_script is not None
        cmd = [str(self.run_script), "-n", str(scans)]
        for e in exprs:
            cmd += ["-e", e]
        p = subprocess.run(cmd + [str(st)], capture_output=True, text=True, timeout=300)
        return p.returncode, p.stdout + p.stderr


def find_matiec() -> Matiec | None:
    """MATIEC_CHECK (a check-st.sh; run-st.sh next to it also runs programs), IEC2C, or an
    iec2c on PATH.

    IEC2C=/path/to/iec2c only checks iec2c's verdict; its standard library is taken from
    IEC2C_LIB, else a `lib` dir beside or above the binary (MatIEC looks for ./lib)."""
    check = os.environ.get("MATIEC_CHECK")
    if check:
        cp = Path(check)
        if not cp.is_file():
            return None
        run = Path(os.environ.get("MATIEC_RUN", cp.with_name("run-st.sh")))
        return Matiec(cp, run if run.is_file() else None, None, None)
    iec2c = os.environ.get("IEC2C") or shutil.which("iec2c")
    if iec2c and Path(iec2c).is_file():
        ip = Path(iec2c).resolve()
        lib = os.environ.get("IEC2C_LIB")
        libdir = Path(lib) if lib else next(
            (d for d in (ip.parent / "lib", ip.parent.parent / "lib") if d.is_dir()), None)
        return Matiec(None, None, ip, libdir)
    return None


def c_expr(top_types: dict[str, Any], path: str, instance: str = INSTANCE,
           resource: str = "RES0") -> tuple[str, str]:
    """(IEC type name for run-st.sh's printer, C expression) of a CHECK path in MatIEC's C."""
    from armbench.compiler.types import ArrayType, ElemType, EnumType, PouType, StructType

    segs = split_path(path)
    first = segs[0]
    assert isinstance(first, str)
    typ = _ci(top_types, first)
    expr = f"{resource}__{instance.upper()}.{first.upper()}"
    if not isinstance(typ, PouType):
        expr += ".value"
    for seg in segs[1:]:
        if isinstance(seg, tuple):
            assert isinstance(typ, ArrayType)
            expr += ".table"  # MatIEC: nested C arrays, .table[i - lo][j - lo]
            for idx, (lo, _hi) in zip(seg, typ.dims, strict=True):
                if re.fullmatch(r"-?\d+", idx):
                    expr += f"[{int(idx) - lo}]"
                else:
                    expr += f"[({resource}__{instance.upper()}.{idx.upper()}.value) - ({lo})]"
            typ = typ.element
        elif isinstance(typ, StructType):
            expr += f".{seg.upper()}"
            typ = typ.fields[seg.upper()][1]
        else:
            assert isinstance(typ, PouType)
            mt = typ.symbol.vars[seg.upper()].type  # type: ignore[attr-defined]
            expr += f".{seg.upper()}" + ("" if isinstance(mt, PouType) else ".value")
            typ = mt
    if isinstance(typ, EnumType):
        return "DINT", expr
    assert isinstance(typ, ElemType), f"{path}: cannot print {typ}"
    return typ.name, expr


def parse_matiec_value(text: str) -> Any:
    t = text.strip()
    if len(t) >= 2 and t[0] == t[-1] == "'":
        return parse_string(t)
    m = re.fullmatch(r"TIME\((-?\d+)s (-?\d+)ns\)", t)
    if m:
        return int(m.group(1)) * 10**9 + int(m.group(2))
    if t.startswith("16#"):
        return int(t[3:], 16)
    if re.fullmatch(r"-?\d+", t):
        return int(t)
    low = t.lower()
    if low in ("nan", "-nan"):
        return math.nan
    return float(low)
