"""Property tests of the motion profiles and MotionJointMove over their whole documented
range: long and slow moves, tiny distances, float32 extremes and just beyond, NaN/Inf, and
command inputs changed every scan while a move is Busy.

References: the closed-form trapezoid in float64 (cruise speed = smaller root of
Vc^2 - A T Vc + A D = 0, taken in its stable form), the group's limits applied to finite
differences of the scan-by-scan setpoints, exact target positions, and a second run of the
same move with unchanged inputs (the path must be identical).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import BAD_PARAMETER, DT, NOT_FINITE, GroupSim, make_group

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

F32_MAX = float(np.finfo(np.float32).max)
LIBRARY_FINITE = 1.0e30  # IsFiniteReal: beyond is "not finite"
MAX_SCANS = 2**24  # MotionJointMove's documented longest move


def f32(x: float) -> float:
    return float(np.float32(x))


def ref_trapezoid(dist: float, duration: float, acc: float) -> tuple[float, float]:
    """(cruise speed, duration) of the rest-to-rest trapezoid that takes `duration` or, if
    that is below the triangle's time, of the triangle (float64)."""
    d = abs(dist)
    t_tri = 2 * math.sqrt(d / acc)
    if duration <= t_tri:
        return math.sqrt(acc * d), t_tri
    root = math.sqrt((acc * duration) ** 2 - 4 * acc * d)
    return 2 * acc * d / (acc * duration + root), duration


def no_nan(record: dict[str, Any]) -> bool:
    return all(not (isinstance(v, float) and math.isnan(v)) for v in record.values())


positive = st.floats(1e-3, 1e7).map(f32)
extreme = st.one_of(
    st.sampled_from([0.0, -0.0, 1e-45, 1e-38, 1e-30, 1e30, 1.0000001e30, 1e31, F32_MAX,
                     -F32_MAX, math.inf, -math.inf, math.nan]),
    st.floats(-F32_MAX, F32_MAX, width=32))


@examples(300)
@given(dist=st.one_of(st.floats(1e-6, 1e3), st.floats(1e3, 1e7)),
       sign=st.sampled_from([1.0, -1.0]), acc=positive,
       stretch=st.floats(0.5, 1e5))
def test_trapezoid_plan_matches_closed_form(st_module: Any, dist: float, sign: float,
                                            acc: float, stretch: float) -> None:
    dist = f32(sign * dist)
    t_tri = 2 * math.sqrt(abs(dist) / acc)
    duration = f32(t_tri * stretch)
    plan = st_module.call("MotionTrapezoidPlan", dist, 0.0, duration, acc)
    assert plan["Valid"] and no_nan(plan)
    vc, t = ref_trapezoid(dist, duration, acc)
    # near the triangle the root is ill-conditioned in any arithmetic: compare the speed
    # there through the duration only
    if stretch > 1.01:
        assert plan["Vc"] == pytest.approx(vc, rel=1e-4)
    assert plan["Vc"] <= math.sqrt(acc * abs(dist)) * (1 + 1e-5)
    assert plan["Duration"] == pytest.approx(t, rel=1e-4)
    end = st_module.call("MotionTrapezoidEval", plan, plan["Duration"])
    assert end["Pos"] == dist and end["Vel"] == 0.0


@examples(300)
@given(dist=extreme, v0=extreme, duration=extreme, acc=extreme, vmax=extreme, jerk=extreme,
       t=extreme)
# found by the 10x soak: the cruise speed underflowed to 0, the plan lasted 0 s and its end
# was the start
@example(dist=1e-45, v0=0.0, duration=1e30, acc=1e-45, vmax=0.0, jerk=0.0, t=0.0)
def test_profiles_never_nan(st_module: Any, dist: float, v0: float, duration: float,
                            acc: float, vmax: float, jerk: float, t: float) -> None:
    plan = st_module.call("MotionTrapezoidPlan", dist, v0, duration, acc)
    assert no_nan(plan)
    inputs_ok = all(math.isfinite(x) and abs(x) <= LIBRARY_FINITE for x in
                    (dist, v0, duration, acc)) and acc > 0
    if not inputs_ok:
        assert not plan["Valid"] and plan["Duration"] == 0.0
    if plan["Valid"]:
        assert math.isfinite(plan["Duration"]) and plan["Duration"] >= 0.0
        for time in (t, plan["Duration"] / 2, plan["Duration"]):
            assert no_nan(st_module.call("MotionTrapezoidEval", plan, time))
        assert st_module.call("MotionTrapezoidEval", plan, plan["Duration"])["Pos"] == f32(
            plan["Dir"] * plan["Dist"])
    tmin = st_module.call("MotionTrapezoidMinTime", dist, v0, vmax, acc)
    assert tmin == -1.0 or (0.0 <= tmin <= LIBRARY_FINITE)
    qmin = st_module.call("MotionQuinticMinTime", dist, vmax, acc, jerk)
    assert qmin == -1.0 or (0.0 <= qmin <= LIBRARY_FINITE)
    assert no_nan(st_module.call("MotionStopEval", v0, acc, t))
    assert no_nan(st_module.call("MotionQuinticEval", dist, v0, duration, t))
    assert no_nan(st_module.call("MotionConstSpeedEval", dist, vmax, t))


