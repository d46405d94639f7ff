"""The checker's time grows linearly with its input, for every construct.

Each construct is generated at about 2,000 and 20,000 tokens and checked, in the same run;
the larger must cost less than 15 times the smaller (linear: 10; the quadratic passes this
replaced cost 50 to 240 times: a diagnostic per level of a 20,000-sign chain of unary minus,
each compared with all earlier ones, took minutes). CPU time of this process, best of three:
wall time on a shared machine measures the neighbours too. Measured in a fresh interpreter, as
`armbench check` runs: the garbage collector's share depends on everything else alive in the
process, and inside pytest that is pytest and the earlier tests.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from armbench.compiler.driver import analyse

HEAD = "PROGRAM Main\nVAR\n  x : DINT;\n  b : BOOL;\n  r : REAL;\n  a : ARRAY[0..9] OF DINT;\n" \
       "END_VAR\n"
TAIL = "END_PROGRAM\n"


def _body(text: str) -> str:
    return HEAD + text + TAIL


# tokens -> program; each about `tokens` tokens long
CONSTRUCTS: dict[str, Callable[[int], str]] = {
    "nested parentheses": lambda n: _body("x := " + "(" * (n // 2) + "x" + ")" * (n // 2)
                                          + ";\n"),
    "unary minus chain": lambda n: _body("x := " + "- " * n + "x;\n"),
    "NOT chain": lambda n: _body("b := " + "NOT " * n + "b;\n"),
    "nested -(": lambda n: _body("x := " + "-(" * (n // 3) + "x" + ")" * (n // 3) + ";\n"),
    "nested calls": lambda n: _body("x := " + "ABS(" * (n // 3) + "x" + ")" * (n // 3)
                                    + ";\n"),
    "nested indices": lambda n: _body("x := " + "a[" * (n // 3) + "0" + "]" * (n // 3)
                                      + ";\n"),
    "long expression": lambda n: _body("x := " + " + ".join(["x"] * (n // 2)) + ";\n"),
    "many statements": lambda n: _body("x := x + 1;\n" * (n // 6)),
    "deep IF nesting": lambda n: _body("IF b THEN\n" * (n // 7) + "x := 1;\n"
                                       + "END_IF;\n" * (n // 7)),
    "many type errors": lambda n: _body("x := r;\n" * (n // 4)),
    "many syntax errors": lambda n: _body("x := ;\n" * (n // 3)),
}


def _cpu(path: Path) -> float:
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        analyse([path])
        best = min(best, time.process_time() - t0)
    return best


def measure(folder: Path) -> dict[str, tuple[float, float]]:
    """construct -> (CPU s for 2,000 tokens, for 20,000), in this process."""
    out = {}
    for name, make in CONSTRUCTS.items():
        small, large = folder / "small.st", folder / "large.st"
        small.write_text(make(2_000))
        large.write_text(make(20_000))
        analyse([small])  # warm up: the parser, data files
        out[name] = (_cpu(small), _cpu(large))
    return out


@pytest.fixture(scope="module")
def timings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[float, float]]:
    folder = tmp_path_factory.mktemp("scaling")
    code = (f"import json, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
            "from pathlib import Path; from test_scaling import measure; "
            f"print(json.dumps(measure(Path({str(folder)!r}))))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    return {k: (v[0], v[1]) for k, v in json.loads(proc.stdout).items()}


@pytest.mark.parametrize("construct", sorted(CONSTRUCTS))
def test_checking_time_is_linear(construct: str,
                                 timings: dict[str, tuple[float, float]]) -> None:
    t_small, t_large = timings[construct]
    assert t_large < 15 * t_small, (
        f"{construct}: 20,000 tokens took {t_large * 1e3:.1f} ms of CPU, 2,000 tokens "
        f"{t_small * 1e3:.1f} ms: {t_large / t_small:.1f} times (linear: 10)")


def test_a_chain_of_unary_signs_is_one_diagnostic(tmp_path: Path) -> None:
    src = tmp_path / "neg.st"
    src.write_text(CONSTRUCTS["unary minus chain"](10_000))
    _, diags = analyse([src])
    assert sorted(d.code for d in diags.items) == ["E0105", "E0108"]
    e0105 = next(d for d in diags.items if d.code == "E0105")
    assert (e0105.pos.line, e0105.pos.col) == (8, 6) and len(e0105.message) < 300
