"""Stateful soak of the controller (prints figures, not a test): the seeded random programs of
tests/controller/ctl_fuzz.py on the in-process stepped PLC for N seconds, every scan checked
against the output-stage, Stop and mailbox-answer promises (see
tests/controller/test_controller_stateful.py). Programs run seed, seed + 1, ... until the time
is up; each prints its scans, commands, worst |step|/limit and |step change|/limit per channel
and worst Stop-to-rest scans against the bound, and the first violation if any.

Run: PYTHONPATH=sim .venv/bin/python bench/controller_stateful.py [--seconds 300] [--seed 1]
     [--scans-per-seed 20000] [--check crc|weighted|sum] [--keep-going]
(--check sum: the old five-DINT check word, for a controller that still expects it.)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "controller"))

from ctl_fuzz import run  # noqa: E402
from stepped_controller import CHANNELS, CHECK_FORMULAS, load_controller  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scans-per-seed", type=int, default=20_000)
    ap.add_argument("--check", choices=sorted(CHECK_FORMULAS), default="crc")
    ap.add_argument("--keep-going", action="store_true",
                    help="run each program to its end instead of stopping at a violation")
    args = ap.parse_args(argv)
    program = load_controller()
    t0 = time.perf_counter()
    seed = args.seed
    scans = commands = failures = 0
    worst_step = [0.0] * len(CHANNELS)
    worst_change = [0.0] * len(CHANNELS)
    while time.perf_counter() - t0 < args.seconds:
        left = args.seconds - (time.perf_counter() - t0)
        report = run(program, seed, max_scans=args.scans_per_seed, seconds=left,
                     check_formula=CHECK_FORMULAS[args.check],
                     stop_at_first=not args.keep_going)
        print(report.format(), flush=True)
        scans += report.scans
        commands += report.commands
        failures += bool(report.violations)
        assert report.output is not None
        for c, f in enumerate(report.output.figures):
            worst_step[c] = max(worst_step[c], f.worst_step_ratio)
            worst_change[c] = max(worst_change[c], f.worst_change_ratio)
        seed += 1
    print(f"total: seeds {args.seed}..{seed - 1}, {scans} scans, {commands} commands, "
          f"{failures} program(s) with violations, {time.perf_counter() - t0:.1f} s")
    for c, name in enumerate(CHANNELS):
        print(f"  {name:<10} worst |step|/limit {worst_step[c]:.4f}  "
              f"worst |step change|/limit {worst_change[c]:.4f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
