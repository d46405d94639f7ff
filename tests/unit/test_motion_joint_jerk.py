"""MotionJointMove's profile 4 (time-optimal jerk-limited, all joints synchronised) and
MotionHalt's jerk-limited braking (st/MotionJoint.st), scan by scan, against Ruckig.

The reference is the PyPI `ruckig` package (Ruckig.calculate, phase synchronisation: the
block's documented Sync) on exactly the inputs the block latches: the group's REAL position,
velocity and acceleration (the acceleration within +/- the joint's limit) and the REAL limits
min(Velocity, MaxVelDeg), min(Acceleration, MaxAccDeg), Jerk. Per move: the same duration
within 1e-4 relative, the setpoints of every scan within float32 tolerance of Ruckig's
trajectory at that time, the target reached exactly, and -- densely, with the same move run at
a 20 times shorter cycle (the plan is a function of time, not of the cycle) -- velocity,
acceleration and jerk within the limits at every sample (the block's own outputs, and the
finite differences of its positions).

The jerk-limited halt is checked against Ruckig's velocity interface with the limits its
header promises (each joint on its own: |a| <= D = min(Deceleration, MaxAccDeg), jerk Jerk
raised so that no acceleration ramp lasts more than 0.02 s, and for a joint already braking
the jerk that ends the braking at rest), and against the promises themselves: continuous
position and velocity, no reversal, at rest within |v0| / D + 0.03 s.
"""

from __future__ import annotations

import math
import random
from typing import Any

import numpy as np
import pytest
from jerk_support import F32_EPS, AxisCase, ruckig_plan
from joint_jerk_support import (
    DT,
    DT32,
    JointCase,
    check_against_ruckig,
    check_limits_densely,
    f32,
    random_case,
    run_move,
    span,
)
from motion_support import BAD_PARAMETER, BAD_PROFILE, GroupSim, make_group

ruckig = pytest.importorskip("ruckig")

JERK_TOO_LONG = 29
HALT_RAMP_S = 0.02  # MotionHalt's HaltRampS


# ------------------------------------------------------------------------------ profile 4


@pytest.mark.parametrize("kind,joints,seed", [
    ("rest", 3, 1), ("rest", 5, 2), ("moving", 3, 3), ("moving", 5, 4), ("fast", 3, 5)])
def test_profile4_matches_ruckig(st_module: Any, figures: Any, kind: str, joints: int,
                                 seed: int) -> None:
    rng = random.Random(seed)
    worst_rel = worst_pos = 0.0
    for _ in range(6):
        case = random_case(rng, kind, joints)
        rel, pos = check_against_ruckig(st_module, case)
        worst_rel, worst_pos = max(worst_rel, rel), max(worst_pos, pos)
    figures.case("MotionJointMove")
    figures.error("MotionJointMove", worst_pos, "of float32 tolerance vs ruckig (profile 4)")
    print(f"profile 4, {kind}, {joints} joints: duration rel err {worst_rel:.2e}, position "
          f"err {worst_pos:.2e} of float32 tolerance")


