"""The PLCopen single-axis layer (st/AMC*.st) from outside.

1. A hypothesis stateful test (RuleBasedStateMachine): random sequences of block inputs on two
   axes -- Execute edges, aborts, two commands in one scan, inputs changed while Busy, power
   cycles, resets, random call orders -- run through the bench-compiled ST; every scan checks
   every block's outputs and both axes' states against plcopen_model.py (the PLCopen state
   diagram and output rules written from the specification), the exclusivity of
   Busy/Done/Error/CommandAborted, Active within Busy, ReadStatus and the set point's
   continuity (amc_stateful.py). Bounded here; bench/plcopen_axis_soak.py runs it longer.
2. Durations: AMC_MoveAbsolute (and MoveRelative, Home, an override) from rest takes the scans
   ruckig's time-optimal trajectory with the same limits takes (the first scan at or past
   ruckig's duration reports Done); with PYPLCOPEN_PYTHON set (a Python with the pyplcopen
   package: PyPI, lusipad/plcopen) also pyplcopen's AxisSim move_absolute, in the same run,
   whose time may only be longer (it is not time-optimal: the figures are printed).
3. A velocity move towards a range end stops the axis in ErrorStop (JointLimit) inside the
   range, and MC_Reset brings it back.
"""

from __future__ import annotations

import math
import os
import random
import subprocess
from pathlib import Path
from typing import Any

import pytest

hypothesis = pytest.importorskip("hypothesis")
ruckig = pytest.importorskip("ruckig")
from amc_bench import ABS_A, BLOCKS, HOME, OVERRIDE, POWER, REL, RESET, VEL, compile_bench  # noqa: E402
from amc_stateful import CFG, CYCLE, Machine, random_params, report  # noqa: E402
from hypothesis import settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.stateful import RuleBasedStateMachine, rule, run_state_machine_as_test  # noqa: E402

ERRORSTOP, STANDSTILL = 6, 1


