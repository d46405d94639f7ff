"""Fixtures for the ST block tests: the library st/*.st compiled once per session.

Also the hypothesis profile of the property tests (test_properties_*.py): derandomized and
without an example database, so that CI runs the same cases every time and never depends on
a previous run. `HYPOTHESIS_PROFILE=armbench-thorough` runs ten times as many cases (still
deterministic) for a local soak.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
ST_DIR = REPO / "st"

try:
    from hypothesis import HealthCheck, settings
except ImportError:  # pragma: no cover - the property tests skip themselves
    pass
else:
    _COMMON: dict[str, Any] = {
        "derandomize": True,
        "database": None,
        "deadline": None,
        "print_blob": False,
        "suppress_health_check": [HealthCheck.too_slow, HealthCheck.filter_too_much],
    }
    settings.register_profile("armbench", max_examples=400, **_COMMON)
    settings.register_profile("armbench-thorough", max_examples=4000, **_COMMON)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "armbench"))


@pytest.fixture(scope="session")
def st_module() -> Any:
    """The whole ST library (st/*.st) compiled by the bench's compiler, once per session.

    A compile error fails every test that uses it, with the compiler's diagnostics.
    """
    compiler = pytest.importorskip("armbench.compiler")
    paths = sorted(ST_DIR.glob("*.st"))
    assert paths, f"no ST sources in {ST_DIR}"
    try:
        return compiler.compile_files(paths)
    except compiler.CompileFailed as exc:  # pragma: no cover - reported as a failure
        pytest.fail(f"st/*.st does not compile:\n{exc}", pytrace=False)


class Figures:
    """Cases run, answers checked against the reference and the worst error, per POU, for
    the report (run with -s)."""

    def __init__(self) -> None:
        self.cases: dict[str, int] = {}
        self.checked: dict[str, int] = {}
        self.worst: dict[str, tuple[float, str]] = {}

    def case(self, pou: str) -> None:
        self.cases[pou] = self.cases.get(pou, 0) + 1

    def error(self, pou: str, value: float, unit: str) -> None:
        self.checked[pou] = self.checked.get(pou, 0) + 1
        if value > self.worst.get(pou, (-1.0, ""))[0]:
            self.worst[pou] = (value, unit)

    def table(self) -> str:
        lines = ["", f"{'POU':34} {'cases':>6} {'answers':>7}  worst |error| vs reference"]
        for pou in sorted(set(self.cases) | set(self.checked)):
            value, unit = self.worst.get(pou, (0.0, ""))
            worst = f"{value:.3e} {unit}" if unit else "exact (codes/values equal)"
            lines.append(f"{pou:34} {self.cases.get(pou, 0):>6} {self.checked.get(pou, 0):>7}"
                         f"  {worst}")
        return "\n".join(lines)


@pytest.fixture(scope="session")
def figures() -> Iterator[Figures]:
    """Session-wide tally of the property tests; printed at the end (run with -s)."""
    tally = Figures()
    yield tally
    if tally.cases:
        print(tally.table())
