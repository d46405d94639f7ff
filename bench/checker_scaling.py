"""How `armbench check` and the C build scale with long flat code (prints figures).

Long chains (`x + x + ...`), long ELSIF and CASE lists and long call graphs are legal at any
size; deep nesting stops at E0108 after the syntax-tree walk. Times are the best of 3.
Run: .venv/bin/python bench/checker_scaling.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from armbench.compiler import check_files
from armbench.compiler.build import build
from armbench.compiler.driver import emit_files

CONFIG = """
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


def main_with(body: str, before: str = "") -> str:
    return f"{before}\nPROGRAM Main\nVAR\n  x : DINT;\n  b : BOOL;\nEND_VAR\n{body}\n" \
        "END_PROGRAM\n" + CONFIG


SHAPES: dict[str, Callable[[int], str]] = {
    "sum a+a+...": lambda n: main_with("x := " + " + ".join(["x"] * n) + ";"),
    "ELSIF list": lambda n: main_with("IF b THEN x := 0;\n" + "".join(
        f"ELSIF x = {k} THEN x := {k + 1};\n" for k in range(n)) + "END_IF;"),
    "CASE list": lambda n: main_with("CASE x OF\n" + "".join(
        f"{k}: x := {k};\n" for k in range(n)) + "END_CASE;"),
    "call graph F0->F1->...": lambda n: main_with("x := F0(x);", "".join(
        f"FUNCTION F{k} : DINT\nVAR_INPUT\n  a : DINT;\nEND_VAR\n  F{k} := "
        f"{f'F{k + 1}(a)' if k < n else 'a'};\nEND_FUNCTION\n" for k in range(n + 1))),
    "nested IF (rejected)": lambda n: main_with("IF b THEN\n" * n + "x := 1;\n" +
                                                "END_IF;\n" * n),
}


def best_of(fn: Callable[[], object], repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    tmp = Path(tempfile.mkdtemp())
    for name, make in SHAPES.items():
        for n in (1_000, 5_000, 20_000):
            path = tmp / f"{name.split()[0]}_{n}.st"
            path.write_text(make(n), encoding="utf-8")
            ds = check_files([path])
            t_check = best_of(lambda p=path: check_files([p]))  # type: ignore[misc]
            line = f"{name:24s} n={n:6d}: check {t_check * 1e3:8.1f} ms"
            if ds:
                line += f"  ({ds[0].code})"
            elif n <= 5_000 or name.startswith("sum"):
                _, unit = emit_files([path])
                t0 = time.perf_counter()
                lib = build(unit)
                line += f", C build {time.perf_counter() - t0:6.2f} s" + \
                    (" (cached)" if lib.cached else "")
            print(line)
            sys.stdout.flush()


if __name__ == "__main__":
    main()
