"""docs/motion.md's time-optimal jerk-limited theory, its two figures and Lab 6's question 5
against the `ruckig` package (a dev dependency: missing, this file fails) and closed forms.

* The figures come from armbench.plots.motion.compare_profiles, which runs MotionJointMove
  (trapezoid, quintic) and MotionJerkGenerator scan by scan: their durations and every sample
  of their curves are compared with Ruckig's trajectory of the same move and with the closed
  forms of the trapezoid and the quintic.
* The four rest-to-rest cases of motion.md (which phases exist, the duration) are checked
  against Ruckig's phase times over limits and distances that cover every case.
* The numbers the pages print -- motion.md's duration table, blocked interval and
  synchronisation example, the teacher's guide's key to Lab 6 Q5 -- are compared with Ruckig's
  and the closed forms to the digits printed (and the ST planner is asked the same).
"""

from __future__ import annotations

import glob
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import ruckig

from armbench.compiler import compile_files
from armbench.plots.motion import (
    FINE_DT,
    JERK_LIMITS,
    JERK_MOVE,
    MOVING_MOVE,
    MOVING_START,
    ProfileTrace,
    compare_profiles,
)

REPO = Path(__file__).resolve().parents[2]
MOTION = (REPO / "docs" / "motion.md").read_text(encoding="utf-8")
GUIDE = (REPO / "docs" / "teachers-guide.md").read_text(encoding="utf-8")
V, A, J = JERK_LIMITS


@pytest.fixture(scope="module")
def module() -> Any:
    return compile_files(sorted(glob.glob(str(REPO / "st" / "*.st"))))


# ----------------------------------------------------------------------------- references

def reference(p0: Sequence[float], v0: Sequence[float], a0: Sequence[float],
              pf: Sequence[float], vf: Sequence[float] | None = None,
              synchronization: str = "Time",
              minimum_duration: float | None = None) -> Any:
    """Ruckig's offline trajectory (Ruckig.calculate) with the pages' limits on every axis."""
    n = len(p0)
    otg = ruckig.Ruckig(n)
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.current_velocity = list(p0), list(v0)
    inp.current_acceleration, inp.target_position = list(a0), list(pf)
    inp.target_velocity = list(vf) if vf is not None else [0.0] * n
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [V] * n, [A] * n, [J] * n
    inp.synchronization = getattr(ruckig.Synchronization, synchronization)
    if minimum_duration is not None:
        inp.minimum_duration = minimum_duration
    traj = ruckig.Trajectory(n)
    assert otg.calculate(inp, traj) == ruckig.Result.Working
    return traj


def ruckig_jerk(profile: Any, t: float) -> float:
    """The jerk of a Ruckig profile (no brake) at time t; NaN at a phase boundary."""
    edges = np.cumsum(profile.t)
    if np.min(np.abs(edges - t)) < 1e-9:
        return math.nan
    k = int(np.searchsorted(edges, t))
    return float(profile.j[k]) if k < 7 else 0.0


def trapezoid_rest(d: float, v0: float, t: float) -> float:
    """The textbook trapezoid from v0 (towards the target) to rest: position at t."""
    t1 = (V - v0) / A
    d1 = (V * V - v0 * v0) / (2 * A)
    t2 = (d - d1 - V * V / (2 * A)) / V
    total = t1 + t2 + V / A
    if t <= t1:
        return v0 * t + A * t * t / 2
    if t <= t1 + t2:
        return d1 + V * (t - t1)
    if t <= total:
        return d - A * (total - t) ** 2 / 2
    return d


def quintic(d: float, v0: float, T: float, t: float) -> tuple[float, float]:
    """motion.md's quintic D h(tau) + V0 T g(tau): position and jerk at t."""
    if t >= T:
        return d, 0.0
    tau = t / T
    h = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    g = tau - 6 * tau**3 + 8 * tau**4 - 3 * tau**5
    h3 = 60 - 360 * tau + 360 * tau**2
    g3 = -36 + 192 * tau - 180 * tau**2
    return d * h + v0 * T * g, d * h3 / T**3 + v0 * g3 / T**2


