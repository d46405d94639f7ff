"""Stateful property test of the controller: seeded random programs (ctl_fuzz.py) of every
command code and junk codes from up to four clients in the same scan, hostile arguments,
calibration and limit changes mid-motion, Relax/Stop storms, takeovers and waits, on the
in-process stepped PLC, with the output stage (A), Stop (B) and the mailbox answers checked
after EVERY scan. A failure names the seed, the scan, the channel, the value against its
limit and the commands of the last scans; `python bench/controller_stateful.py --seed N`
replays and extends a seed.

Budget: SEEDS x SCANS_PER_SEED = 90,000 scans checked, about 15 s on the shared 2-core
machine (plus the compile: about 7 s cold, 1 s cached); the figures print with -s.
"""

from __future__ import annotations

import pytest
from ctl_fuzz import FuzzReport, run
from stepped_controller import check_formula_from_env, load_controller

from armbench.softplc.loader import LoadedProgram

SEEDS = (11, 22, 33, 44, 55, 66)
SCANS_PER_SEED = 15_000


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@pytest.mark.parametrize("seed", SEEDS)
def test_random_programs_keep_every_promise(program: LoadedProgram, seed: int) -> None:
    report: FuzzReport = run(program, seed, max_scans=SCANS_PER_SEED,
                             check_formula=check_formula_from_env(), stop_at_first=True)
    print()
    print(report.format())
    first = report.first_violation()
    if first is not None:
        pytest.fail(f"seed {seed}: {first}", pytrace=False)
    assert report.scans >= SCANS_PER_SEED
    # the program must really have exercised the controller: commands run and motions made
    assert report.results.get(0, 0) > 50, f"results by code: {report.results}"
    assert report.output is not None
    assert max(f.worst_step_ratio for f in report.output.figures) > 0.3
