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

PROFILE = os.environ.get("DRAWS_PROFILE", "armbench")
if os.environ.get("DRAWS_SETUP") == "profile-only":   # the set-up without the fixed pool
    hypothesis_setup.load_profile(PROFILE)
else:
    hypothesis_setup.configure(PROFILE)


def pytest_configure(config):
    if os.environ.get("DRAWS_SETUP") != "profile-only":
        hypothesis_setup.use_seed_option(config)
"""

PROPERTY_TESTS = """
import os

from hypothesis import given, strategies as st
from hypothesis_setup import examples


def test_imports_a_module_of_ours():
    import late_module

    assert late_module.LIMITS


@given(n=st.integers(), x=st.floats(allow_nan=False), s=st.lists(st.integers(0, 10**6)))
def test_draws(n, x, s):
    with open(os.environ["DRAWS_OUT"], "a", encoding="utf-8") as out:
        out.write(f"{n!r} {x!r} {s!r}\\n")


@examples(30)
@given(n=st.integers())
def test_draws_of_a_test_with_its_own_count(n):
    with open(os.environ["DRAWS_OUT"], "a", encoding="utf-8") as out:
        out.write(f"{n!r}\\n")
"""


def draws(folder: Path, tests: list[str], hash_seed: str, setup: str = "configure",
          seed: int | None = None, profile: str = "armbench",
          probe: str = "test_draws") -> str:
    """What the `probe` test drew, one line per example, run after `tests` in one pytest
    process (with `--hypothesis-seed=seed` if a seed is given)."""
    out = folder / f"draws-{len(list(folder.glob('draws-*')))}.txt"
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTEST_", "HYPOTHESIS_", "PYTHONHASHSEED"))}
    env.update(PYTHONHASHSEED=hash_seed, DRAWS_OUT=str(out), DRAWS_SETUP=setup,
               DRAWS_PROFILE=profile)
    ids = [f"test_property.py::{name}" for name in [*tests, probe]]
    proc = subprocess.run(
        # no armbench plugin: its import analyses the controller (a second per process)
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         "-p", "no:armbench", *([] if seed is None else [f"--hypothesis-seed={seed}"]), *ids],
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


def test_a_seed_on_the_command_line_draws_other_examples_the_same_for_the_same_seed(
        folder: Path) -> None:
    # The soak's --seed: derandomize=True alone would ignore --hypothesis-seed and draw the
    # fixed examples again, so a "new" soak would only repeat CI's.
    fixed = draws(folder, [], hash_seed="1")
    seed_1 = draws(folder, [], hash_seed="1", seed=1)
    seed_1_again = draws(folder, ["test_imports_a_module_of_ours"], hash_seed="2", seed=1)
    seed_2 = draws(folder, [], hash_seed="1", seed=2)
    assert seed_1.count("\n") == seed_2.count("\n") == 400   # still the profile's examples
    assert seed_1 != fixed
    assert seed_2 != seed_1
    assert seed_1_again == seed_1


def test_a_test_with_its_own_example_count_scales_with_the_profile(folder: Path) -> None:
    # examples(n) is CI's n under armbench and ten times n under the thorough soak; a bare
    # @settings(max_examples=n) overrode the profile, so the "10x" soak ran CI's n again
    probe = "test_draws_of_a_test_with_its_own_count"
    ci = draws(folder, [], hash_seed="1", probe=probe)
    thorough = draws(folder, [], hash_seed="1", profile="armbench-thorough", probe=probe)
    assert ci.count("\n") == 30
    assert thorough.count("\n") == 300
