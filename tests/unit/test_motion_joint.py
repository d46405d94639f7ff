"""MotionJointMove and MotionHalt (st/MotionJoint.st) scan by scan.

References: the Robotics Toolbox's trapezoidal and quintic profiles for the same start,
target, duration and cruise speed; closed forms (float64) for durations and braking; the
contract's rules (MOTION-CONTRACT.md): limits, zero-length moves, bad input changes nothing,
abort and blend without a velocity jump.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import (
    BAD_GROUP_LIMITS,
    BAD_GROUP_STATE,
    BAD_JOINT_COUNT,
    BAD_PARAMETER,
    BAD_PROFILE,
    DT,
    JOINT_LIMIT,
    NOT_FINITE,
    GroupSim,
    make_group,
    run_until_done,
)

rtb_traj = pytest.importorskip("roboticstoolbox.tools.trajectory")

NAN, INF = float("nan"), float("inf")
START = [10.0, 40.0, 120.0]
TARGET = [-50.0, 75.0, 100.0]
MAX_VEL, MAX_ACC = 120.0, 400.0


def padded(values: list[float]) -> list[float]:
    return list(values) + [0.0] * (6 - len(values))


def move_inputs(target: list[float], profile: int, velocity: float = 60.0,
                acceleration: float = 150.0, jerk: float = 2000.0) -> dict[str, Any]:
    return {"Execute": True, "Target": padded(target), "Profile": profile,
            "Velocity": velocity, "Acceleration": acceleration, "Jerk": jerk,
            "CycleTime": DT}


def ref_min_time(d: float, vmax: float, a: float) -> float:
    d = abs(d)
    if d == 0:
        return 0.0
    if d * a <= vmax * vmax:
        return 2 * math.sqrt(d / a)
    return d / vmax + vmax / a


def ref_cruise(d: float, a: float, t: float) -> float:
    """Cruise speed of a rest-to-rest trapezoid that takes exactly t (float64)."""
    d = abs(d)
    disc = max(a * a * t * t - 4 * a * d, 0.0)
    return (a * t - math.sqrt(disc)) / 2


def check_limits(sim: GroupSim, vmax: list[float], amax: float, dt: float = DT) -> None:
    pos, vel = sim.pos(), sim.vel()
    pos = np.vstack([np.array(sim.start), pos])
    vel = np.vstack([np.zeros(pos.shape[1]), vel])
    speed = np.abs(np.diff(pos, axis=0)) / dt
    assert np.all(speed <= np.array(vmax) * (1 + 1e-4) + 1e-3)
    assert np.all(np.abs(vel[1:]) <= np.array(vmax) * (1 + 1e-4) + 1e-3)
    assert np.max(np.abs(np.diff(vel, axis=0))) <= amax * dt * (1 + 1e-4) + 1e-3


def new_sim(start: list[float] = START) -> GroupSim:
    return GroupSim(make_group(start, max_vel=MAX_VEL, max_acc=MAX_ACC))


@pytest.mark.parametrize("profile", [1, 2])
def test_synchronised_trapezoid_vs_robotics_toolbox(st_module: Any, figures: Any,
                                                    profile: int) -> None:
    sim = new_sim()
    fb = st_module.new_fb("MotionJointMove")
    inputs = move_inputs(TARGET, profile)
    acc = 150.0 if profile == 2 else MAX_ACC
    scans = run_until_done(sim, fb, **inputs)
    assert fb.Done and not fb.Error and sim.group["Owner"] == 0
    dists = [t - s for s, t in zip(START, TARGET, strict=True)]
    want_t = max(ref_min_time(d, 60.0, acc) for d in dists)
    assert fb.Duration == pytest.approx(want_t, rel=1e-5)
    assert scans == math.ceil(want_t / DT - 1e-3)
    worst = 0.0
    times = DT * np.arange(1, scans + 1)
    for j, (s, t) in enumerate(zip(START, TARGET, strict=True)):
        cruise = min(ref_cruise(t - s, acc, want_t), 2 * abs(t - s) / want_t)
        ref = rtb_traj.trapezoidal_func(s, t, want_t, cruise)
        q = np.array([float(ref(min(tt, want_t))[0]) for tt in times])
        worst = max(worst, float(np.max(np.abs(sim.pos()[:, j] - q))))
    figures.case("MotionJointMove")
    figures.error("MotionJointMove", worst, "deg vs roboticstoolbox (profiles 1, 2, 3)")
    assert worst <= 1e-3
    check_limits(sim, [60.0] * 3, acc)


def test_quintic_vs_robotics_toolbox(st_module: Any, figures: Any) -> None:
    sim = new_sim()
    fb = st_module.new_fb("MotionJointMove")
    jerk = 2000.0
    scans = run_until_done(sim, fb, **move_inputs(TARGET, 3, jerk=jerk))
    dists = [t - s for s, t in zip(START, TARGET, strict=True)]
    want_t = max(max(15 / 8 * abs(d) / 60.0, math.sqrt(10 / math.sqrt(3) * abs(d) / 150.0),
                     (60 * abs(d) / jerk) ** (1 / 3)) for d in dists)
    assert fb.Duration == pytest.approx(want_t, rel=1e-5)
    times = DT * np.arange(1, scans + 1)
    worst = 0.0
    for j, (s, t) in enumerate(zip(START, TARGET, strict=True)):
        q = rtb_traj.quintic_func(s, t, want_t)(np.minimum(times, want_t))[0]
        worst = max(worst, float(np.max(np.abs(sim.pos()[:, j] - q))))
    figures.case("MotionJointMove")
    figures.error("MotionJointMove", worst, "deg vs roboticstoolbox (profiles 1, 2, 3)")
    assert worst <= 1e-3
    check_limits(sim, [60.0] * 3, 150.0)


def test_constant_speed_each_joint_own_time(st_module: Any) -> None:
    sim = new_sim()
    fb = st_module.new_fb("MotionJointMove")
    run_until_done(sim, fb, **move_inputs(TARGET, 0, velocity=50.0))
    pos = sim.pos()
    arrival = [int(np.argmax(np.abs(pos[:, j] - TARGET[j]) < 1e-4)) + 1 for j in range(3)]
    for j, (s, t) in enumerate(zip(START, TARGET, strict=True)):
        # each joint: its own trapezoid at 50 deg/s ramped at the joint's limit
        assert arrival[j] == math.ceil(ref_min_time(t - s, 50.0, MAX_ACC) / DT - 1e-3)
    assert len(set(arrival)) == 3
    check_limits(sim, [50.0] * 3, MAX_ACC)


def test_velocity_capped_by_group_limits(st_module: Any) -> None:
    sim = new_sim()
    sim.group["Limits"]["MaxVelDeg"] = [30.0, 120.0, 10.0, 1.0, 1.0, 1.0]
    fb = st_module.new_fb("MotionJointMove")
    run_until_done(sim, fb, **move_inputs(TARGET, 0, velocity=100.0))
    check_limits(sim, [30.0, 100.0, 10.0], MAX_ACC)
    assert sim.positions[-1] == pytest.approx(TARGET, abs=1e-4)


def test_zero_length_move_done_in_one_scan(st_module: Any) -> None:
    for profile in range(4):
        sim = new_sim()
        fb = st_module.new_fb("MotionJointMove")
        sim.scan(fb, **move_inputs(START, profile))
        assert fb.Done and not fb.Busy and not fb.Error
        assert sim.positions[-1] == pytest.approx(START)
        sim.scan(fb, **{**move_inputs(START, profile), "Execute": False})
        assert not fb.Done


BAD_MOVES: list[tuple[str, dict[str, Any], int]] = [
    ("velocity NaN", {"Velocity": NAN}, BAD_PARAMETER),
    ("velocity Inf", {"Velocity": INF}, BAD_PARAMETER),
    ("velocity 0", {"Velocity": 0.0}, BAD_PARAMETER),
    ("velocity negative", {"Velocity": -10.0}, BAD_PARAMETER),
    ("acceleration NaN", {"Acceleration": NAN}, BAD_PARAMETER),
    ("acceleration negative", {"Acceleration": -1.0}, BAD_PARAMETER),
    ("jerk 0", {"Profile": 3, "Jerk": 0.0}, BAD_PARAMETER),
    ("jerk -Inf", {"Profile": 3, "Jerk": -INF}, BAD_PARAMETER),
    ("cycle time 0", {"CycleTime": 0.0}, BAD_PARAMETER),
    ("cycle time NaN", {"CycleTime": NAN}, BAD_PARAMETER),
    ("profile 5", {"Profile": 5}, BAD_PROFILE),
    ("profile -1", {"Profile": -1}, BAD_PROFILE),
    ("target NaN", {"Target": padded([NAN, 0.0, 90.0])}, NOT_FINITE),
    ("target beyond upper limit", {"Target": padded([0.0, 171.0, 90.0])}, JOINT_LIMIT),
    ("target below lower limit", {"Target": padded([0.0, 0.0, -200.0])}, JOINT_LIMIT),
]


@pytest.mark.parametrize(("change", "code"), [(c, k) for _, c, k in BAD_MOVES],
                         ids=[n for n, _, _ in BAD_MOVES])
def test_bad_input_changes_nothing(st_module: Any, change: dict[str, Any], code: int) -> None:
    new_sim().assert_rejected(st_module.new_fb("MotionJointMove"), code,
                              **{**move_inputs(TARGET, 2), **change})


@pytest.mark.parametrize(("name", "edit", "code"), [
    ("joints 0", lambda g: g.update(Joints=0), BAD_JOINT_COUNT),
    ("joints 7", lambda g: g.update(Joints=7), BAD_JOINT_COUNT),
    ("max vel 0", lambda g: g["Limits"]["MaxVelDeg"].__setitem__(1, 0.0), BAD_GROUP_LIMITS),
    ("max acc NaN", lambda g: g["Limits"]["MaxAccDeg"].__setitem__(0, NAN), BAD_GROUP_LIMITS),
    ("lower > upper", lambda g: g["Limits"]["LowerDeg"].__setitem__(2, 171.0),
     BAD_GROUP_LIMITS),
    ("position NaN", lambda g: g["Position"].__setitem__(0, NAN), BAD_GROUP_STATE),
    ("velocity Inf", lambda g: g["Velocity"].__setitem__(2, INF), BAD_GROUP_STATE),
])
def test_bad_group_changes_nothing(st_module: Any, name: str, edit: Any, code: int) -> None:
    for block, inputs in (("MotionJointMove", move_inputs(TARGET, 2)),
                          ("MotionHalt", {"Execute": True, "Deceleration": 100.0,
                                          "CycleTime": DT})):
        sim = new_sim()
        edit(sim.group)
        before = repr(sim.group)  # repr: NaN != NaN in a plain comparison
        fb = st_module.new_fb(block)
        sim.scan(fb, **inputs)
        assert fb.Error and fb.ErrorId == code, (block, name)
        assert repr(sim.group) == before


def takeover(st_module: Any, first: dict[str, Any], second: dict[str, Any],
             after_scans: int) -> tuple[GroupSim, Any, Any]:
    sim = new_sim()
    a = st_module.new_fb("MotionJointMove")
    b = st_module.new_fb("MotionJointMove")
    for _ in range(after_scans):
        sim.scan(a, **first)
    assert a.Busy
    sim.scan(b, **second)
    sim.call(a, **first)  # the old block sees that it lost the group
    assert a.CommandAborted and not a.Busy and not a.Active
    run_until_done(sim, b, **second)
    assert b.Done
    return sim, a, b


@pytest.mark.parametrize(("second_target", "profile"), [
    ([-30.0, 90.0, 90.0], 2),   # same direction, further: continue without stopping
    ([60.0, 10.0, 140.0], 2),   # reverse: brake at the limit, then go
    ([-30.0, 90.0, 90.0], 3),   # quintic from the current velocity
    ([60.0, 10.0, 140.0], 3),
    ([-30.0, 90.0, 90.0], 0),
    ([-40.0, 60.0, 110.0], 1),
])
def test_abort_and_blend_no_velocity_jump(st_module: Any, second_target: list[float],
                                          profile: int) -> None:
    first = move_inputs(TARGET, 2, velocity=80.0, acceleration=200.0)
    second = move_inputs(second_target, profile, velocity=80.0, acceleration=200.0)
    sim, _, _ = takeover(st_module, first, second, after_scans=35)
    assert sim.positions[-1] == pytest.approx(second_target, abs=1e-4)
    # the takeover scan changes the velocity by no more than the limit allows
    check_limits(sim, [MAX_VEL] * 3, MAX_ACC)
    vel = sim.vel()
    assert np.max(np.abs(vel[35] - vel[34])) <= MAX_ACC * DT * (1 + 1e-4)


def test_new_execute_with_bad_input_keeps_old_move(st_module: Any) -> None:
    sim = new_sim()
    fb = st_module.new_fb("MotionJointMove")
    good = move_inputs(TARGET, 2)
    for _ in range(10):
        sim.scan(fb, **good)
    sim.scan(fb, **{**good, "Execute": False})
    sim.scan(fb, **{**good, "Velocity": NAN})
    assert fb.Error and fb.ErrorId == BAD_PARAMETER and fb.Busy
    run_until_done(sim, fb, **good)
    assert sim.positions[-1] == pytest.approx(TARGET, abs=1e-4)
    check_limits(sim, [60.0] * 3, 150.0)


@pytest.mark.parametrize("decel", [100.0, 1000.0])
def test_halt_brakes_within_deceleration(st_module: Any, decel: float) -> None:
    sim = new_sim()
    move = st_module.new_fb("MotionJointMove")
    halt = st_module.new_fb("MotionHalt")
    inputs = move_inputs(TARGET, 2, velocity=80.0, acceleration=200.0)
    for _ in range(40):
        sim.scan(move, **inputs)
    v0 = list(sim.group["Velocity"][:3])
    p0 = list(sim.group["Position"][:3])
    halt_in = {"Execute": True, "Deceleration": decel, "CycleTime": DT}
    scans = run_until_done(sim, halt, **halt_in)
    sim.call(move, **inputs)
    assert move.CommandAborted and halt.Done
    dec = min(decel, MAX_ACC)
    assert scans == math.ceil(max(abs(v) for v in v0) / dec / DT - 1e-3)
    for j in range(3):
        want = p0[j] + math.copysign(v0[j] ** 2 / (2 * dec), v0[j])
        assert sim.positions[-1][j] == pytest.approx(want, abs=1e-3)
    assert sim.velocities[-1] == [0.0, 0.0, 0.0]
    assert np.max(np.abs(np.diff(sim.vel()[39:], axis=0))) <= dec * DT * (1 + 1e-4)


def test_halt_at_rest_done_in_one_scan(st_module: Any) -> None:
    sim = new_sim()
    halt = st_module.new_fb("MotionHalt")
    sim.scan(halt, Execute=True, Deceleration=100.0, CycleTime=DT)
    assert halt.Done and not halt.Busy
    for bad in (0.0, -5.0, NAN, INF):
        fb = st_module.new_fb("MotionHalt")
        before = sim.snapshot()
        sim.scan(fb, Execute=True, Deceleration=bad, CycleTime=DT)
        assert fb.Error and fb.ErrorId == BAD_PARAMETER and sim.group == before
