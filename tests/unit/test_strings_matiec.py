"""STRING functions on the real MatIEC + OpenPLC runtime and in the bench, value for value.

One PROGRAM computes, in its first scan, MatIEC's string functions over a grid of lengths and
positions (LEFT, RIGHT, MID, INSERT, DELETE, REPLACE, FIND, LEN, CONCAT, the comparisons) and
the STRING conversions of a spread of values; OpenPLC's own build (the scripts MATIEC_CHECK
and MATIEC_RUN name, see the README) and the bench must print the same bytes and numbers for
every variable. DELETE and REPLACE with P = 0 are left out: MatIEC's C copies a negative
byte count there and the PLC crashes (the bench faults: test_string_crash_is_a_fault).
Skips where the real toolchain is absent.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from matiec_run import SKIP_REASON, first_scan_both, run_tool

from armbench.compiler import compile_files
from armbench.faults import PlcFault

SOURCES = ["'Hello'", "''", "'abcabcab'", "'a$Nb$41c'"]
PATTERNS = ["'b'", "'ab'", "'ca'", "'x'", "''", "'cab'", "'abcabcab'"]
REALS = ["0.0", "1.0", "-1.5", "3.14159", "1.0E20", "-2.5E-7", "0.1", "100.0", "123456.7",
         "1.0E-30", "16777217.0"]
LREALS = ["0.1", "123456789.123456789", "-1.0E30", "2.0E-30", "1.0 / 3.0"]
INTS = ["0", "-1", "32767", "-32768", "12345"]
TIMES = ["T#0s", "T#1h2m3s", "T#1500ms", "T#2d", "T#59m", "T#1h1m1s", "T#2m0s", "T#10s5ms"]
PARSE = ["'1234'", "'-56'", "'16#7F'", "'16#ff'", "'2#1011'", "'8#17'", "'12ab3'", "'  77'",
         "'3.75'", "'-0.125'", "''", "'x'", "'1'", "'TRUE'", "'true'", "'yes'", "'1e3'",
         "'99999999999'"]


def _program() -> tuple[str, int]:
    decls: list[str] = []
    body: list[str] = []

    def var(name: str, typ: str, expr: str) -> None:
        decls.append(f"    {name} : {typ};")
        body.append(f"    {name} := {expr};")

    for s, src in enumerate(SOURCES):
        decls.append(f"    src{s} : STRING := {src};")
        for n in range(-1, 10):
            tag = f"m{-n}" if n < 0 else str(n)
            var(f"left_{s}_{tag}", "STRING", f"LEFT(src{s}, {n})")
            var(f"right_{s}_{tag}", "STRING", f"RIGHT(src{s}, {n})")
        for ln in range(0, 10):
            for p in range(0, 10):
                var(f"mid_{s}_{ln}_{p}", "STRING", f"MID(src{s}, {ln}, {p})")
                if p > 0:
                    var(f"del_{s}_{ln}_{p}", "STRING", f"DELETE(src{s}, {ln}, {p})")
                    var(f"rep_{s}_{ln}_{p}", "STRING", f"REPLACE(src{s}, 'XY', {ln}, {p})")
        for p in range(0, 10):
            var(f"ins_{s}_{p}", "STRING", f"INSERT(src{s}, 'XY', {p})")
        for k, pat in enumerate(PATTERNS):
            var(f"find_{s}_{k}", "INT", f"FIND(src{s}, {pat})")
            var(f"eq_{s}_{k}", "BOOL", f"src{s} = {pat}")
            var(f"lt_{s}_{k}", "BOOL", f"src{s} < {pat}")
            var(f"ge_{s}_{k}", "BOOL", f"src{s} >= {pat}")
            var(f"ne_{s}_{k}", "BOOL", f"src{s} <> {pat}")
        var(f"len_{s}", "DINT", f"LEN(src{s})")
        var(f"cat_{s}", "STRING", f"CONCAT(src{s}, '-', src{s}, src{s})")
    for k, r in enumerate(REALS):
        var(f"r2s_{k}", "STRING", f"REAL_TO_STRING({r})")
    for k, r in enumerate(LREALS):
        var(f"lr2s_{k}", "STRING", f"LREAL_TO_STRING({r})")
    for k, i in enumerate(INTS):
        var(f"i2s_{k}", "STRING", f"INT_TO_STRING({i})")
        var(f"w2s_{k}", "STRING", f"WORD_TO_STRING(INT_TO_WORD({i}))")
    for k, t in enumerate(TIMES):
        var(f"t2s_{k}", "STRING", f"TIME_TO_STRING({t})")
    for k, txt in enumerate(PARSE):
        var(f"s2i_{k}", "INT", f"STRING_TO_INT({txt})")
        var(f"s2l_{k}", "LINT", f"STRING_TO_LINT({txt})")
        var(f"s2r_{k}", "LREAL", f"STRING_TO_LREAL({txt})")
        var(f"s2b_{k}", "BOOL", f"STRING_TO_BOOL({txt})")
        # in seconds: run-st.sh's TIME(<s>s <ns>ns) has a space the value parser stops at
        var(f"s2t_{k}", "LINT", f"TIME_TO_LINT(STRING_TO_TIME({txt}))")
    text = ("PROGRAM StringGrid\n  VAR\n" + "\n".join(decls) + "\n  END_VAR\n" +
            "\n".join(body) + "\nEND_PROGRAM\n"
            "CONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            "    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);\n"
            "    PROGRAM instance0 WITH task0 : StringGrid;\n  END_RESOURCE\nEND_CONFIGURATION\n")
    return text, len(body)


def _as_printed(value: object) -> str:
    """A bench value as run-st.sh prints MatIEC's (STRING as an IEC literal, BOOL 0/1,
    LREAL %.17g)."""
    if isinstance(value, str):
        out = "'"
        for b in value.encode("latin-1"):
            c = chr(b)
            out += f"${c}" if c in "'$" else f"${b:02X}" if b <= 32 or b >= 127 else c
        return out + "'"
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return f"{value:.17g}"
    assert isinstance(value, int)
    return str(value)


@pytest.mark.skipif(run_tool() is None, reason=SKIP_REASON)
def test_string_functions_match_openplc(tmp_path: Path) -> None:
    text, count = _program()
    real, prog = first_scan_both(tmp_path, "string_grid.st", [], text)
    assert len(real) >= count, f"run-st.sh printed {len(real)} of {count} variables"
    diffs = []
    compared = 0
    for name, printed in real.items():
        if name.startswith("SRC"):
            continue
        ours_text = _as_printed(prog.get(name))
        compared += 1
        if ours_text != printed:
            diffs.append(f"{name}: OpenPLC {printed}, bench {ours_text}")
    assert compared == count
    assert not diffs, f"{len(diffs)} of {compared} values differ:\n" + "\n".join(diffs[:40])


def test_string_crash_is_a_fault(tmp_path: Path) -> None:
    """DELETE(s, L, 0): MatIEC's C copies (size_t)-1 bytes and the PLC dies; the bench stops
    the scan with a fault that names the call, instead of computing something."""
    path = tmp_path / "crash.st"
    path.write_text("PROGRAM Main\n  VAR\n    s : STRING := 'Hello';\n  END_VAR\n"
                    "    s := DELETE(s, 2, 0);\nEND_PROGRAM\n"
                    "CONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
                    "    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);\n"
                    "    PROGRAM instance0 WITH task0 : Main;\n  END_RESOURCE\n"
                    "END_CONFIGURATION\n", encoding="utf-8")
    mod = compile_files([path])
    mod.config_init()
    with pytest.raises(PlcFault, match="STRING function argument out of range"):
        mod.run_task_index(0, 0)
