"""MotionJerkGenerator (st/MotionJerkOnline.st): the per-scan generator against Ruckig's online
update (Ruckig.update with the output passed back as the next input), scan by scan.

Scenarios: targets that change mid-move (some every scan, as when following), jog with the
velocity interface, separate minimum limits; the setpoints must equal Ruckig's within 1e-9
(relative to the move) at every scan, and be continuous: between two scans the velocity
changes by at most the acceleration limit times the cycle and the acceleration by at most
the jerk limit times the cycle, re-plans included. Bad input mid-move (NaN, a target beyond
the limits, a zero limit, a bad cycle time) gives the documented ErrorId while the setpoints
carry on exactly along the last valid trajectory, never NaN; good input plans again from
there.
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
