"""The hypothesis set-up of the property tests: the `armbench` profiles (derandomized, no
example database) and a fixed constant pool, so that every run draws the same examples.

Why the pool: besides its random draws, hypothesis (the pinned 6.170.15) takes about one
number or string in twenty from a pool of constants that it reads from the source of every
*local* module in `sys.modules` (outside site-packages, the standard library and test
folders: for us sim/armbench and the PSM script), re-read whenever `sys.modules` grows. Which
of our modules are imported when a property test runs depends on the tests that ran before it
in the same process (tests/modbus imports armbench.batchgen only when its test runs, the
figure tests armbench.plots.*), and under pytest-xdist that is the worker's share of the
suite, which changes from run to run. A different pool changes the constant picked and can change
every draw after it, so derandomize=True alone gave different examples in two full runs.
`drop_local_constants` empties the pool; hypothesis' own constants (type extremes, nasty
floats, ...) stay, and the edge values our tests care about are in their strategies.

Exploring: derandomize=True makes hypothesis ignore `pytest --hypothesis-seed=N` (it draws
from a digest of the test function instead), so a soak that wants new ground could not get
it. With a seed on the command line, `use_seed_option` switches the loaded profile to its
`-seeded` variant (derandomize=False, same examples per test): the draws then follow N, and the
same N draws the same examples again. Without the option nothing changes, so CI stays fixed.
"""

from __future__ import annotations

import hypothesis
import pytest
from hypothesis import HealthCheck, settings
from hypothesis.internal.conjecture import providers
from hypothesis.internal.constants_ast import Constants

#: profile name -> examples per test: `armbench` is CI's, `armbench-thorough` a local soak.
PROFILES = {"armbench": 400, "armbench-thorough": 4000}


#: suffix of a profile's variant that follows `--hypothesis-seed` (see use_seed_option)
SEEDED = "-seeded"


def load_profile(name: str, *, seeded: bool = False) -> None:
    """Register the armbench profiles and load `name` (a key of PROFILES), or its `-seeded`
    variant (derandomize=False, for `--hypothesis-seed`) when `seeded`."""
    if name not in PROFILES:
        raise ValueError(f"unknown hypothesis profile {name!r}: HYPOTHESIS_PROFILE takes one "
                         f"of {sorted(PROFILES)}")
    for profile, examples in PROFILES.items():
        settings.register_profile(
            profile, max_examples=examples, derandomize=True, database=None, deadline=None,
            print_blob=False,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
        settings.register_profile(profile + SEEDED, parent=settings.get_profile(profile),
                                  derandomize=False)
    settings.load_profile(name + SEEDED if seeded else name)


def examples(n: int) -> settings:
    """The settings of a test that CI runs `n` examples of, in place of
    `@settings(max_examples=n)`: `n` times the loaded profile's examples over CI's.

    A test's own max_examples overrides the profile's, so with a bare
    `@settings(max_examples=n)` the ten-times soak (`armbench-thorough`) ran the same `n`
    examples as CI; this keeps each test's share of the budget and scales it with the profile.
    """
    if n < 1:
        raise ValueError(f"examples({n}): a property test needs at least one example")
    loaded = settings().max_examples  # a new settings object takes the loaded profile's
    return settings(max_examples=max(1, n * loaded // PROFILES["armbench"]))


def use_seed_option(config: pytest.Config) -> None:
    """Load the seeded variant of the current armbench profile if pytest was given
    `--hypothesis-seed` (call from pytest_configure, after `configure`).

    hypothesis' plugin turns the option into its global seed, which only a profile with
    derandomize=False uses; without this the option would be accepted and silently ignored.
    """
    if config.getoption("--hypothesis-seed", default=None) is None:
        return
    current = settings.get_current_profile_name()
    if current.endswith(SEEDED):
        return
    if current not in PROFILES:
        raise RuntimeError(f"--hypothesis-seed given but the loaded hypothesis profile is "
                           f"{current!r}, not one of {sorted(PROFILES)}: call configure() "
                           "before use_seed_option()")
    load_profile(current, seeded=True)


def drop_local_constants() -> None:
    """Make hypothesis' pool of local-source constants empty for the rest of the process.

    hypothesis has no setting for this, so its module-level lookup is replaced; the
    version is pinned in pyproject.toml, and a version without the lookup fails here
    rather than silently drawing order-dependent examples again.
    """
    lookup = getattr(providers, "_get_local_constants", None)
    cache = getattr(providers, "CONSTANTS_CACHE", None)
    if not callable(lookup) or cache is None:
        raise RuntimeError(
            f"hypothesis {hypothesis.__version__} has no providers._get_local_constants or "
            "CONSTANTS_CACHE: tests/unit/hypothesis_setup.py must be updated to keep the "
            "property tests' examples independent of the modules already imported")
    empty = Constants()
    providers._get_local_constants = lambda: empty
    # pools already computed for some strategy constraints would still hold local constants
    cache.cache.clear()


def configure(profile: str) -> None:
    """The property tests' set-up: `profile` loaded and the constant pool fixed."""
    load_profile(profile)
    drop_local_constants()
