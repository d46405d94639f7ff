"""Soak of the property tests: every tests/unit module that uses hypothesis, run with a
larger hypothesis profile than CI's (prints figures, not a test).

Each module runs in its own pytest subprocess (so one slow or crashing module cannot hide the
others) with HYPOTHESIS_PROFILE set (tests/unit/hypothesis_setup.py: ``armbench`` = CI's 400
examples, ``armbench-thorough`` = 4000, both derandomized; a test's own example count,
``examples(n)``, scales with the profile) and ``--hypothesis-show-statistics``;
the report is per module: pass/fail, tests, examples run (the sum of hypothesis's "N passing,
M failing, K invalid" lines) and wall time. ``--seconds`` is the budget for the whole soak:
a module that would start after it is spent is reported as not run, and a running module is
stopped at the budget's end.

The derandomized profiles draw CI's examples (ten times as many with the thorough one);
``--seed N`` draws other ones (``--hypothesis-seed=N``, which tests/unit/conftest.py honours
with the profile's derandomize=False variant), the same ones again for the same N.
``-k`` may be given more than once: modules run in the order of the first pattern they match.
``--logs DIR`` keeps each module's pytest output (the falsifying examples of a failure).

Run: .venv/bin/python bench/property_soak.py [--profile armbench-thorough] [--seconds 3600]
     [--seed N] [-k pattern ...] [--logs DIR]  (PYTHONPATH=sim from a worktree)
"""

from __future__ import annotations

import argparse
import ast
import os
import re
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TEST_DIR = REPO / "tests" / "unit"
_EXAMPLES = re.compile(r"- (\d+) passing, (\d+) failing, and (\d+) invalid")
_SUMMARY = re.compile(r"(\d+) (passed|failed|error|errors|skipped|xfailed|xpassed)")


@dataclass(frozen=True)
class ModuleResult:
    name: str
    status: str  # "pass", "FAIL", "timeout", "not run"
    tests: int
    examples: int
    failing_examples: int
    seconds: float


def property_modules(test_dir: Path = TEST_DIR) -> list[Path]:
    """The test modules that import hypothesis (tests/unit/test_*.py)."""
    found = []
    for path in sorted(test_dir.glob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if (isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hypothesis")
                    or isinstance(node, ast.Import)
                    and any(a.name.startswith("hypothesis") for a in node.names)):
                found.append(path)
                break
    return found


def parse_output(text: str) -> tuple[int, int, int]:
    """(tests run, examples, failing examples) from pytest's output with the statistics."""
    examples = failing = 0
    for match in _EXAMPLES.finditer(text):
        examples += sum(int(g) for g in match.groups())
        failing += int(match.group(2))
    tests = sum(int(n) for n, kind in _SUMMARY.findall(text.splitlines()[-1] if text else "")
                if kind in ("passed", "failed", "xfailed", "xpassed"))
    return tests, examples, failing


def ordered_modules(modules: Sequence[Path], patterns: Sequence[str]) -> list[Path]:
    """The modules whose file name contains one of `patterns` (all of them if none), in the
    order of the first pattern each matches."""
    if not patterns:
        return list(modules)
    ranked = []
    for path in modules:
        rank = next((i for i, pattern in enumerate(patterns) if pattern in path.name), None)
        if rank is not None:
            ranked.append((rank, path))
    return [path for _, path in sorted(ranked, key=lambda item: item[0])]


def run_module(path: Path, profile: str, timeout: float, seed: int | None = None,
               logs: Path | None = None) -> ModuleResult:
    env = dict(os.environ, HYPOTHESIS_PROFILE=profile)
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
           "--hypothesis-show-statistics", "-W", "ignore", str(path.relative_to(REPO))]
    if seed is not None:
        cmd.insert(-1, f"--hypothesis-seed={seed}")
    start = time.monotonic()
    try:
        proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True,
                              timeout=timeout, check=False)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        _write_log(logs, path, out)
        tests, examples, failing = parse_output(out)
        return ModuleResult(path.name, "timeout", tests, examples, failing,
                            time.monotonic() - start)
    _write_log(logs, path, proc.stdout + proc.stderr)
    tests, examples, failing = parse_output(proc.stdout.rstrip())
    status = "pass" if proc.returncode == 0 else "FAIL"
    return ModuleResult(path.name, status, tests, examples, failing, time.monotonic() - start)


def _write_log(logs: Path | None, path: Path, text: str) -> None:
    if logs is not None:
        logs.mkdir(parents=True, exist_ok=True)
        (logs / f"{path.stem}.log").write_text(text, encoding="utf-8")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--profile", default="armbench-thorough",
                        help="hypothesis profile (tests/unit/hypothesis_setup.py)")
    parser.add_argument("--seconds", type=float, default=3600.0,
                        help="budget of the whole soak, s")
    parser.add_argument("--seed", type=int, default=None,
                        help="explore: draw the examples of this hypothesis seed instead of "
                             "CI's derandomized ones")
    parser.add_argument("-k", dest="patterns", action="append", default=[],
                        help="only modules whose file name contains this (repeatable; run in "
                             "the order given)")
    parser.add_argument("--logs", type=Path, default=None,
                        help="folder for each module's pytest output")
    args = parser.parse_args(argv)
    modules = ordered_modules(property_modules(), args.patterns)
    deadline = time.monotonic() + args.seconds
    results: list[ModuleResult] = []
    seed = "derandomized" if args.seed is None else f"seed {args.seed}"
    print(f"profile {args.profile} ({seed}), {len(modules)} modules, "
          f"budget {args.seconds:.0f} s")
    for path in modules:
        left = deadline - time.monotonic()
        if left <= 0:
            results.append(ModuleResult(path.name, "not run", 0, 0, 0, 0.0))
            continue
        result = run_module(path, args.profile, left, args.seed, args.logs)
        results.append(result)
        print(f"  {result.name:48} {result.status:8} {result.tests:4} tests "
              f"{result.examples:8} examples {result.seconds:8.1f} s", flush=True)
    bad = [r for r in results if r.status != "pass"]
    total = sum(r.seconds for r in results)
    print(f"{len(results) - len(bad)}/{len(results)} modules passed, "
          f"{sum(r.examples for r in results)} examples, {total:.1f} s")
    for r in bad:
        print(f"  {r.status}: {r.name}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