def quintic_min_time(d: float) -> float:
    return max(15 * d / (8 * V), math.sqrt(10 * d / (math.sqrt(3) * A)), math.cbrt(60 * d / J))


@dataclass(frozen=True)
class RestCase:
    """One row of motion.md's table of the rest-to-rest cases: its cells as printed, and the
    same condition and duration in Python (the test checks both the cells and the Python)."""

    label: str  # the first cell
    phases: frozenset[int]
    when_tex: str
    duration_tex: str
    when: Callable[[float, float, float, float], bool]
    duration: Callable[[float, float, float, float], float]


def _reach(v: float, a: float, j: float) -> float:
    """The distance of the two ramps to v with both plateaus: where the cruise begins."""
    return v * (v / a + a / j)


REST_CASES = (
    RestCase("all seven", frozenset(range(1, 8)),
             r"$v_{\max} \ge a_{\max}^2/j_{\max}$ and "
             r"$D \ge v_{\max}\left(\frac{v_{\max}}{a_{\max}} + \frac{a_{\max}}{j_{\max}}\right)$",
             r"$\frac{D}{v_{\max}} + \frac{v_{\max}}{a_{\max}} + \frac{a_{\max}}{j_{\max}}$",
             lambda d, v, a, j: v >= a * a / j and d >= _reach(v, a, j),
             lambda d, v, a, j: d / v + v / a + a / j),
    RestCase("no plateau: 1, 3, 4, 5, 7", frozenset({1, 3, 4, 5, 7}),
             r"$v_{\max} < a_{\max}^2/j_{\max}$ and $D \ge 2 v_{\max}\sqrt{v_{\max}/j_{\max}}$",
             r"$\frac{D}{v_{\max}} + 2\sqrt{\frac{v_{\max}}{j_{\max}}}$",
             lambda d, v, a, j: v < a * a / j and d >= 2 * v * math.sqrt(v / j),
             lambda d, v, a, j: d / v + 2 * math.sqrt(v / j)),
    RestCase("no cruise: 1, 2, 3, 5, 6, 7", frozenset({1, 2, 3, 5, 6, 7}),
             r"$2a_{\max}^3/j_{\max}^2 \le D < v_{\max}\left(\frac{v_{\max}}{a_{\max}} + "
             r"\frac{a_{\max}}{j_{\max}}\right)$",
             r"$\frac{a_{\max}}{j_{\max}} + \sqrt{\frac{a_{\max}^2}{j_{\max}^2} + "
             r"\frac{4D}{a_{\max}}}$",
             lambda d, v, a, j: 2 * a**3 / j**2 <= d < _reach(v, a, j),
             lambda d, v, a, j: a / j + math.sqrt(a * a / (j * j) + 4 * d / a)),
    RestCase("neither: 1, 3, 5, 7", frozenset({1, 3, 5, 7}),
             r"$D < 2a_{\max}^3/j_{\max}^2$ and $D < 2 v_{\max}\sqrt{v_{\max}/j_{\max}}$",
             r"$\sqrt[3]{32 D/j_{\max}}$",
             lambda d, v, a, j: d < 2 * a**3 / j**2 and d < 2 * v * math.sqrt(v / j),
             lambda d, v, a, j: math.cbrt(32 * d / j)),
)


def rest_case(d: float, v: float, a: float, j: float) -> tuple[set[int], float]:
    """The one case of REST_CASES whose condition holds: its phases and duration."""
    hits = [c for c in REST_CASES if c.when(d, v, a, j)]
    assert len(hits) == 1, (d, v, a, j, [c.label for c in hits])
    return set(hits[0].phases), hits[0].duration(d, v, a, j)


def test_the_case_table_is_the_one_checked_here() -> None:
    for case in REST_CASES:
        assert table_row(MOTION, case.label)[1:] == [case.when_tex, case.duration_tex], \
            case.label


# ----------------------------------------------------------------------------- printed numbers

def table_row(text: str, first_cell: str) -> list[str]:
    """The cells of the Markdown table row whose first cell is `first_cell`."""
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] == first_cell:
            return cells
    raise AssertionError(f"no table row {first_cell!r}")