@pytest.mark.parametrize("kind,seed", [("rest", 11), ("moving", 12), ("fast", 13)])
def test_profile4_keeps_the_limits_between_scans(st_module: Any, kind: str, seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(3):
        check_limits_densely(st_module, random_case(rng, kind, 3))


def test_profile4_from_rest_is_a_straight_line_in_joint_space(st_module: Any) -> None:
    """Phase synchronisation: from rest every joint covers the same fraction of its
    distance at every scan."""
    case = JointCase((10.0, -40.0, 120.0, 0.0), (-50.0, 75.0, 100.0, 30.0),
                     (150.0,) * 4, (1000.0,) * 4, 90.0, 600.0, 4000.0)
    run = run_move(st_module, case)
    d = np.array(case.target) - np.array(case.start)
    frac = (run.pos - np.array(case.start)) / d
    assert np.max(np.abs(frac - frac[:, :1])) < 1e-5


@pytest.mark.parametrize("jerk,velocity,acceleration,target", [
    (0.5, 100.0, 500.0, 3.0),          # tiny jerk: the move is all jerk phases
    (1.0e9, 100.0, 500.0, 90.0),       # huge jerk: all but the trapezoid of profile 2
    (2000.0, 0.05, 500.0, 120.0),      # very long: 2,400 s at 0.05 deg/s
])
def test_profile4_extreme_but_legal_limits(st_module: Any, jerk: float, velocity: float,
                                           acceleration: float, target: float) -> None:
    case = JointCase((0.0, 10.0, -20.0), (target, 10.0 - target / 2, -20.0 + target / 4),
                     (150.0,) * 3, (1000.0,) * 3, velocity, acceleration, jerk)
    axes = case.axes()
    ref = ruckig_plan(axes, "Phase")
    assert ref.ok
    if ref.duration > 60.0:
        # a long move: its plan and a scan at the end, at a 1 s cycle
        long_case = case
        sim = GroupSim(long_case.group())
        fb = st_module.new_fb("MotionJointMove")
        sim.call(fb, **long_case.inputs(1.0))
        assert fb.Busy and abs(fb.Duration - ref.duration) <= 1e-4 * ref.duration
        scans = 1
        while fb.Busy:
            g = sim.group
            p, _, _ = ref.at(scans * 1.0)
            for j, ax in enumerate(axes):
                assert abs(g["Position"][j] - p[j]) <= F32_EPS * span(ax, ref.duration)
            sim.call(fb, **long_case.inputs(1.0))
            scans += 1
        assert fb.Done and sim.group["Position"][:3] == [f32(t) for t in case.target]
        return
    check_against_ruckig(st_module, case)
    check_limits_densely(st_module, case, factor=5)
    if jerk > 1e8:
        # almost the time-optimal trapezoid (profile 2) of the same limits
        sim = GroupSim(case.group())
        fb2 = st_module.new_fb("MotionJointMove")
        sim.call(fb2, **{**case.inputs(), "Profile": 2})
        assert ref.duration == pytest.approx(fb2.Duration, rel=1e-5)


def test_profile4_takes_over_a_moving_group_without_a_jump(st_module: Any) -> None:
    """A profile-4 move re-planned on another block while the first one is at full
    acceleration: the second plans from the group's position, velocity and acceleration
    (Ruckig's plan from exactly that state), and between scans the velocity changes by at
    most the acceleration limit and the acceleration by at most the jerk limit."""
    case = JointCase((0.0, 40.0, 95.0), (100.0, -20.0, 60.0), (150.0,) * 3, (1000.0,) * 3,
                     120.0, 800.0, 6000.0)
    sim = GroupSim(case.group())
    first, second = st_module.new_fb("MotionJointMove"), st_module.new_fb("MotionJointMove")
    acc = []
    vel = []
    for _ in range(12):
        sim.call(first, **case.inputs())
        vel.append(sim.group["Velocity"][:3])
        acc.append(sim.group["Acceleration"][:3])
    assert first.Busy and max(abs(a) for a in acc[-1]) > 500.0
    g = sim.snapshot()
    new_target = [-40.0, 10.0, 120.0]
    axes = [AxisCase(f32(g["Position"][j]), f32(g["Velocity"][j]), f32(g["Acceleration"][j]),
                     f32(new_target[j]), 0.0, 120.0, 800.0, 6000.0) for j in range(3)]
    ref = ruckig_plan(axes, "Phase")
    assert ref.ok
    inputs2 = {**case.inputs(), "Target": new_target + [0.0] * 3}
    scans = 0
    while True:
        sim.call(second, **inputs2)
        sim.call(first, **case.inputs())
        scans += 1
        if scans == 1:
            assert second.Duration == pytest.approx(ref.duration, rel=1e-4)
            assert first.CommandAborted and not first.Busy
        p, _, _ = ref.at(scans * DT32)
        for j, ax in enumerate(axes):
            assert abs(sim.group["Position"][j] - p[j]) <= F32_EPS * span(ax, ref.duration)
        vel.append(sim.group["Velocity"][:3])
        acc.append(sim.group["Acceleration"][:3])
        if not second.Busy:
            break
    assert second.Done
    dv = np.max(np.abs(np.diff(np.array(vel), axis=0)))
    da = np.max(np.abs(np.diff(np.array(acc), axis=0)))
    assert dv <= 800.0 * DT * (1 + 1e-5)
    assert da <= 6000.0 * DT * (1 + 1e-4)


@pytest.mark.parametrize("change,code", [
    ({"Jerk": 0.0}, BAD_PARAMETER),
    ({"Jerk": -5.0}, BAD_PARAMETER),
    ({"Jerk": math.nan}, BAD_PARAMETER),
    ({"Jerk": math.inf}, BAD_PARAMETER),
    ({"Acceleration": 0.0}, BAD_PARAMETER),
    ({"Acceleration": math.nan}, BAD_PARAMETER),
    ({"Jerk": 1.0e20}, BAD_PARAMETER),                  # beyond the planner's 1E15
    ({"Velocity": 1.0e-4}, JERK_TOO_LONG),             # 1.2E6 s at full speed
    # the planner would fail (27, as Ruckig); while another move runs the start is faster
    # than 1e-30 deg/s and the block cannot tell the move too long before planning: 27
    ({"Velocity": 1.0e-30}, JERK_TOO_LONG),
    ({"Profile": 5}, BAD_PROFILE),
])
def test_profile4_bad_input_changes_nothing(st_module: Any, change: dict[str, Any],
                                            code: int) -> None:
    """Refused at the Execute edge, also while another profile-4 move runs: that move goes
    on exactly as if nothing had happened."""
    case = JointCase((0.0, 40.0, 95.0), (100.0, -20.0, 60.0), (150.0,) * 3, (1000.0,) * 3,
                     120.0, 800.0, 6000.0)
    fresh = GroupSim(case.group())
    fresh.assert_rejected(st_module.new_fb("MotionJointMove"), code,
                          **{**case.inputs(), **change})
    calm = GroupSim(case.group())
    busy = GroupSim(case.group())
    a, b = st_module.new_fb("MotionJointMove"), st_module.new_fb("MotionJointMove")
    c = st_module.new_fb("MotionJointMove")
    for k in range(40):
        calm.scan(a, **case.inputs())
        busy.scan(b, **case.inputs())
        if k == 10:
            busy.call(c, **{**case.inputs(), **change})
            busy_code = 27 if change.get("Velocity") == 1.0e-30 else code
            assert c.Error and c.ErrorId == busy_code
    assert busy.positions == calm.positions and busy.velocities == calm.velocities


@pytest.mark.parametrize("seconds,acceleration,ok", [
    (7000.0, 500.0, True), (7700.0, 500.0, False),
    # 7,590 s at full speed, and 1,318 s more to reach it: refused after planning
    (7590.0, 1.0e-5, False)])
def test_profile4_seven_thousand_six_hundred_seconds(st_module: Any, seconds: float,
                                                     acceleration: float, ok: bool) -> None:
    """One joint, 100 deg (the planner itself limits only several): just under 7600 s is
    planned, just over refused (29)."""
    case = JointCase((0.0,), (100.0,), (150.0,), (1000.0,), f32(100.0 / seconds),
                     acceleration, 5000.0)
    sim = GroupSim(case.group())
    fb = st_module.new_fb("MotionJointMove")
    sim.call(fb, **case.inputs())
    assert fb.Busy == ok
    ref = ruckig_plan(case.axes())
    assert ref.ok and (ref.duration <= 7600.0) == ok
    if not ok:
        assert fb.Error and fb.ErrorId == JERK_TOO_LONG
    else:
        assert fb.Duration == pytest.approx(ref.duration, rel=1e-6)


# ------------------------------------------------------------------------------ halt


def halt_limits(v0: float, a0: float, decel: float, jerk: float,
                cycle: float = DT) -> tuple[float, float]:
    """The header's rule, per joint: the start acceleration within +/-D, the jerk Jerk raised
    so that no ramp lasts more than HaltRampS, and for a joint braking already the jerk that
    ends at rest (or acceleration 0 when that would take less than a scan)."""
    a0 = max(-decel, min(decel, a0))
    js = max(jerk, (abs(a0) + decel) / HALT_RAMP_S)
    if (a0 < 0.0 <= v0) or (a0 > 0.0 >= v0):
        if abs(a0) / f32(cycle) * abs(v0) * 2.0 < a0 * a0:
            a0 = 0.0
            js = max(jerk, decel / HALT_RAMP_S)
        else:
            js = max(js, a0 * a0 / (2.0 * abs(v0)))
    return a0, js


@pytest.mark.parametrize("after,jerk,decel", [
    (8, 3000.0, 1.0e6),     # accelerating hard
    (30, 3000.0, 1.0e6),    # cruising
    (55, 3000.0, 1.0e6),    # braking already
    (8, 3000.0, 150.0),     # a soft stop while accelerating at 800
    (30, 1.0e6, 400.0),     # a jerk above the ramp's
])
def test_jerk_halt_of_a_profile4_move(st_module: Any, after: int, jerk: float,
                                      decel: float) -> None:
    case = JointCase((0.0, 40.0, 95.0), (100.0, -20.0, 60.0), (150.0,) * 3, (1000.0,) * 3,
                     120.0, 800.0, 6000.0)
    sim = GroupSim(case.group())
    move, halt = st_module.new_fb("MotionJointMove"), st_module.new_fb("MotionHalt")
    for _ in range(after):
        sim.call(move, **case.inputs())
    assert move.Busy
    g = sim.snapshot()
    d = min(decel, 1000.0)
    axes = []
    for j in range(3):
        v0, a0 = f32(g["Velocity"][j]), f32(g["Acceleration"][j])
        a0, js = halt_limits(v0, a0, f32(d), f32(jerk))
        axes.append(AxisCase(f32(g["Position"][j]), v0, a0, 0.0, 0.0, 1.0, f32(d), js))
    refs = [ruckig_plan([ax], "None", "Velocity") for ax in axes]
    assert all(r.ok for r in refs)
    halt_in = {"Execute": True, "Deceleration": decel, "Jerk": jerk, "CycleTime": DT}
    pos, vel = [list(g["Position"][:3])], [list(g["Velocity"][:3])]
    scans = 0
    while True:
        sim.call(halt, **halt_in)
        sim.call(move, **case.inputs())
        scans += 1
        assert move.CommandAborted
        for j, (ax, ref) in enumerate(zip(axes, refs, strict=True)):
            p, _, _ = ref.at(scans * DT32)
            assert abs(sim.group["Position"][j] - p[0]) <= F32_EPS * (abs(ax.p0) + 200.0)
        pos.append(sim.group["Position"][:3])
        vel.append(sim.group["Velocity"][:3])
        if not halt.Busy:
            break
    assert halt.Done and sim.group["Owner"] == 0
    v = np.array(vel)
    # no reversal, within the deceleration (after the start's own acceleration)
    for j in range(3):
        assert np.all(v[:, j] * v[0, j] >= -1e-9)
        assert np.max(np.abs(np.diff(v[1:, j]))) <= d * DT * (1 + 1e-5)
    # the bound of the header: |v0| / D + 1.5 HaltRampS, one scan for the discretisation
    t_bound = max(abs(x) for x in v[0]) / d + 1.5 * HALT_RAMP_S
    assert scans * DT <= t_bound + DT + 1e-9
    assert scans == math.ceil(max(r.duration for r in refs) / DT32 - 1e-3)


def test_jerk_halt_bad_jerk_and_refused_plan(st_module: Any) -> None:
    case = JointCase((0.0, 40.0, 95.0), (100.0, -20.0, 60.0), (150.0,) * 3, (1000.0,) * 3,
                     120.0, 800.0, 6000.0)
    for jerk in (math.nan, -1.0, math.inf):
        sim = GroupSim(case.group())
        sim.assert_rejected(st_module.new_fb("MotionHalt"), BAD_PARAMETER, Execute=True,
                            Deceleration=500.0, Jerk=jerk, CycleTime=DT)
    # a jerk beyond the planner's range: the halt brakes at constant deceleration
    runs = []
    for jerk in (0.0, 1.0e20):
        sim = GroupSim(case.group())
        move, halt = st_module.new_fb("MotionJointMove"), st_module.new_fb("MotionHalt")
        for _ in range(20):
            sim.call(move, **case.inputs())
        while True:
            sim.scan(halt, Execute=True, Deceleration=500.0, Jerk=jerk, CycleTime=DT)
            if not halt.Busy:
                break
        assert halt.Done and not halt.Error
        runs.append(sim.positions)
    assert runs[0] == runs[1]


@pytest.mark.parametrize("acc0", [2400.0, -2400.0, math.nan])
def test_profile4_takes_the_group_acceleration_within_the_limit(st_module: Any,
                                                                acc0: float) -> None:
    """A group acceleration beyond the move's limit (another generator's, noisy or stale)
    starts the move at the limit; a NaN one at 0: Ruckig's plan from that start, no
    braking for an acceleration the move never had."""
    case = JointCase((0.0, 40.0, 95.0), (100.0, -20.0, 60.0), (150.0,) * 3, (1000.0,) * 3,
                     120.0, 800.0, 6000.0, (30.0, -20.0, 10.0), (acc0, acc0, acc0))
    expected_a0 = 0.0 if math.isnan(acc0) else math.copysign(800.0, acc0)
    axes = [AxisCase(ax.p0, ax.v0, expected_a0, ax.pf, 0.0, ax.vmax, ax.amax, ax.jmax)
            for ax in case.axes()]
    ref = ruckig_plan(axes, "Phase")
    sim = GroupSim(case.group())
    fb = st_module.new_fb("MotionJointMove")
    sim.call(fb, **case.inputs())
    assert fb.Busy and fb.Duration == pytest.approx(ref.duration, rel=1e-6)
    p, _, _ = ref.at(DT32)
    assert sim.group["Position"][:3] == pytest.approx(p, abs=1e-4)


def test_profile4_longer_than_two_to_the_24_scans_is_refused(st_module: Any) -> None:
    """At a 0.1 ms cycle 2^24 scans are 1,678 s: a 2,000 s move (inside Ruckig's 7,600 s)
    is refused (8), a 1,500 s one planned."""
    for seconds, ok in ((1500.0, True), (2000.0, False)):
        case = JointCase((0.0,), (100.0,), (150.0,), (1000.0,), f32(100.0 / seconds), 500.0,
                         5000.0)
        sim = GroupSim(case.group())
        fb = st_module.new_fb("MotionJointMove")
        sim.call(fb, **case.inputs(1.0e-4))
        assert fb.Busy == ok and fb.Error == (not ok)
        if not ok:
            assert fb.ErrorId == BAD_PARAMETER


@pytest.mark.parametrize("cycle,v0", [(0.001, 0.5), (0.01, 1.0)],
                         ids=["jerk_that_ends_at_rest", "within_a_scan_from_zero"])
def test_jerk_halt_of_a_joint_braking_hard_never_reverses(st_module: Any, cycle: float,
                                                          v0: float) -> None:
    """A joint at 0.5 (1) deg/s braking at 800 deg/s^2: ramping that to 0 at the 0.02 s
    ramp's jerk would reverse it by 3.6 deg/s. At a 1 ms cycle the halt takes the jerk that
    ends the braking at rest (Ruckig's plan with it); at 10 ms that ramp is shorter than a
    scan and the halt starts from acceleration 0. Never a reversal either way."""
    g = make_group([10.0, 0.0, 0.0], max_vel=150.0, max_acc=1000.0)
    g["Velocity"][0], g["Acceleration"][0] = v0, -800.0
    sim = GroupSim(g)
    halt = st_module.new_fb("MotionHalt")
    a0, js = halt_limits(v0, -800.0, 1000.0, 3000.0, cycle)
    ref = ruckig_plan([AxisCase(10.0, v0, a0, 0.0, 0.0, 1.0, 1000.0, js)], "None", "Velocity")
    assert ref.ok
    cyc32 = f32(cycle)
    k = 0
    while True:
        sim.scan(halt, Execute=True, Deceleration=1.0e6, Jerk=3000.0, CycleTime=cycle)
        k += 1
        p, v, _ = ref.at(k * cyc32)
        assert sim.group["Position"][0] == pytest.approx(p[0], abs=2e-6)
        assert sim.group["Velocity"][0] >= 0.0
        if not halt.Busy:
            break
    assert halt.Done and k <= math.ceil(ref.duration / cyc32 - 1e-3)
