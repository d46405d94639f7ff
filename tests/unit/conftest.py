"""Fixtures for the ST block tests: the library st/*.st compiled once per session.

Also the hypothesis set-up of the property tests (test_properties_*.py and the other users,
hypothesis_setup.py): derandomized, without an example database and with a fixed constant
pool, so that CI draws the same cases in every run, whatever the worker split and test order,
and never depends on a previous run. `HYPOTHESIS_PROFILE=armbench-thorough` runs ten times as
many cases (still deterministic) for a local soak; `--hypothesis-seed=N` draws other cases
(the profile's derandomize=False variant, the same ones for the same N) to explore.
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
    import hypothesis  # noqa: F401
except ImportError:  # pragma: no cover - the property tests skip themselves
    pass
else:
    from hypothesis_setup import configure

    configure(os.environ.get("HYPOTHESIS_PROFILE", "armbench"))


def pytest_configure(config: pytest.Config) -> None:
    try:
        from hypothesis_setup import use_seed_option
    except ImportError:  # pragma: no cover - no hypothesis, nothing to seed
        return
    use_seed_option(config)


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