@pytest.fixture(scope="module")
def bench_module(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return compile_bench(tmp_path_factory.mktemp("amc"))


def test_random_sequences_follow_the_plcopen_model(bench_module: Any) -> None:
    figures: list[Machine] = []

    class PlcopenAxes(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            self.machine = Machine(bench_module)
            figures.append(self.machine)
            for a in range(2):
                self.machine.set_block(a, POWER, True)

        @rule(axis=st.integers(0, 1), block=st.integers(1, BLOCKS - 1),
              seed=st.integers(0, 2**32 - 1))
        def toggle(self, axis: int, block: int, seed: int) -> None:
            rng = random.Random(seed)
            slot = axis * BLOCKS + block - 1
            execute = rng.random() < 0.8 if block == POWER else not self.machine.exec[slot]
            self.machine.set_block(axis, block, execute, random_params(rng, block))

        @rule(axis=st.integers(0, 1), block=st.sampled_from([ABS_A, REL, VEL, HOME]),
              seed=st.integers(0, 2**32 - 1))
        def change_inputs_while_busy(self, axis: int, block: int, seed: int) -> None:
            slot = axis * BLOCKS + block - 1
            self.machine.set_block(axis, block, self.machine.exec[slot],
                                   random_params(random.Random(seed), block))

        @rule(scans=st.sampled_from([1, 1, 2, 5, 20, 80]), shuffle=st.integers(0, 2**32 - 1))
        def run(self, scans: int, shuffle: int) -> None:
            order = list(range(1, 2 * BLOCKS + 1))
            if shuffle % 3 == 0:
                random.Random(shuffle).shuffle(order)
            for k in range(scans):
                self.machine.scan(order if k == 0 else None)

    run_state_machine_as_test(PlcopenAxes, settings=settings(
        max_examples=int(os.environ.get("AMC_STATEFUL_EXAMPLES", "12")),
        stateful_step_count=40, deadline=None, derandomize=True, database=None))
    scans = sum(m.fig.scans for m in figures)
    calls = sum(m.fig.calls for m in figures)
    checks = sum(sum(m.fig.checks.values()) for m in figures)
    print(f"\nstateful: {len(figures)} runs, {scans} scans, {calls} block calls, {checks} checks")
    assert scans > 500


def test_long_random_run_visits_the_whole_diagram(bench_module: Any) -> None:
    """A seeded run long enough to reach every transition of the single-axis diagram."""
    from amc_stateful import random_run
    seen: dict[str, int] = {}
    for seed in range(10):
        m = Machine(bench_module)
        random_run(m, random.Random(seed), 1500)
        for k, v in m.fig.transitions.items():
            seen[k] = seen.get(k, 0) + v
    print("\n" + report(m.fig))
    for t in ("Disabled->Standstill", "Standstill->DiscreteMotion", "DiscreteMotion->Standstill",
              "Standstill->ContinuousMotion", "ContinuousMotion->DiscreteMotion",
              "Standstill->Homing", "Homing->Standstill", "DiscreteMotion->Stopping",
              "ContinuousMotion->Stopping", "Stopping->Standstill", "ContinuousMotion->ErrorStop",
              "ErrorStop->Standstill", "Standstill->Disabled"):
        assert seen.get(t, 0) > 0, (t, seen)


# ------------------------------------------------------------------------ durations
def ruckig_duration(distance: float, vel: float, acc: float, jerk: float) -> float:
    inp = ruckig.InputParameter(1)
    inp.current_position = [0.0]
    inp.target_position = [distance]
    inp.max_velocity = [vel]
    inp.max_acceleration = [acc]
    inp.max_jerk = [jerk]
    traj = ruckig.Trajectory(1)
    ruckig.Ruckig(1).calculate(inp, traj)
    return float(traj.duration)


PYPLCOPEN_SCRIPT = """
import sys, pyplcopen as p
dt = float(sys.argv[1])
def ok(P, V, A, J, k):
    a = p.AxisSim(); a.power_on()
    try:
        a.move_absolute(P, V * dt, A * dt * dt, A * dt * dt, J * dt ** 3, max_cycles=k)
        return abs(a.command_position() - P) < 1e-6
    except RuntimeError:
        return False
for line in sys.stdin:
    P, V, A, J = map(float, line.split())
    lo, hi = 1, 200000
    while lo < hi:
        m = (lo + hi) // 2
        lo, hi = (lo, m) if ok(P, V, A, J, m) else (m + 1, hi)
    print(lo)
"""


def pyplcopen_cycles(cases: list[tuple[float, float, float, float]]) -> list[int] | None:
    """pyplcopen's cycles for each move from rest (the fewest max_cycles its blocking
    move_absolute completes in), run by the Python PYPLCOPEN_PYTHON names; None when unset."""
    python = os.environ.get("PYPLCOPEN_PYTHON")
    if not python:
        return None
    text = "".join(f"{p!r} {v!r} {a!r} {j!r}\n" for p, v, a, j in cases)
    out = subprocess.run([python, "-c", PYPLCOPEN_SCRIPT, repr(CYCLE)], input=text,
                         capture_output=True, text=True, timeout=600, check=True)
    return [int(x) for x in out.stdout.split()]


MOVES = [(45.0, 100.0, 500.0, 5000.0), (10.0, 120.0, 600.0, 6000.0),
         (80.0, 60.0, 200.0, 1000.0), (-30.0, 20.0, 600.0, 6000.0), (0.5, 120.0, 600.0, 6000.0),
         (-85.0, 120.0, 50.0, 500.0)]


def scans_to_done(m: Machine, axis: int, block: int, params: list[float]) -> int:
    m.set_block(axis, block, True, (params, 0))
    for n in range(1, 5000):
        m.scan()
        slot = axis * BLOCKS + block - 1
        if m.fb.Done[slot]:
            m.set_block(axis, block, False)
            m.scan()
            return n
    raise AssertionError("no Done")


def test_move_durations_equal_ruckig(bench_module: Any) -> None:
    ratios = []
    for p, v, a, j in MOVES:
        m = Machine(bench_module)
        m.set_block(0, POWER, True)
        m.scan()
        n = scans_to_done(m, 0, ABS_A, [p, v, a, a * 2.0, j])  # Deceleration above: no effect
        t = ruckig_duration(p, v, a, j)
        # the move runs in the drive from the edge's scan on; Done shows one scan later
        assert (n - 2) * CYCLE < t + 1e-9 and t <= (n - 1) * CYCLE + 1e-9, (p, n, t)
        ratios.append((n - 1) * CYCLE / t)
        # and back by a relative move with the override at 0.5: ruckig at half the velocity
        m.set_block(0, OVERRIDE, True, ([0.5, 1.0, 1.0, 0.0, 0.0], 0))
        n = scans_to_done(m, 0, REL, [-p, v, a, a, j])
        t = ruckig_duration(p, v * 0.5, a, j)
        assert (n - 2) * CYCLE < t + 1e-9 and t <= (n - 1) * CYCLE + 1e-9, (p, n, t)
        assert abs(m.fb.Out1["SetPosDeg"]) < 1e-9
    # Home at HomeVelDeg and the axis' acceleration and jerk limits
    m = Machine(bench_module)
    m.set_block(0, POWER, True)
    m.scan()
    n = scans_to_done(m, 0, HOME, [40.0, 0.0, 0.0, 0.0, 0.0])
    t = ruckig_duration(40.0, CFG["HomeVelDeg"], CFG["MaxAccDeg"], CFG["MaxJerkDeg"])
    assert (n - 2) * CYCLE < t + 1e-9 and t <= (n - 1) * CYCLE + 1e-9
    assert m.fb.Out1["Homed"]
    print(f"\nAMC_MoveAbsolute / ruckig duration: {min(ratios):.4f} .. {max(ratios):.4f}")
    cycles = pyplcopen_cycles(MOVES)
    if cycles is not None:
        for (p, v, a, j), c in zip(MOVES, cycles, strict=True):
            t = ruckig_duration(p, v, a, j)
            print(f"move {p:6.1f} deg: ruckig {t / CYCLE:7.2f} cycles, AMC "
                  f"{math.ceil(t / CYCLE - 1e-9):4d}, pyplcopen {c:4d} ({c * CYCLE / t:.3f})")
            assert c >= math.ceil(t / CYCLE - 1e-9) - 1  # nothing beats time-optimal


@pytest.mark.skipif(not os.environ.get("PYPLCOPEN_PYTHON"),
                    reason="PYPLCOPEN_PYTHON not set: a Python with pyplcopen (PyPI) installed")
def test_pyplcopen_is_reached() -> None:
    assert pyplcopen_cycles(MOVES[:1]) is not None


# ------------------------------------------------------------------------ range ends
@pytest.mark.parametrize(("velocity", "direction", "acc", "start"),
                         [(120.0, 1, 600.0, 0.0), (80.0, -1, 50.0, 10.0), (5.0, 1, 800.0, 85.0),
                          (120.0, -1, 800.0, -60.0)])
def test_velocity_move_stops_inside_the_range(bench_module: Any, velocity: float,
                                              direction: int, acc: float, start: float) -> None:
    m = Machine(bench_module)
    m.set_block(0, POWER, True)
    m.scan()
    scans_to_done(m, 0, ABS_A, [start, 120.0, 600.0, 600.0, 6000.0])
    m.set_block(0, VEL, True, ([velocity, acc, acc, 6000.0, 0.0], direction))
    lo, hi = CFG["MinPosDeg"], CFG["MaxPosDeg"]
    for _ in range(3000):
        m.scan()
        pos = m.fb.Out1["SetPosDeg"]
        assert lo <= pos <= hi, pos
        if m.fb.Out1["State"] == ERRORSTOP and abs(m.fb.Out1["SetVelDeg"]) < 1e-12:
            break
    assert m.fb.Out1["State"] == ERRORSTOP and m.fb.Out1["AxisErrorId"] == 10
    slot = VEL - 1
    assert m.fb.Err[slot] and m.fb.ErrId[slot] == 10
    m.set_block(0, VEL, False)
    m.set_block(0, RESET, True)
    m.scan()
    m.scan()
    assert m.fb.Out1["State"] == STANDSTILL and m.fb.Done[RESET - 1]
    for _ in range(20):
        m.scan()
        assert lo <= m.fb.Out1["SetPosDeg"] <= hi


def test_repo_st_layer_files_exist() -> None:
    st_dir = Path(__file__).resolve().parents[2] / "st"
    assert {"AMCTypes.st", "AMCAxisDrive.st", "AMCAxisMove.st", "AMCAxisAdmin.st"} <= {
        p.name for p in st_dir.glob("AMC*.st")}