MAX_VEL, MAX_ACC = 90.0, 300.0
angle = st.floats(-150.0, 150.0).map(f32)
joints3 = st.lists(angle, min_size=3, max_size=3)


def move_inputs(target: list[float], profile: int, velocity: float, acc: float,
                jerk: float, dt: float = DT) -> dict[str, Any]:
    return {"Execute": True, "Target": list(target) + [0.0] * 3, "Profile": profile,
            "Velocity": velocity, "Acceleration": acc, "Jerk": jerk, "CycleTime": dt}


def run_move(st_module: Any, start: list[float], inputs: dict[str, Any],
             changed: list[dict[str, Any]] | None = None) -> tuple[GroupSim, Any, int]:
    sim = GroupSim(make_group(start, max_vel=MAX_VEL, max_acc=MAX_ACC))
    fb = st_module.new_fb("MotionJointMove")
    for k in range(4000):
        sim.scan(fb, **(inputs if changed is None or k == 0 else changed[k % len(changed)]))
        if not fb.Busy:
            return sim, fb, k + 1
    raise AssertionError("move still busy")


def check_path(sim: GroupSim, target: list[float], vmax: float, amax: float,
               synchronised: bool) -> None:
    pos = np.vstack([np.array(sim.start), sim.pos()])
    vel = np.vstack([np.zeros(3), np.diff(pos, axis=0) / DT])
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(sim.vel()))
    # the setpoints are REALs: a step between two of them is off by up to one float32 ulp
    # of the position (1.5e-5 deg at 128 deg, 1.5e-3 deg/s over 10 ms), whatever the block
    # computes; the differences of the steps by up to two
    quantum = float(np.spacing(np.float32(np.max(np.abs(pos))))) / DT
    assert np.max(np.abs(vel)) <= vmax * (1 + 1e-4) + 1e-3 + quantum
    assert np.max(np.abs(np.diff(vel, axis=0))) <= amax * DT * (1 + 1e-3) + 1e-3 + 2 * quantum
    assert sim.positions[-1] == target
    if synchronised:
        # no joint arrives early: at 90 % of the move every joint that moves at least
        # 0.1 deg is still on its way (float32 resolves the quintic's last 1 % there)
        late = int(0.9 * len(sim.positions))
        for j in range(3):
            if abs(target[j] - sim.start[j]) > 0.1:
                assert sim.positions[late - 1][j] != target[j]


command = st.fixed_dictionaries({
    "Execute": st.sampled_from([True, True, True, False]),
    "Target": st.lists(st.one_of(angle, st.sampled_from([math.nan, math.inf, 1e31, 500.0])),
                       min_size=6, max_size=6),
    "Profile": st.integers(-1, 5),
    "Velocity": st.one_of(st.floats(1e-3, 1e3), st.sampled_from([0.0, -1.0, math.nan])),
    "Acceleration": st.one_of(st.floats(1e-3, 1e4), st.sampled_from([0.0, math.inf])),
    "Jerk": st.floats(1e-3, 1e5),
    "CycleTime": st.one_of(st.floats(1e-4, 0.1), st.sampled_from([0.0, math.nan])),
})


@examples(25)
@given(start=joints3, target=joints3, profile=st.integers(0, 4),
       velocity=st.floats(60.0, 200.0), acc=st.floats(150.0, 1000.0),
       changes=st.lists(command, min_size=1, max_size=6))
def test_joint_move_ignores_inputs_changed_while_busy(
        st_module: Any, start: list[float], target: list[float], profile: int,
        velocity: float, acc: float, changes: list[dict[str, Any]]) -> None:
    inputs = move_inputs(target, profile, velocity, acc, 5 * acc)
    calm, calm_fb, n_calm = run_move(st_module, start, inputs)
    assert calm_fb.Done
    # Execute falling and rising again starts a new move by design: keep it TRUE here,
    # everything else changes every scan
    noisy = [{**c, "Execute": True} for c in changes]
    busy, busy_fb, n_busy = run_move(st_module, start, inputs, noisy)
    assert busy_fb.Done and n_busy == n_calm
    assert busy.positions == calm.positions and busy.velocities == calm.velocities
    vmax = min(velocity, MAX_VEL)
    amax = MAX_ACC if profile <= 1 else min(acc, MAX_ACC)
    check_path(calm, target, vmax, amax, synchronised=profile >= 1)