def printed(text: str, unit: str = " s") -> list[tuple[float, int]]:
    """The numbers followed by `unit` in `text`, with their count of decimals."""
    out = []
    for m in re.finditer(r"(−?\d+(?:\.(\d+))?)" + re.escape(unit), text):
        out.append((float(m.group(1).replace("−", "-")), len(m.group(2) or "")))
    return out


def shows(numbers: list[tuple[float, int]], value: float) -> bool:
    """`value` is one of the printed numbers, to its printed digits."""
    return any(abs(x - value) <= 0.5 * 10.0**-dec + 1e-12 for x, dec in numbers)


def test_printed_number_reader() -> None:
    row = table_row("| a | b |\n| 5° | 0.161 s and 2.8125 s, −7.6 °/s |\n", "5°")
    assert printed(row[1]) == [(0.161, 3), (2.8125, 4)]
    assert printed(row[1], " °/s") == [(-7.6, 1)]
    assert shows(printed(row[1]), 0.16091) and not shows(printed(row[1]), 0.1616)
    assert shows(printed(row[1]), 2.8125) and not shows(printed(row[1]), 2.812)


# ----------------------------------------------------------------------------- the figures

def _check_jerk_limited(trace: ProfileTrace, ref: Any, dist: float) -> None:
    assert trace.duration == pytest.approx(ref.duration, rel=1e-12)
    prof = ref.profiles[0][0]
    for k, t in enumerate(trace.t):
        p, v, a = (x[0] for x in ref.at_time(float(t)))
        assert trace.q[k] == pytest.approx(p, abs=1e-9 * dist)
        assert trace.qd[k] == pytest.approx(v, abs=1e-9 * V)
        assert trace.qdd[k] == pytest.approx(a, abs=1e-9 * A)
        if k > 0 and not math.isnan(jerk := ruckig_jerk(prof, float(t))):
            assert trace.qddd[k] == jerk, t
    # continuous acceleration: never more than j dt per scan
    assert np.max(np.abs(np.diff(trace.qdd))) <= J * FINE_DT * (1 + 1e-9)


def test_rest_to_rest_figure_is_ruckig_and_the_closed_forms(module: Any) -> None:
    trapezoid, quint, jerk = compare_profiles(module, JERK_MOVE)
    d = JERK_MOVE
    assert trapezoid.duration == pytest.approx(d / V + V / A, rel=1e-6)  # REAL blocks
    assert quint.duration == pytest.approx(quintic_min_time(d), rel=1e-6)
    assert jerk.duration == pytest.approx(d / V + V / A + A / J, rel=1e-12)
    _check_jerk_limited(jerk, reference([0.0], [0.0], [0.0], [d]), d)
    # the blocks are REAL: their time (scans times a float32 CycleTime) and the quintic's
    # polynomial are rounded to float32, a few ulps of the move's size in all
    tol = 2.0**-23 * 16 * d
    for k, t in enumerate(trapezoid.t):
        assert trapezoid.q[k] == pytest.approx(trapezoid_rest(d, 0.0, float(t)), abs=tol)
        p, _ = quintic(d, 0.0, quint.duration, float(t))
        assert quint.q[k] == pytest.approx(p, abs=tol)
    # the quintic's jerk panel (its acceleration's change per scan) is its third derivative
    mid = (quint.t > FINE_DT) & (quint.t < quint.duration - FINE_DT)
    exact = [quintic(d, 0.0, quint.duration, float(t) - FINE_DT / 2)[1] for t in quint.t[mid]]
    assert np.max(np.abs(quint.qddd[mid] - exact)) < 0.01 * 60 * d / quint.duration**3
    # its peaks are below a and j (motion.md: it reaches neither anywhere)
    assert np.max(np.abs(quint.qdd)) < 0.6 * A and np.max(np.abs(quint.qddd)) < 0.5 * J
    # the trapezoid's steps of acceleration leave the jerk panel's scale (1.6 j)
    assert np.max(np.abs(trapezoid.qddd)) > 100 * J


