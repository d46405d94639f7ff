"""The PLCopen single-axis layer (st/AMC*.st) under random block sequences for longer than CI:
tests/unit/amc_stateful.py's machine (two axes, every AMC_* block per axis, random call
orders, edges, aborts, power cycles, resets, bad inputs) on the bench-compiled ST, every scan
checked against tests/unit/plcopen_model.py (the same checks as
tests/unit/test_amc_axis_stateful.py). Seeds seed, seed + 1, ... until the time is up; prints
scans, block calls and rule checks, the diagram transitions and block results seen.

Run: PYTHONPATH=sim .venv/bin/python bench/plcopen_axis_soak.py [--seconds S] [--seed N]
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

from amc_bench import compile_bench  # noqa: E402
from amc_stateful import Figures, Machine, random_run, report  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scans-per-run", type=int, default=3000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        module = compile_bench(Path(tmp))
    total = Figures()
    runs = 0
    seed = args.seed
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        m = Machine(module)
        random_run(m, random.Random(seed), args.scans_per_run)
        runs += 1
        seed += 1
        total.scans += m.fig.scans
        total.calls += m.fig.calls
        for src, dst in ((m.fig.checks, total.checks), (m.fig.transitions, total.transitions),
                         (m.fig.results, total.results)):
            for k, v in src.items():
                dst[k] = dst.get(k, 0) + v
    print(f"{runs} runs (seeds {args.seed}..{seed - 1}), all checks passed")
    print(report(total))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