@examples(25)
@given(start=joints3, target=joints3, profile=st.integers(1, 2),
       velocity=st.floats(0.05, 5.0), slow_joint=st.floats(1e-4, 0.5))
# found by the 10x soak: a step of 3 deg/s at 128 deg rounds to 3.0014 deg/s
@example(start=[0.0, 0.0, 128.0], target=[0.0, 0.0, 0.0], profile=1, velocity=3.0,
         slow_joint=0.5)
def test_slow_synchronised_moves_arrive_together(st_module: Any, start: list[float],
                                                 target: list[float], profile: int,
                                                 velocity: float, slow_joint: float) -> None:
    # the lead joint takes at most about 1,000 scans; joint 3 moves a tiny distance
    lead = min(abs(target[0] - start[0]), velocity * 9.0)
    target = [f32(start[0] + math.copysign(lead, target[0] - start[0])), target[1],
              f32(start[2] + slow_joint)]
    target[1] = f32(start[1] + max(-lead, min(lead, target[1] - start[1])))
    inputs = move_inputs(target, profile, velocity, MAX_ACC, 1.0)
    sim, fb, _ = run_move(st_module, start, inputs)
    assert fb.Done and not fb.Error
    check_path(sim, target, min(velocity, MAX_VEL), MAX_ACC, synchronised=True)


@examples(60)
@given(field=st.sampled_from(["Velocity", "Acceleration", "Jerk", "CycleTime", "Target"]),
       value=extreme, profile=st.integers(0, 4))
def test_joint_move_extreme_inputs(st_module: Any, field: str, value: float,
                                   profile: int) -> None:
    start = [10.0, -20.0, 30.0]
    inputs = move_inputs([40.0, 0.0, -10.0], profile, 60.0, 150.0, 2000.0)
    if field == "Target":
        inputs["Target"] = [value, 0.0, -10.0, 0.0, 0.0, 0.0]
    else:
        inputs[field] = value
    sim = GroupSim(make_group(start, lower=-f32(LIBRARY_FINITE), upper=f32(LIBRARY_FINITE),
                              max_vel=MAX_VEL,
                              max_acc=MAX_ACC))
    fb = st_module.new_fb("MotionJointMove")
    before = sim.snapshot()
    sim.scan(fb, **inputs)
    finite = math.isfinite(value) and abs(value) <= LIBRARY_FINITE
    used = field in ("Velocity", "CycleTime", "Target") or (
        field == "Acceleration" and profile >= 2) or (field == "Jerk" and profile >= 3)
    if used and not finite:
        assert fb.Error and fb.ErrorId == (NOT_FINITE if field == "Target" else BAD_PARAMETER)
        assert sim.group == before
        return
    if fb.Error:
        # a legal value the block cannot plan: zero or negative, or a move beyond 2^24
        # scans or 1E30 deg; profile 4 also a limit beyond the planner's 1E15 (8), a move
        # beyond its 7600 s (29 JerkTooLong) or a ratio of limits the planner cannot
        # solve (27 JerkNoProfile, 28 JerkSyncFailed: Ruckig fails on them too);
        # nothing changes
        codes = (BAD_PARAMETER, 10) + ((27, 28, 29) if profile == 4 else ())
        assert fb.ErrorId in codes and sim.group == before
        return
    for _ in range(200):
        if not fb.Busy:
            break
        sim.scan(fb, **inputs)
    values = np.concatenate([sim.pos().ravel(), sim.vel().ravel()])
    assert np.all(np.isfinite(values))
    assert fb.Duration <= MAX_SCANS * inputs["CycleTime"] * (1 + 1e-6)


def test_joint_move_longest_move_boundary(st_module: Any) -> None:
    """Documented maximum: 2^24 scans. Just below is accepted, just beyond refused."""
    dt = 1e-3
    limit_s = MAX_SCANS * dt  # 16,777 s
    for factor, ok in ((0.99, True), (1.01, False)):
        speed = f32(100.0 / (limit_s * factor))  # 100 deg at constant speed
        sim = GroupSim(make_group([0.0, 0.0, 0.0], max_vel=MAX_VEL, max_acc=MAX_ACC))
        fb = st_module.new_fb("MotionJointMove")
        sim.scan(fb, **move_inputs([100.0, 0.0, 0.0], 2, speed, MAX_ACC, 1.0, dt))
        assert fb.Busy == ok and fb.Error == (not ok)
        if ok:
            assert fb.Duration == pytest.approx(100.0 / speed + speed / MAX_ACC, rel=1e-5)
            sim.scan(fb, **move_inputs([100.0, 0.0, 0.0], 2, speed, MAX_ACC, 1.0, dt))
            assert np.all(np.isfinite(sim.pos()))
        else:
            assert fb.ErrorId == BAD_PARAMETER