def test_moving_start_figure_is_ruckig_and_the_closed_forms(module: Any) -> None:
    v0, a0 = MOVING_START
    d = MOVING_MOVE
    trapezoid, quint, jerk = compare_profiles(module, d, v0, a0)
    _check_jerk_limited(jerk, reference([0.0], [v0], [a0], [d]), d)
    t_trap = (V - v0) / A + V / A + (d - (V * V - v0 * v0) / (2 * A) - V * V / (2 * A)) / V
    assert trapezoid.duration == pytest.approx(t_trap, rel=1e-6)
    # the quintic from v0 fits the limits at its rest-to-rest minimum: no stretch here
    assert quint.duration == pytest.approx(quintic_min_time(d), rel=1e-6)
    tol = 2.0**-23 * 16 * d  # REAL blocks, as above
    for k, t in enumerate(quint.t):
        assert trapezoid.q[k] == pytest.approx(trapezoid_rest(d, v0, float(t)), abs=tol)
        assert quint.q[k] == pytest.approx(quintic(d, v0, quint.duration, float(t))[0], abs=tol)
    assert np.max(np.abs(quint.qd)) <= V and np.max(np.abs(quint.qdd)) <= A
    # both start from v0 and drop a0 in the first scan: a step of acceleration
    assert trapezoid.qdd[1] == pytest.approx(A) and abs(quint.qdd[1]) < 0.02 * a0
    assert jerk.qdd[1] == pytest.approx(a0 + J * FINE_DT, rel=1e-12)


def test_the_duration_table_is_what_the_figures_show(module: Any) -> None:
    rows = {"90° from rest to rest": compare_profiles(module, JERK_MOVE),
            "60° from 40 °/s and 100 °/s² to rest": compare_profiles(module, MOVING_MOVE,
                                                                    *MOVING_START)}
    for first, traces in rows.items():
        cells = table_row(MOTION, first)
        best = traces[2].duration
        for cell, trace in zip(cells[1:], traces, strict=True):
            assert shows(printed(cell), trace.duration), (cell, trace.duration)
            if trace is not traces[2]:
                assert shows(printed(cell, "×)"), trace.duration / best), cell
    phases = list(reference([0.0], [0.0], [0.0], [JERK_MOVE]).profiles[0][0].t)
    said = ", ".join(f"{x:g}" for x in phases[:6]) + f" and {phases[6]:g} s"
    assert said in " ".join(MOTION.split()), said


# ----------------------------------------------------------------------------- the four cases

LIMIT_SETS = [(60.0, 120.0, 600.0), (10.0, 200.0, 1000.0), (100.0, 50.0, 5000.0),
              (1.0, 3.0, 2.0)]


@pytest.mark.parametrize("limits", LIMIT_SETS, ids=lambda lim: "v{}-a{}-j{}".format(*lim))
def test_the_four_rest_cases_are_ruckigs(module: Any, limits: tuple[float, float, float]) -> None:
    """motion.md's table: for distances from far below to far above both borders, the phases
    Ruckig uses and its duration are the table's (phases 3 and 5 of the last case as one)."""
    v, a, j = limits
    scale = v * (v / a + a / j)
    seen = set()
    for d in scale * np.geomspace(1e-6, 30.0, 61):
        phases, duration = rest_case(float(d), v, a, j)
        seen.add(frozenset(phases))
        otg, inp, traj = ruckig.Ruckig(1), ruckig.InputParameter(1), ruckig.Trajectory(1)
        inp.current_position, inp.target_position = [0.0], [float(d)]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
        assert otg.calculate(inp, traj) == ruckig.Result.Working
        assert traj.duration == pytest.approx(duration, rel=1e-9), d
        t = list(traj.profiles[0][0].t)
        used = {k + 1 for k, x in enumerate(t) if x > 1e-9 * duration}
        if phases == {1, 3, 5, 7} and 5 not in used:
            assert t[2] == pytest.approx(t[0] + t[6], rel=1e-9)  # 3 and 5 stored as one
            used.add(5)
        assert used == phases, (d, t)
    expected = {frozenset({1, 3, 5, 7}),
                frozenset(range(1, 8) if v >= a * a / j else {1, 3, 4, 5, 7})}
    assert expected <= seen


