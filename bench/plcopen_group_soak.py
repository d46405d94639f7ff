"""The PLCopen axis-group layer (st/AMCGroup*.st) under random sequences for longer than CI:
tests/unit/amc_group_stateful.py's machine (one group of three axes: axes powered on and off,
moved, run into a range end, reset; group enable, disable, reset and model selection in random
call orders) on the bench-compiled ST, every scan checked against
tests/unit/plcopen_group_model.py (the checks of tests/unit/test_amc_group_stateful.py).
Seeds seed, seed + 1, ... until the time is up; prints scans, group block calls, checks and
the group transitions seen.

Run: PYTHONPATH=sim .venv/bin/python bench/plcopen_group_soak.py [--seconds S] [--seed N]
     [--scans-per-run K]
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "unit"))

from amc_group_bench import compile_group_bench  # noqa: E402
from amc_group_stateful import GroupMachine, random_run  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scans-per-run", type=int, default=3000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        module = compile_group_bench(Path(tmp))
    scans = calls = checks = runs = 0
    transitions: dict[str, int] = {}
    seed = args.seed
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        m = GroupMachine(module)
        random_run(m, random.Random(seed), args.scans_per_run)
        runs += 1
        seed += 1
        scans, calls, checks = scans + m.fig.scans, calls + m.fig.calls, checks + m.fig.checks
        for k, v in m.fig.transitions.items():
            transitions[k] = transitions.get(k, 0) + v
    print(f"{runs} runs (seeds {args.seed}..{seed - 1}), all checks passed")
    print(f"{scans} scans, {calls} group block calls, {checks} checks")
    for k, v in sorted(transitions.items()):
        print(f"  {k}: {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
