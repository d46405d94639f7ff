"""The package can be adopted: a licence, complete metadata, and dependency ranges that a
user's existing test environment can satisfy, each tested at both of its ends.

* LICENSE is the MIT licence and pyproject.toml says so (SPDX expression, licence file); the
  README says why.
* Every dependency is a range with a lower and an upper bound, never one exact version.
* tests/packaging/constraints-lowest.txt pins each dependency to its lower bound (the CI job
  scripts/test-lowest.sh installs exactly that and runs the suites of the modules that use
  them); tests/packaging/constraints-current.txt (the lock of the main environment) pins
  versions inside every range.
* pip resolves the package into an environment that holds back pymodbus below 3.16 and numpy
  below 2 (the report that started this: the pinned wheel gave ResolutionImpossible).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.utils import canonicalize_name
from packaging.version import Version

REPO = Path(__file__).resolve().parents[2]
LOWEST = REPO / "tests" / "packaging" / "constraints-lowest.txt"
CURRENT = REPO / "tests" / "packaging" / "constraints-current.txt"
OFFLINE_SIGNS = ("No matching distribution found", "Could not find a version",
                 "NewConnectionError", "Temporary failure in name resolution",
                 "Network is unreachable", "Failed to establish a new connection")


def project() -> dict[str, Any]:
    meta: dict[str, Any] = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    return meta


def runtime() -> list[Requirement]:
    return [Requirement(d) for d in project()["project"]["dependencies"]]


def dev() -> list[Requirement]:
    return [Requirement(d) for d in project()["project"]["optional-dependencies"]["dev"]]


def pins(path: Path) -> dict[str, Version]:
    """``name==version`` lines of a constraints file (comments and blank lines skipped)."""
    out: dict[str, Version] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        req = Requirement(line)
        spec = list(req.specifier)
        assert len(spec) == 1 and spec[0].operator == "==", f"{path.name}: {line!r} is no pin"
        out[canonicalize_name(req.name)] = Version(spec[0].version)
    return out


def bounds(spec: SpecifierSet) -> tuple[Version, Version]:
    lower = [Version(s.version) for s in spec if s.operator == ">="]
    upper = [Version(s.version) for s in spec if s.operator == "<"]
    assert len(lower) == 1 and len(upper) == 1, f"{spec}: want one >= and one < bound"
    return lower[0], upper[0]


# ------------------------------------------------------------------------------- licence

def test_license_is_mit_and_declared() -> None:
    text = (REPO / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License\n")
    # the licence's own operative sentences (opensource.org/license/mit)
    for phrase in ("Permission is hereby granted, free of charge, to any person obtaining a copy",
                   "The above copyright notice and this permission notice shall be included in "
                   "all\ncopies or substantial portions of the Software.",
                   'THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND'):
        assert phrase in text, phrase
    meta = project()["project"]
    assert meta["license"] == "MIT"
    assert meta["license-files"] == ["LICENSE"]
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("\n## License\n"):]
    assert "[MIT licence](LICENSE)" in section and "copyleft" in section


def test_metadata_is_complete() -> None:
    meta = project()["project"]
    assert meta["readme"] == "README.md"
    assert meta["requires-python"] == ">=3.11"
    assert len(meta["description"]) > 40
    assert meta["authors"] and all(a.get("name") for a in meta["authors"])
    assert meta["maintainers"] and all(m.get("name") for m in meta["maintainers"])
    assert len(meta["keywords"]) >= 5
    classifiers = set(meta["classifiers"])
    for c in ("Framework :: Pytest", "Programming Language :: Python :: 3.11",
              "Intended Audience :: Manufacturing", "Intended Audience :: Education"):
        assert c in classifiers, c
    # PEP 639: the SPDX expression replaces licence classifiers (setuptools refuses both)
    assert not any(c.startswith("License ::") for c in classifiers)
    # addresses only where one exists: there is no public home page yet
    assert "urls" not in meta


# --------------------------------------------------------------------------- dependencies

def test_every_dependency_is_a_range() -> None:
    for req in [*runtime(), *dev()]:
        assert not any(s.operator in ("==", "===", "~=") for s in req.specifier), (
            f"{req}: an exact pin keeps the wheel out of environments that hold another "
            "version; give a range (lock exact versions in constraints-current.txt)")
        low, high = bounds(req.specifier)
        assert low < high, req


def test_lowest_constraints_pin_every_lower_bound() -> None:
    lowest = pins(LOWEST)
    for req in runtime():
        low, _ = bounds(req.specifier)
        assert lowest.get(canonicalize_name(req.name)) == low, (
            f"{LOWEST.name} must pin {req.name}=={low}, the lower bound in pyproject.toml")
    pytest_req = next(r for r in dev() if r.name == "pytest")
    assert lowest["pytest"] == bounds(pytest_req.specifier)[0]  # the plugin's oldest pytest
    # the other test tools of the job are the lock's (they are no claim of ours)
    current = pins(CURRENT)
    for name in ("hypothesis", "pytest-xdist"):
        assert lowest[name] == current[name], name


def test_lock_is_inside_every_range() -> None:
    current = pins(CURRENT)
    for req in [*runtime(), *dev()]:
        name = canonicalize_name(req.name)
        assert name in current, f"{CURRENT.name} lacks {req.name}"
        assert current[name] in req.specifier, f"{req.name}=={current[name]} outside {req}"


def test_installed_versions_are_inside_the_ranges() -> None:
    """The environment running this suite (the main one, or the lowest-versions job's)."""
    from importlib import metadata

    for req in runtime():
        version = Version(metadata.version(req.name))
        assert version in req.specifier, f"installed {req.name} {version} outside {req}"


def test_ci_runs_the_lowest_versions_job() -> None:
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    assert "bash scripts/test-lowest.sh" in ci
    script = (REPO / "scripts" / "test-lowest.sh").read_text(encoding="utf-8")
    assert "tests/packaging/constraints-lowest.txt" in script
    setup = (REPO / "scripts" / "setup.sh").read_text(encoding="utf-8")
    assert "-c tests/packaging/constraints-current.txt" in setup


def test_resolves_into_an_environment_with_older_versions(tmp_path: Path) -> None:
    """pip's resolver (dry run, nothing installed) takes the package together with a user's
    constraints pymodbus<3.16 and numpy<2, as a test engineer's existing venv has them."""
    src = tmp_path / "src"
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE"):
        src.mkdir(exist_ok=True)
        shutil.copy2(REPO / name, src / name)
    for name in ("sim", "st", "plc_project"):
        shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns(
            "__pycache__", "*.egg-info", "build"))
    user_env = tmp_path / "user-env.txt"
    user_env.write_text("pymodbus<3.16\nnumpy<2\n")
    report = tmp_path / "report.json"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    proc = subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check",
                           "install", "--dry-run", "--ignore-installed", "--quiet",
                           "--report", str(report), "-c", str(user_env), str(src)],
                          capture_output=True, text=True, timeout=600, env=env)
    out = proc.stdout + proc.stderr
    if proc.returncode != 0:
        sign = next((ln for ln in out.splitlines() if any(s in ln for s in OFFLINE_SIGNS)),
                    None)
        if sign is not None and "ResolutionImpossible" not in out:
            pytest.skip(f"PyPI is unreachable and pip's cache lacks a package: {sign[:160]}")
    assert proc.returncode == 0, out[-3000:]
    chosen = {canonicalize_name(i["metadata"]["name"]): Version(i["metadata"]["version"])
              for i in json.loads(report.read_text())["install"]}
    assert chosen["pymodbus"] < Version("3.16") and chosen["numpy"] < Version("2")
    assert "armbench" in chosen


def test_lowest_job_versions_match_the_script() -> None:
    """The job installs the constraints file and nothing pinned beside it."""
    script = (REPO / "scripts" / "test-lowest.sh").read_text(encoding="utf-8")
    assert not re.search(r"\b[\w-]+==\d", script), "pins belong in constraints-lowest.txt"