def test_the_borders_of_the_labs_limits_are_ruckigs() -> None:
    """Lab 6 Q5: with 60 deg/s, 120 deg/s^2, 600 deg/s^3 the plateaus appear at 9.6 deg and
    the cruise at 42 deg."""
    def times(d: float) -> list[float]:
        return list(reference([0.0], [0.0], [0.0], [d]).profiles[0][0].t)

    assert times(9.6 * (1 - 1e-6))[1] == 0.0 and times(9.6 * (1 + 1e-3))[1] > 1e-6
    assert times(42.0 * (1 - 1e-3))[3] == 0.0 and times(42.0 * (1 + 1e-3))[3] > 1e-6
    assert A * A / J < V
    assert "$D \\ge 2a_{\\max}^3/j_{\\max}^2$ = **9.6°**" in GUIDE
    assert "= **42°**" in GUIDE


def test_the_q5_key_is_ruckigs_and_the_closed_forms() -> None:
    for dist in (5.0, 20.0, 90.0):
        cells = table_row(GUIDE, f"{dist:g}°")
        traj = reference([0.0], [0.0], [0.0], [dist])
        t = list(traj.profiles[0][0].t)
        numbers = printed(" ".join(cells))
        phases, duration = rest_case(dist, V, A, J)
        assert traj.duration == pytest.approx(duration, rel=1e-12)
        assert shows(numbers, traj.duration), (dist, traj.duration)
        trap = 2 * math.sqrt(dist / A) if dist < V * V / A else dist / V + V / A
        assert shows(numbers, trap) and shows(numbers, quintic_min_time(dist)), dist
        head = cells[1].split(":")[0]
        listed = set(range(1, 8)) if head == "all seven" else {int(x) for x in head.split(",")}
        assert listed == phases, cells[1]
        candidates = {"velocity": 15 * dist / (8 * V),
                      "acceleration": math.sqrt(10 * dist / (math.sqrt(3) * A)),
                      "jerk": (60 * dist / J) ** (1 / 3)}
        assert cells[4].endswith(f"({max(candidates, key=lambda k: candidates[k])})"), cells[4]
        if dist == 5.0:  # the slopes of tau, and phases 3 and 5 as one phase of 2 tau
            assert t[2] == pytest.approx(2 * t[0]) and shows(numbers, t[0])
            assert shows(numbers, t[2])
        elif dist == 20.0:  # the plateaus, and the peak velocity in the middle
            assert shows(numbers, t[1])
            peak = traj.at_time(traj.duration / 2)[1][0]
            assert shows(printed(cells[1], " °/s"), peak)
        else:
            assert cells[1] == "all seven: " + ", ".join(f"{x:g}" for x in t) + " s"


# ----------------------------------------------------------------------------- synchronisation

def _plan(module: Any, p0: list[float], v0: list[float], pf: list[float], vf: list[float],
          sync: int) -> Any:
    n = len(p0)
    pad = [0.0] * (6 - n)
    planner = module.new_fb("MotionJerkPlanner")
    planner(Joints=n, Sync=sync, CurrentPos=p0 + pad, CurrentVel=v0 + pad,
            CurrentAcc=[0.0] * 6, TargetPos=pf + pad, TargetVel=vf + pad, TargetAcc=[0.0] * 6,
            Limits=[{"MaxVel": V, "MaxAcc": A, "MaxJerk": J}] * 6)
    assert planner.Valid, planner.ErrorId
    return planner


