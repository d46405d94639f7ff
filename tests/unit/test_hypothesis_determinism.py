"""The property tests draw the same examples in every run: whatever ran before them in the
same process (under pytest-xdist, the worker's share of the suite) and whatever the hash seed.

Each case runs a small property test in a fresh pytest process set up by hypothesis_setup
(as tests/unit/conftest.py does) and compares what it drew. The order that used to change
the draws: a test that imports a module of ours (constants in its source) before the
property test runs, as tests/modbus imports armbench.batchgen only when its test runs.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("hypothesis")

UNIT_DIR = Path(__file__).resolve().parent

# A module of ours the way hypothesis sees one: local (not site-packages, not a test folder),
# with numbers in its source.
LATE_MODULE = "LIMITS = (" + ", ".join(
    [str(104729 + 7919 * i) for i in range(60)]
    + [repr(0.1 * (i + 3) + 1e-3 * i) for i in range(60)]) + ")\n"

CONFTEST = f"""
import os
import sys

sys.path.insert(0, {str(UNIT_DIR)!r})
import hypothesis_setup

if os.environ.get("DRAWS_SETUP") == "profile-only":   # the set-up without the fixed pool
    hypothesis_setup.load_profile("armbench")
else:
    hypothesis_setup.configure("armbench")
"""

PROPERTY_TESTS = """
import os

from hypothesis import given, strategies as st


def test_imports_a_module_of_ours():
    import late_module

    assert late_module.LIMITS


@given(n=st.integers(), x=st.floats(allow_nan=False), s=st.lists(st.integers(0, 10**6)))
def test_draws(n, x, s):
    with open(os.environ["DRAWS_OUT"], "a", encoding="utf-8") as out:
        out.write(f"{n!r} {x!r} {s!r}\\n")
"""


def draws(folder: Path, tests: list[str], hash_seed: str, setup: str = "configure") -> str:
    """What test_draws drew, one line per example, run after `tests` in one pytest process."""
    out = folder / f"draws-{len(list(folder.glob('draws-*')))}.txt"
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTEST_", "HYPOTHESIS_", "PYTHONHASHSEED"))}
    env.update(PYTHONHASHSEED=hash_seed, DRAWS_OUT=str(out), DRAWS_SETUP=setup)
    ids = [f"test_property.py::{name}" for name in [*tests, "test_draws"]]
    proc = subprocess.run(
        # no armbench plugin: its import analyses the controller (a second per process)
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         "-p", "no:armbench", *ids],
        cwd=folder, env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out.read_text(encoding="utf-8")


@pytest.fixture()
def folder(tmp_path: Path) -> Path:
    (tmp_path / "conftest.py").write_text(CONFTEST, encoding="utf-8")
    (tmp_path / "late_module.py").write_text(LATE_MODULE, encoding="utf-8")
    (tmp_path / "test_property.py").write_text(PROPERTY_TESTS, encoding="utf-8")
    return tmp_path


def test_same_examples_whatever_ran_before_and_the_hash_seed(folder: Path) -> None:
    alone = draws(folder, [], hash_seed="1")
    after_import = draws(folder, ["test_imports_a_module_of_ours"], hash_seed="2")
    assert alone.count("\n") == 400   # the armbench profile's examples, all drawn
    assert after_import == alone


def test_the_probe_sees_the_order_dependence_without_the_fixed_pool(folder: Path) -> None:
    # Without this the test above could pass because the probe no longer provokes anything
    # (say a hypothesis version without local constants): then the pin is dead code.
    alone = draws(folder, [], hash_seed="1", setup="profile-only")
    after_import = draws(folder, ["test_imports_a_module_of_ours"], hash_seed="1",
                         setup="profile-only")
    assert after_import != alone


def test_the_suite_runs_with_the_fixed_pool() -> None:
    # This process was set up by tests/unit/conftest.py; armbench (ours, constants in its
    # source) is imported, yet the pool hypothesis draws constants from stays empty.
    from hypothesis.internal.conjecture import providers

    import armbench.compiler  # noqa: F401

    assert len(providers._get_local_constants()) == 0
