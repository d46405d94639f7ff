"""Runtime semantics of the ST compiler against tests/corpus/semantics/*.st.

Each corpus file is a PROGRAM run by `CONFIGURATION Config0 / RESOURCE Res0 / TASK` as instance
`instance0`; its expected values are `(* CHECK: ... *)` comments and `(* SCANS: N *)` (see
st_corpus.py for the syntax). The expected values are what the real MatIEC of OpenPLC v3
computes (derived with /opt/realplc/run-st.sh), never what our compiler printed.

test_semantics       compiles with armbench's compiler, runs the first task N times at times
                     k * INTERVAL (k = 0..N-1) and compares every CHECK with the instance's vars.
test_matiec_accepts  the same corpus through the real MatIEC: iec2c (and OpenPLC's C build)
test_matiec_values   must accept every file, and the program run the OpenPLC way must satisfy
                     every CHECK too, so the corpus stays honest.

Environment for the MatIEC cross-check (skipped when neither is set):
  MATIEC_CHECK=/opt/realplc/check-st.sh   a check script (verdict by exit status 0); a
                                                run-st.sh beside it (or MATIEC_RUN=...) runs
                                                programs and prints variables for the values test
  IEC2C=/path/to/iec2c                          bare iec2c (verdict of iec2c alone, no values);
                                                its ST standard library from IEC2C_LIB or a
                                                `lib` dir beside/above the binary
"""

from __future__ import annotations

from pathlib import Path

import pytest
from st_corpus import (
    INSTANCE,
    SEMANTICS,
    c_expr,
    compare,
    f32,
    instance_types,
    parse_checks,
    parse_matiec_value,
    walk,
)

from armbench.compiler import compile_files

FILES = sorted(SEMANTICS.glob("*.st"))


def _params() -> list[object]:
    return [pytest.param(f, id=f.stem) for f in FILES]


def test_corpus_is_there() -> None:
    assert len(FILES) >= 20
    for f in FILES:
        scans, checks = parse_checks(f)
        assert checks, f"{f.name} has no CHECK"
        assert scans >= 1
        # a CHECK states the value after the last scan: one path, one expected value
        seen: dict[str, str] = {}
        for c in checks:
            key = c.path.replace(" ", "").upper()
            assert seen.setdefault(key, c.text) == c.text, f"{f.name}: conflicting CHECKs {c}"


def run_corpus_file(path: Path) -> tuple[dict[str, object], dict[str, object]]:
    scans, _ = parse_checks(path)
    mod = compile_files([path])
    assert mod.program.config is not None
    interval = mod.program.config.tasks[0].interval_ns
    mod.config_init()
    for k in range(scans):
        mod.run_task_index(0, k * interval)
    return mod.instance(INSTANCE).vars(), instance_types(mod)


@pytest.mark.parametrize("path", _params())
def test_semantics(path: Path) -> None:
    _, checks = parse_checks(path)
    values, types = run_corpus_file(path)
    failures = []
    for c in checks:
        try:
            actual, _ = walk(values, types, c.path)
        except (KeyError, IndexError, ValueError, AssertionError) as exc:
            failures.append(f"{c}: {exc}")
            continue
        msg = compare(c, actual)
        if msg:
            failures.append(msg)
    assert not failures, f"{path.name}:\n  " + "\n  ".join(failures)


@pytest.mark.parametrize("path", [pytest.param(f, id=f.stem) for f in FILES])
def test_matiec_accepts(matiec, path: Path) -> None:  # type: ignore[no-untyped-def]
    ok, _, out = matiec.verdict(path)
    assert ok, f"MatIEC rejects {path.name}:\n{out}"


@pytest.mark.parametrize("path", [pytest.param(f, id=f.stem) for f in FILES])
def test_matiec_values(matiec, path: Path) -> None:  # type: ignore[no-untyped-def]
    if matiec.run_script is None:
        pytest.skip("MatIEC values need run-st.sh: set MATIEC_CHECK=/opt/realplc/check-st.sh")
    from armbench.compiler.driver import analyse
    from armbench.compiler.targets import OPENPLC_ONLY

    scans, checks = parse_checks(path)
    # only for the variables' types, to address them in C; MatIEC runs it: its target
    prog, diags = analyse([path], target=OPENPLC_ONLY)
    exprs: list[str] = []
    ctypes: list[str | None] = []
    for i, c in enumerate(checks):
        if prog is None:  # our compiler rejects it (a bug): read MatIEC's default printout
            assert c.path.isidentifier(), f"{c}: needs our compiler's types\n{diags.render()}"
            ctypes.append(None)
            continue
        typ, expr = c_expr(instance_types(prog), c.path)
        ctypes.append(typ)
        exprs.append(f"chk{i}:{typ}={expr}")
    rc, out = matiec.run(path, scans, exprs)
    assert rc == 0, out
    printed = {}
    for line in out.splitlines():
        label, sep, val = line.partition("=")
        if sep:
            try:
                printed[label.strip().upper()] = parse_matiec_value(val)
            except ValueError:
                pass
    got = {}
    for i, c in enumerate(checks):
        key = f"CHK{i}" if ctypes[i] else f"{INSTANCE}.{c.path}".upper()
        if key in printed:
            v = printed[key]
            if isinstance(v, float) and (ctypes[i] == "REAL" or c.text.upper().startswith("REAL#")):
                v = f32(v)  # printed with %.9g: round back to the float it was
            got[i] = v
    failures = []
    for i, c in enumerate(checks):
        if i not in got:
            failures.append(f"{c}: not printed")
            continue
        msg = compare(c, bool(got[i]) if isinstance(c.value, bool) else got[i])
        if msg:
            failures.append(msg)
    assert not failures, f"MatIEC disagrees with {path.name}:\n  " + "\n  ".join(failures)