def test_the_blocked_interval_example(module: Any) -> None:
    """A joint cruising at 60 deg/s to a target 40 deg on, still at 60 deg/s."""
    cruising = _plan(module, [0.0], [V], [40.0], [V], 0)
    block = cruising.Blocks[0]
    assert block["HasA"] and not block["HasB"]
    t_min, left, right = cruising.Duration, block["ALeft"], block["ARight"]
    ref = reference([0.0], [V], [0.0], [40.0], [V])
    assert t_min == pytest.approx(ref.duration, rel=1e-12) == pytest.approx(40.0 / V)
    # Ruckig asked for a duration inside the interval answers its right end; at its left end
    # and beyond its right end it takes the duration asked for
    for inside in (left + 1e-6, (left + right) / 2, right - 1e-6):
        got = reference([0.0], [V], [0.0], [40.0], [V], minimum_duration=inside)
        assert got.duration == pytest.approx(right, rel=1e-9), inside
    for outside in (left, right + 0.1):
        got = reference([0.0], [V], [0.0], [40.0], [V], minimum_duration=outside)
        assert got.duration == pytest.approx(outside, rel=1e-12), outside

    def lowest_velocity(duration: float) -> float:
        got = reference([0.0], [V], [0.0], [40.0], [V], minimum_duration=duration)
        return float(min(got.at_time(float(t))[1][0]
                         for t in np.linspace(0.0, duration, 4001)))

    page = printed(MOTION, " °/s")
    for value in (lowest_velocity(left), lowest_velocity(right)):
        assert shows(page, value), value
    # with a second joint of 20 deg from rest, the common duration is the interval's end
    pair = _plan(module, [0.0, 0.0], [0.0, V], [20.0, 40.0], [0.0, V], 0)
    ref2 = reference([0.0, 0.0], [0.0, V], [0.0, 0.0], [20.0, 40.0], [0.0, V])
    assert pair.Duration == pytest.approx(right, rel=1e-12)
    assert ref2.duration == pytest.approx(right, rel=1e-12)
    assert left < ref2.independent_min_durations[0] < right
    for value, text in ((t_min, "**{:.3f} s**"), (left, "**{:.3f} s**"),
                        (right, "**{:.3f} s**"),
                        (ref2.independent_min_durations[0], "({:.3f} s alone)")):
        assert text.format(value) in MOTION, text.format(value)


def test_the_synchronisation_table(module: Any) -> None:
    """90 deg and 30 deg from rest: joint 2 time- and phase-synchronised, the ST and Ruckig."""
    cells = {name: table_row(MOTION, name) for name in (
        "phase durations, s", "jerk, °/s³", "peak velocity, °/s", "peak acceleration, °/s²")}
    for sync, column in ((0, 2), (1, 3)):
        plan = _plan(module, [0.0, 0.0], [0.0, 0.0], [90.0, 30.0], [0.0, 0.0], sync)
        ref = reference([0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [90.0, 30.0],
                        synchronization="Time" if sync == 0 else "Phase")
        assert plan.Duration == pytest.approx(2.2, rel=1e-12)
        assert ref.duration == pytest.approx(2.2, rel=1e-12)
        for k in range(2):
            got = plan.Profiles[k]
            want = ref.profiles[0][k]
            assert got["T"] == pytest.approx(list(want.t), abs=1e-12)
            assert got["J"] == pytest.approx(list(want.j), abs=1e-9)
        joint2 = plan.Profiles[1]
        shown = re.findall(r"\d+(?:\.\d+)?", cells["phase durations, s"][column])
        assert len(shown) == 7
        for x, t in zip(shown, joint2["T"], strict=True):
            dec = len(x.split(".")[1]) if "." in x else 1  # a bare 0 is a phase of no time
            assert abs(float(x) - t) <= 0.5 * 10.0**-dec + 1e-12, (x, t)
        jerk = max(abs(x) for x in joint2["J"])
        assert cells["jerk, °/s³"][column] == f"±{jerk:.0f}"
        assert jerk == pytest.approx(J * (30.0 / 90.0) if sync == 1 else J)
        # the exact peaks: the velocity at the cruise, the acceleration at the knots
        for name, values in (("peak velocity, °/s", joint2["V"]),
                             ("peak acceleration, °/s²", joint2["A"])):
            peak = max(abs(x) for x in values)
            cell = cells[name][column]
            dec = len(cell.split(".")[1]) if "." in cell else 0
            assert abs(float(cell) - peak) <= 0.5 * 10.0**-dec + 1e-9, (name, cell, peak)
