"""MotionJerkGenerator (st/MotionJerkOnline.st): the per-scan generator against Ruckig's online
update (Ruckig.update with the output passed back as the next input), scan by scan.

Scenarios: targets that change mid-move (some every scan, as when following), jog with the
velocity interface, separate minimum limits; the setpoints must equal Ruckig's within 1e-9
(relative to the move) at every scan, and be continuous: between two scans the velocity
changes by at most the acceleration limit times the cycle and the acceleration by at most
the jerk limit times the cycle, re-plans included. Bad input mid-move (NaN, a target beyond
the limits, a zero limit, a bad cycle time) gives the documented ErrorId while the setpoints
carry on exactly along the last valid trajectory, never NaN; good input plans again from
there. The error clears when the inputs are plannable again, also when they come back to
the values they had (a cycle time, a limit or a target that was NaN, Inf, 0 or negative for a
few scans), moving and at rest: a bad cycle time stops the trajectory's time while it lasts,
a plan's own error outlasts it, and a valid cycle time changed mid-move keeps to the same
trajectory within the limits per cycle.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Any

import pytest

ruckig = pytest.importorskip("ruckig")

DT = 0.01


def vec(values: list[float]) -> list[float]:
    return list(values) + [0.0] * (6 - len(values))


@dataclass
class Scenario:
    limits: list[dict[str, Any]]
    start: list[float]
    # scan -> (target position, target velocity); the last one set stays
    targets: dict[int, tuple[list[float], list[float]]]
    scans: int
    velocity_mode: bool = False


def _limits(rng: random.Random, n: int, separate: bool) -> list[dict[str, Any]]:
    out = []
    for _ in range(n):
        lim: dict[str, Any] = {"MaxVel": rng.uniform(0.3, 3.0), "MaxAcc": rng.uniform(0.5, 8.0),
                               "MaxJerk": rng.uniform(2.0, 60.0)}
        if separate:
            lim.update(SeparateMin=True, MinVel=-lim["MaxVel"] * rng.uniform(0.3, 1.5),
                       MinAcc=-lim["MaxAcc"] * rng.uniform(0.3, 1.5))
        out.append(lim)
    return out


def scenario(seed: int, velocity_mode: bool = False, separate: bool = False) -> Scenario:
    rng = random.Random(seed)
    n = 3
    lim = _limits(rng, n, separate)
    targets: dict[int, tuple[list[float], list[float]]] = {}
    scan = 0
    while scan < 600:
        if velocity_mode:
            tv = [rng.uniform(-0.9, 0.9) * lim[k]["MaxVel"] for k in range(n)]
            targets[scan] = ([0.0] * n, tv)
            scan += rng.randrange(5, 120)
        elif rng.random() < 0.15:
            # following: a target moving a little every scan for a while
            base = [rng.uniform(-2.0, 2.0) for _ in range(n)]
            for j in range(rng.randrange(10, 60)):
                targets[scan + j] = ([b + 0.01 * j for b in base], [0.0] * n)
            scan += 60
        else:
            tv = [rng.choice((0.0, rng.uniform(-0.5, 0.5) * lim[k]["MaxVel"])) for k in range(n)]
            targets[scan] = ([rng.uniform(-2.0, 2.0) for _ in range(n)], tv)
            scan += rng.randrange(1, 150)
    return Scenario(lim, [rng.uniform(-1.0, 1.0) for _ in range(n)], targets, 700,
                    velocity_mode)


class RuckigOnline:
    def __init__(self, sc: Scenario) -> None:
        n = len(sc.start)
        self.otg = ruckig.Ruckig(n, DT)
        self.inp = ruckig.InputParameter(n)
        self.out = ruckig.OutputParameter(n)
        inp = self.inp
        inp.current_position = list(sc.start)
        inp.current_velocity = [0.0] * n
        inp.current_acceleration = [0.0] * n
        inp.max_velocity = [lim["MaxVel"] for lim in sc.limits]
        inp.max_acceleration = [lim["MaxAcc"] for lim in sc.limits]
        inp.max_jerk = [lim["MaxJerk"] for lim in sc.limits]
        if sc.limits[0].get("SeparateMin"):
            inp.min_velocity = [lim["MinVel"] for lim in sc.limits]
            inp.min_acceleration = [lim["MinAcc"] for lim in sc.limits]
        if sc.velocity_mode:
            inp.control_interface = ruckig.ControlInterface.Velocity

    def step(self, pos: list[float], vel: list[float]) -> tuple[list[float], list[float],
                                                                 list[float]]:
        self.inp.target_position = pos
        self.inp.target_velocity = vel
        self.otg.update(self.inp, self.out)
        self.out.pass_to_input(self.inp)
        return (list(self.out.new_position), list(self.out.new_velocity),
                list(self.out.new_acceleration))


def gen_call(gen: Any, sc: Scenario, pos: list[float], vel: list[float], **over: Any) -> Any:
    n = len(sc.start)
    lims = sc.limits + [{"MaxVel": 1.0, "MaxAcc": 1.0, "MaxJerk": 1.0}] * (6 - n)
    args: dict[str, Any] = dict(Enable=True, CycleTime=DT, Joints=n,
                                VelocityMode=sc.velocity_mode, Sync=0, TargetPos=vec(pos),
                                TargetVel=vec(vel), TargetAcc=vec([]), Limits=lims,
                                StartPos=vec(sc.start), StartVel=vec([]), StartAcc=vec([]))
    args.update(over)
    gen(**args)
    return gen


def run_both(st_module: Any, sc: Scenario) -> tuple[float, int]:
    """Both generators through the scenario; returns the largest setpoint difference and
    the number of re-plans."""
    gen = st_module.new_fb("MotionJerkGenerator")
    ref = RuckigOnline(sc)
    n = len(sc.start)
    pos, vel = sc.targets[0]
    worst = 0.0
    plans = 0
    prev: tuple[list[float], list[float]] | None = None
    for k in range(sc.scans):
        if k in sc.targets:
            pos, vel = sc.targets[k]
        p_ref, v_ref, a_ref = ref.step(pos, vel)
        gen_call(gen, sc, pos, vel)
        assert not gen.Error, (k, gen.ErrorId)
        plans += gen.NewPlan
        for j in range(n):
            worst = max(worst, abs(gen.Position[j] - p_ref[j]), abs(gen.Velocity[j] - v_ref[j]),
                        abs(gen.Acceleration[j] - a_ref[j]))
        # continuity, re-plans included
        if prev is not None:
            for j in range(n):
                lim = sc.limits[j]
                a_lo = lim.get("MinAcc", -lim["MaxAcc"])
                dv = gen.Velocity[j] - prev[0][j]
                da = gen.Acceleration[j] - prev[1][j]
                assert a_lo * DT * (1 + 1e-9) - 1e-12 <= dv <= lim["MaxAcc"] * DT * (1 + 1e-9) \
                    + 1e-12, (k, j, dv)
                assert abs(da) <= lim["MaxJerk"] * DT * (1 + 1e-9) + 1e-12, (k, j, da)
        prev = (list(gen.Velocity[:n]), list(gen.Acceleration[:n]))
    return worst, plans


@pytest.mark.parametrize("seed", range(4))
def test_changing_targets_equal_ruckig_update(st_module: Any, seed: int) -> None:
    worst, plans = run_both(st_module, scenario(seed))
    print(f"seed {seed}: {plans} re-plans, worst |setpoint - Ruckig's| {worst:.2e}")
    assert plans >= 5
    assert worst < 1e-9


@pytest.mark.parametrize("seed", range(2))
def test_jog_equals_ruckig_update(st_module: Any, seed: int) -> None:
    worst, plans = run_both(st_module, scenario(100 + seed, velocity_mode=True))
    assert plans >= 5
    assert worst < 1e-9


def test_separate_minimum_limits_equal_ruckig_update(st_module: Any) -> None:
    worst, plans = run_both(st_module, scenario(200, separate=True))
    assert plans >= 5
    assert worst < 1e-9


@pytest.mark.parametrize(("bad", "code"), [
    ({"TargetPos": [math.nan, 0.0, 0.0]}, 8),
    ({"TargetVel": [5.0, 0.0, 0.0]}, 26),                  # beyond MaxVel 1.0
    ({"Limits": [{"MaxVel": 0.0, "MaxAcc": 2.0, "MaxJerk": 10.0}]}, 8),
    ({"Limits": [{"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": math.inf}]}, 8),
    ({"Sync": 9}, 8),
])
def test_bad_input_mid_move_keeps_the_last_trajectory(st_module: Any, bad: dict[str, Any],
                                                       code: int) -> None:
    lims = [{"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": 10.0}] * 3
    sc = Scenario(lims, [0.0, 0.5, -0.5], {}, 0)
    good_pos, good_vel = [1.5, -1.0, 0.3], [0.0, 0.0, 0.0]
    clean = st_module.new_fb("MotionJerkGenerator")
    gen = st_module.new_fb("MotionJerkGenerator")
    for _ in range(40):
        gen_call(clean, sc, good_pos, good_vel)
        gen_call(gen, sc, good_pos, good_vel)
    over = dict(bad)
    if "Limits" in over:
        over["Limits"] = over["Limits"] * 3 + [{"MaxVel": 1.0, "MaxAcc": 1.0, "MaxJerk": 1.0}] * 3
    pos = over.pop("TargetPos", good_pos)
    vel = over.pop("TargetVel", good_vel)
    for _ in range(30):
        gen_call(clean, sc, good_pos, good_vel)
        gen_call(gen, sc, pos, vel, **over)
        assert gen.Error and gen.ErrorId == code
        assert gen.Position == clean.Position and gen.Velocity == clean.Velocity
        assert gen.Acceleration == clean.Acceleration
        assert all(math.isfinite(x) for x in gen.Position + gen.Velocity + gen.Acceleration)
    # good input again: plans from where it is, continuously
    before_v, before_a = list(gen.Velocity), list(gen.Acceleration)
    gen_call(gen, sc, [0.0, 0.0, 0.0], good_vel)
    assert not gen.Error and gen.NewPlan
    for j in range(3):
        assert abs(gen.Velocity[j] - before_v[j]) <= 2.0 * DT * (1 + 1e-9)
        assert abs(gen.Acceleration[j] - before_a[j]) <= 10.0 * DT * (1 + 1e-9)


def test_bad_cycle_time_holds_the_setpoints(st_module: Any) -> None:
    lims = [{"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": 10.0}] * 3
    sc = Scenario(lims, [0.0, 0.0, 0.0], {}, 0)
    gen = st_module.new_fb("MotionJerkGenerator")
    for _ in range(20):
        gen_call(gen, sc, [1.0, 1.0, 1.0], [0.0] * 3)
    held = list(gen.Position)
    for cycle in (0.0, -0.01, math.nan, 11.0):
        gen_call(gen, sc, [1.0, 1.0, 1.0], [0.0] * 3, CycleTime=cycle)
        assert gen.Error and gen.ErrorId == 8 and gen.Position == held


def test_enable_takes_over_the_start_and_holds_when_disabled(st_module: Any) -> None:
    lims = [{"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": 10.0}] * 2
    sc = Scenario(lims, [0.3, -0.2], {}, 0)
    gen = st_module.new_fb("MotionJerkGenerator")
    gen_call(gen, sc, [0.3, -0.2], [0.0, 0.0], StartVel=vec([0.5, 0.0]))
    # moving start: the first scan continues the start velocity
    assert gen.Active and gen.NewPlan
    assert gen.Position[0] == pytest.approx(0.3 + 0.5 * DT, rel=1e-3)
    for _ in range(300):
        gen_call(gen, sc, [0.3, -0.2], [0.0, 0.0])
    assert gen.InTarget and not gen.Busy
    assert gen.Position[:2] == pytest.approx([0.3, -0.2], abs=1e-12)
    gen_call(gen, sc, [5.0, 5.0], [0.0, 0.0], Enable=False)
    assert not gen.Active and not gen.NewPlan and gen.Position[:2] == pytest.approx([0.3, -0.2])
    # a new rising edge with a bad start: refused, nothing put out
    gen_call(gen, sc, [1.0, 1.0], [0.0, 0.0], StartPos=vec([math.nan, 0.0]))
    assert gen.Error and gen.ErrorId == 8 and not gen.Active
    assert all(math.isfinite(x) for x in gen.Position)


# --- a bad input that becomes good again, with no other change -------------------------------

LIMS3 = [{"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": 10.0}] * 3
START3 = [0.0, 0.5, -0.5]
TARGET3 = [1.5, -1.0, 0.3]
ZERO3 = [0.0, 0.0, 0.0]
BAD_CYCLES = pytest.mark.parametrize("cycle", [math.nan, math.inf, -math.inf, 0.0],
                                     ids=["nan", "+inf", "-inf", "zero"])
# scans from the start: 40 is mid-move (the move takes about 2.3 s), 400 long after it ended
MOVING = pytest.mark.parametrize("scans", [40, 400], ids=["moving", "at-rest"])


def setpoints(gen: Any) -> tuple[Any, ...]:
    return (list(gen.Position), list(gen.Velocity), list(gen.Acceleration), list(gen.Jerk),
            gen.PlanTime, gen.Duration)


def two_generators(st_module: Any, scans: int) -> tuple[Scenario, Any, Any]:
    """Two generators driven alike for ``scans`` scans: one to disturb, one left alone."""
    sc = Scenario(LIMS3, START3, {}, 0)
    clean = st_module.new_fb("MotionJerkGenerator")
    gen = st_module.new_fb("MotionJerkGenerator")
    for _ in range(scans):
        gen_call(clean, sc, TARGET3, ZERO3)
        gen_call(gen, sc, TARGET3, ZERO3)
    assert gen.Busy == (scans < 200) and gen.InTarget == (scans >= 200) and not gen.Error
    return sc, clean, gen


@BAD_CYCLES
@MOVING
def test_bad_cycle_time_error_clears_when_the_cycle_time_is_valid_again(
        st_module: Any, cycle: float, scans: int) -> None:
    """The documented promise: the error clears when the inputs are plannable again. A bad
    CycleTime stops the trajectory's time (the setpoints hold); the first scan with a valid
    one clears the error and carries on from where the time stood, on the same trajectory."""
    sc, clean, gen = two_generators(st_module, scans)
    held = setpoints(gen)
    for _ in range(5):
        gen_call(gen, sc, TARGET3, ZERO3, CycleTime=cycle)
        assert gen.Error and gen.ErrorId == 8 and not gen.InTarget and gen.Active
        assert setpoints(gen) == held
    for k in range(300):
        gen_call(clean, sc, TARGET3, ZERO3)
        gen_call(gen, sc, TARGET3, ZERO3)
        assert not gen.Error and gen.ErrorId == 0, k
        assert not gen.NewPlan, k
        assert setpoints(gen) == setpoints(clean), k
        assert (gen.Busy, gen.InTarget) == (clean.Busy, clean.InTarget), k
    assert gen.InTarget and gen.Position[:3] == pytest.approx(TARGET3, abs=1e-12)


@BAD_CYCLES
def test_bad_cycle_time_at_the_rising_edge_plans_once_it_is_valid(st_module: Any,
                                                                   cycle: float) -> None:
    """Re-enabled with the inputs of the last enable (so nothing "changed") and a bad
    CycleTime: the take-over of the start state must still be planned at the first valid
    CycleTime, exactly as a generator enabled then."""
    sc, _, gen = two_generators(st_module, 400)
    gen_call(gen, sc, TARGET3, ZERO3, Enable=False)
    start2 = vec([-0.4, 0.2, 1.0])
    gen_call(gen, sc, TARGET3, ZERO3, StartPos=start2, CycleTime=cycle)
    assert gen.Active and gen.Error and gen.ErrorId == 8 and not gen.InTarget
    assert gen.Position == start2
    fresh = st_module.new_fb("MotionJerkGenerator")
    for k in range(400):
        gen_call(fresh, sc, TARGET3, ZERO3, StartPos=start2)
        gen_call(gen, sc, TARGET3, ZERO3, StartPos=start2)
        assert not gen.Error and gen.ErrorId == 0, k
        assert gen.NewPlan == (k == 0), k
        assert setpoints(gen) == setpoints(fresh), k
    assert gen.InTarget


@MOVING
def test_a_plan_error_outlasts_a_bad_cycle_time(st_module: Any, scans: int) -> None:
    """An error of the planner (here 26, a target velocity beyond the limit) stays while its
    input does, through scans with a bad CycleTime (8), and clears with a plannable target."""
    sc, clean, gen = two_generators(st_module, scans)
    bad_vel = [5.0, 0.0, 0.0]
    for cycle in (DT, math.nan, 0.0, DT, DT):
        gen_call(gen, sc, TARGET3, bad_vel, CycleTime=cycle)
        assert gen.Error and gen.ErrorId == (26 if cycle == DT else 8), cycle
        assert not gen.InTarget
    gen_call(gen, sc, TARGET3, ZERO3)
    assert not gen.Error and gen.ErrorId == 0 and gen.NewPlan


@MOVING
def test_a_target_changed_under_a_bad_cycle_time_is_planned_when_it_is_valid(
        st_module: Any, scans: int) -> None:
    sc, _, gen = two_generators(st_module, scans)
    held = setpoints(gen)
    target2 = [-1.0, 0.0, 1.0]
    gen_call(gen, sc, target2, ZERO3, CycleTime=math.nan)
    assert gen.Error and gen.ErrorId == 8 and setpoints(gen) == held
    gen_call(gen, sc, target2, ZERO3, CycleTime=math.nan)
    before_v, before_a = list(gen.Velocity), list(gen.Acceleration)
    gen_call(gen, sc, target2, ZERO3)
    assert not gen.Error and gen.NewPlan
    for j in range(3):
        assert abs(gen.Velocity[j] - before_v[j]) <= 2.0 * DT * (1 + 1e-9)
        assert abs(gen.Acceleration[j] - before_a[j]) <= 10.0 * DT * (1 + 1e-9)
    for _ in range(400):
        gen_call(gen, sc, target2, ZERO3)
        assert not gen.Error
    assert gen.InTarget and gen.Position[:3] == pytest.approx(target2, abs=1e-12)


def _limits_with(axis0: dict[str, float]) -> list[dict[str, Any]]:
    return [axis0, *LIMS3[1:], *[{"MaxVel": 1.0, "MaxAcc": 1.0, "MaxJerk": 1.0}] * 3]


@pytest.mark.parametrize("bad", [
    {"Limits": _limits_with({"MaxVel": 1.0, "MaxAcc": math.nan, "MaxJerk": 10.0})},
    {"Limits": _limits_with({"MaxVel": 0.0, "MaxAcc": 2.0, "MaxJerk": 10.0})},
    {"Limits": _limits_with({"MaxVel": 1.0, "MaxAcc": 2.0, "MaxJerk": -10.0})},
    {"Limits": _limits_with({"MaxVel": -1.0, "MaxAcc": 2.0, "MaxJerk": 10.0})},
    {"TargetPos": vec([math.nan, -1.0, 0.3])},
    {"TargetPos": vec([1.5, -math.inf, 0.3])},
    {"TargetVel": vec([0.0, 0.0, math.nan])},
], ids=["MaxAcc-nan", "MaxVel-zero", "MaxJerk-negative", "MaxVel-negative", "TargetPos-nan",
        "TargetPos-inf", "TargetVel-nan"])
@MOVING
def test_other_bad_inputs_clear_when_restored(st_module: Any, bad: dict[str, Any],
                                              scans: int) -> None:
    """A limit or target that goes bad (NaN, Inf, 0, negative) for a few scans and comes back
    to its old value: 8 while it is bad, the setpoints following the last trajectory; then no
    error, a plan from the state it reached, continuous, and on to the same target."""
    sc, clean, gen = two_generators(st_module, scans)
    for k in range(5):
        gen_call(clean, sc, TARGET3, ZERO3)
        gen(**{**_inputs(sc), **bad})
        assert gen.Error and gen.ErrorId == 8 and not gen.InTarget, k
        assert setpoints(gen)[:4] == setpoints(clean)[:4], k
    prev = (list(gen.Velocity), list(gen.Acceleration))
    for k in range(400):
        gen_call(clean, sc, TARGET3, ZERO3)
        gen_call(gen, sc, TARGET3, ZERO3)
        assert not gen.Error and gen.ErrorId == 0, k
        assert gen.NewPlan == (k == 0), k
        for j in range(3):
            assert abs(gen.Velocity[j] - prev[0][j]) <= 2.0 * DT * (1 + 1e-9) + 1e-12, (k, j)
            assert abs(gen.Acceleration[j] - prev[1][j]) <= 10.0 * DT * (1 + 1e-9) + 1e-12, (k, j)
            # the re-plan from a state on the time-optimal trajectory to the same target is
            # the rest of that trajectory
            assert gen.Position[j] == pytest.approx(clean.Position[j], abs=1e-9), (k, j)
        prev = (list(gen.Velocity), list(gen.Acceleration))
    assert gen.InTarget and gen.Position[:3] == pytest.approx(TARGET3, abs=1e-12)


def _inputs(sc: Scenario) -> dict[str, Any]:
    return dict(Enable=True, CycleTime=DT, Joints=3, VelocityMode=False, Sync=0,
                TargetPos=vec(TARGET3), TargetVel=vec(ZERO3), TargetAcc=vec([]),
                Limits=_limits_with(LIMS3[0]), StartPos=vec(sc.start), StartVel=vec([]),
                StartAcc=vec([]))


@pytest.mark.parametrize("new_cycle", [0.004, 0.025])
def test_a_valid_cycle_time_change_while_busy_keeps_to_the_trajectory(
        st_module: Any, new_cycle: float) -> None:
    """A new (valid) CycleTime mid-move changes only the step: no re-plan, no error, the
    setpoints are the same trajectory's (Ruckig's, at the block's PlanTime) and move between
    two scans by no more than the limits allow in one new cycle."""
    sc, _, gen = two_generators(st_module, 40)
    duration = gen.Duration
    otg = ruckig.Ruckig(3)
    inp = ruckig.InputParameter(3)
    inp.current_position = START3
    inp.target_position = TARGET3
    inp.max_velocity = [1.0] * 3
    inp.max_acceleration = [2.0] * 3
    inp.max_jerk = [10.0] * 3
    traj = ruckig.Trajectory(3)
    assert otg.calculate(inp, traj) == ruckig.Result.Working
    assert duration == pytest.approx(traj.duration, rel=1e-12)
    prev = setpoints(gen)
    while gen.Busy:
        gen_call(gen, sc, TARGET3, ZERO3, CycleTime=new_cycle)
        assert not gen.Error and not gen.NewPlan and gen.Duration == duration
        assert gen.PlanTime == pytest.approx(prev[4] + new_cycle, abs=1e-12)
        ref = traj.at_time(gen.PlanTime)
        for j in range(3):
            assert gen.Position[j] == pytest.approx(ref[0][j], abs=1e-9)
            assert gen.Velocity[j] == pytest.approx(ref[1][j], abs=1e-9)
            assert gen.Acceleration[j] == pytest.approx(ref[2][j], abs=1e-9)
            assert abs(gen.Position[j] - prev[0][j]) <= 1.0 * new_cycle * (1 + 1e-9)
            assert abs(gen.Velocity[j] - prev[1][j]) <= 2.0 * new_cycle * (1 + 1e-9) + 1e-12
            assert abs(gen.Acceleration[j] - prev[2][j]) <= 10.0 * new_cycle * (1 + 1e-9) \
                + 1e-12
        prev = setpoints(gen)
    assert gen.InTarget and gen.PlanTime >= duration
