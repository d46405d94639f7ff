"""Edge cases of the motion blocks found by an audit: latched command inputs, long slow
trapezoids, the jog at the inner workspace shell and with absurd speeds, a joint limit
between MotionLinear's samples.

References are independent of the ST: the closed-form trapezoid (cruise speed = smaller root
of Vc^2 - A T Vc + A D = 0, float64), finite differences of the scan-by-scan setpoints
against the limits, the float64 reference kinematics of armbench.plant.arm, exact targets.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import DT, JOINT_LIMIT, GroupSim, make_group, run_until_done

from armbench.plant import arm

GEO = arm.DEFAULT_GEOMETRY.as_st()
MAX_VEL, MAX_ACC = 120.0, 400.0


def padded(values: list[float]) -> list[float]:
    return list(values) + [0.0] * (6 - len(values))


def ref_cruise(d: float, a: float, t: float) -> float:
    """Smaller root of Vc^2 - A T Vc + A D = 0 (float64, the stable form)."""
    disc = max((a * t) ** 2 - 4 * a * d, 0.0)
    return 2 * a * d / (a * t + math.sqrt(disc))


def joint_rates(sim: GroupSim, dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """Finite-difference velocity and acceleration of the recorded setpoints (from rest)."""
    pos = np.vstack([np.array(sim.start), sim.pos()])
    vel = np.vstack([np.zeros(pos.shape[1]), np.diff(pos, axis=0) / dt])
    return vel, np.diff(vel, axis=0) / dt


# --- 1. MotionJointMove latches its command inputs ---------------------------------------

@pytest.mark.parametrize("change", ["target", "everything", "rejected_edge"])
def test_joint_move_inputs_latched_at_the_edge(st_module: Any, change: str) -> None:
    """Original code: Target changed to 0 while Execute stays TRUE -> the last scan jumped
    99.99 deg (to the new Target). Now the move ends exactly at the planned target."""
    target = [100.0, -50.0, 60.0]
    sim = GroupSim(make_group([0.0, 0.0, 0.0], max_vel=MAX_VEL, max_acc=MAX_ACC))
    fb = st_module.new_fb("MotionJointMove")
    inputs = {"Execute": True, "Target": padded(target), "Profile": 2, "Velocity": 60.0,
              "Acceleration": 150.0, "Jerk": 2000.0, "CycleTime": DT}
    for k in range(1, 5000):
        if k == 5 and change == "target":
            inputs = {**inputs, "Target": padded([0.0, 0.0, 0.0])}
        elif k == 5 and change == "everything":
            inputs = {**inputs, "Target": padded([-20.0, 10.0, 0.0]), "Profile": 3,
                      "Velocity": 5.0, "Acceleration": 1.0, "Jerk": 3.0, "CycleTime": 0.05}
        elif k == 5 and change == "rejected_edge":
            inputs = {**inputs, "Execute": False}
        elif k == 6 and change == "rejected_edge":
            # a new edge with a target outside the limits: Error, the move goes on
            inputs = {**inputs, "Execute": True, "Target": padded([500.0, 0.0, 0.0])}
        sim.scan(fb, **inputs)
        if k == 6 and change == "rejected_edge":
            assert fb.Error and fb.ErrorId == JOINT_LIMIT and fb.Busy
        if not fb.Busy:
            break
    assert fb.Done
    assert sim.positions[-1] == target  # exactly the planned end point
    vel, acc = joint_rates(sim)
    assert np.max(np.abs(vel)) <= 60.0 * (1 + 1e-4)
    assert np.max(np.abs(acc)) <= 150.0 * (1 + 1e-3) + 0.1


# --- 2. MotionTrapezoidPlan on long, slow moves -------------------------------------------

@pytest.mark.parametrize(("dist", "duration", "acc"), [
    (10.0, 340.0025, 400.0),   # original: Duration 320 s (6 % short), Vc 0.03125
    (0.5, 340.0025, 400.0),    # original: Vc 0, Duration 0, but Valid
    (1.0e-3, 1000.0, 1000.0),
    (170.0, 1.0e4, 4.0e3),
])
def test_trapezoid_plan_long_slow_moves(st_module: Any, dist: float, duration: float,
                                        acc: float) -> None:
    plan = st_module.call("MotionTrapezoidPlan", dist, 0.0, duration, acc)
    assert plan["Valid"]
    vc = ref_cruise(dist, acc, duration)
    assert plan["Vc"] == pytest.approx(vc, rel=2e-5)
    assert plan["Duration"] == pytest.approx(duration, rel=2e-6)
    # the phases add up to the distance, evaluated at the end and mid-cruise
    end = st_module.call("MotionTrapezoidEval", plan, duration)
    mid = st_module.call("MotionTrapezoidEval", plan, duration / 2)
    assert end["Pos"] == pytest.approx(dist, rel=1e-6)
    assert mid["Vel"] == pytest.approx(vc, rel=2e-5)
    assert mid["Pos"] == pytest.approx(dist / 2, rel=1e-4)


def test_synchronised_joint_move_long_and_slow(st_module: Any) -> None:
    """Original code: the 0.5 deg joint stepped 0 -> 0.5 deg in its first scan (5,000
    deg/s^2 against 400) and arrived 20 s before the others."""
    start = [0.0, 0.0, 0.0]
    target = [340.0, 10.0, 0.5]
    sim = GroupSim(make_group(start, lower=-360.0, upper=360.0, max_vel=MAX_VEL,
                              max_acc=MAX_ACC))
    fb = st_module.new_fb("MotionJointMove")
    inputs = {"Execute": True, "Target": padded(target), "Profile": 2, "Velocity": 1.0,
              "Acceleration": MAX_ACC, "Jerk": 1.0, "CycleTime": DT}
    scans = run_until_done(sim, fb, max_scans=40000, **inputs)
    assert fb.Done and sim.positions[-1] == target
    expected = 340.0 / 1.0 + 1.0 / MAX_ACC  # closed-form trapezoid of the lead joint
    assert scans * DT == pytest.approx(expected, abs=2 * DT)
    vel, acc = joint_rates(sim)
    assert np.max(np.abs(acc)) <= MAX_ACC * (1 + 1e-3) + 0.5
    # synchronised: every joint arrives in the last scan, none stands still before
    pos = sim.pos()
    for j in range(3):
        still = np.flatnonzero(np.abs(pos[:, j] - target[j]) > 1e-6)
        assert still[-1] >= scans - 3, f"joint {j + 1} arrived {scans - still[-1]} scans early"
        cruise = ref_cruise(abs(target[j]), MAX_ACC, expected)
        assert np.max(np.abs(vel[:, j])) == pytest.approx(cruise, rel=2e-3, abs=1e-4)


# --- 3. MotionJog at the inner workspace shell --------------------------------------------

@pytest.mark.parametrize(("start", "command"), [
    ((25.0, 0.0, 40.0), (0.0, 0.0, 1.0)),     # up into the shell next to the shoulder
    ((120.0, 0.0, 105.0), (-1.0, 0.0, 0.0)),  # back towards it (shoulder near 180 deg)
    ((60.0, 0.0, 60.0), (-1.0, 0.0, 0.5)),    # towards the base axis
])
def test_jog_brakes_at_the_inner_shell(st_module: Any, start: tuple[float, float, float],
                                       command: tuple[float, float, float]) -> None:
    """Original code: 80 -> 0 mm/s in one scan (the look-ahead solved the stopping point on
    the back branch); the rate limit is Acceleration * dt = 3 mm/s per scan."""
    speed, accel = 80.0, 300.0
    q0 = [float(np.float32(q)) for q in arm.inverse(*start)]
    sim = GroupSim(make_group(q0, lower=-360.0, upper=360.0, max_vel=500.0))
    fb = st_module.new_fb("MotionJog")
    for _ in range(250):
        sim.scan(fb, Enable=True, Command=list(command), MaxSpeed=speed, Acceleration=accel,
                 ElbowUp=True, Geometry=GEO, CycleTime=DT)
    pts = np.vstack([arm.forward(*sim.start), np.array(sim.cartesian)])
    vel = np.vstack([np.zeros(3), np.diff(pts, axis=0) / DT])
    dv = np.linalg.norm(np.diff(vel, axis=0), axis=1)
    assert np.max(dv) <= accel * DT * (1 + 1e-3) + 1e-2
    assert fb.AtLimit and not fb.Error
    assert np.linalg.norm(vel[-1]) < 1e-3  # came to rest
    low, high = arm.reach_limits()
    assert all(low - 1e-3 <= arm.shoulder_distance(*p) <= high + 1e-3 for p in pts)
    # the joints stay the IK of the Cartesian setpoint on the arm's own branch: no flips
    steps = np.abs(np.diff(np.vstack([sim.start, sim.pos()]), axis=0))
    assert np.max(steps) <= 500.0 * DT * (1 + 1e-4)


# --- 5. MotionJog never outputs NaN, whatever MaxSpeed ------------------------------------

@pytest.mark.parametrize("max_speed", [1.0e19, 1.0e20, 1.0e25, 1.0e30])
@pytest.mark.parametrize("command", [(1.0, 0.0, 0.0), (1.0, 0.5, 0.0), (-1.0, -1.0, 1.0)])
def test_jog_absurd_max_speed_never_nan(st_module: Any, max_speed: float,
                                        command: tuple[float, float, float]) -> None:
    """Original code: MaxSpeed 1E20 squared overflowed, Want became NaN and so did the
    setpoints."""
    p0 = (180.0, -40.0, 150.0)
    q0 = [float(np.float32(q)) for q in arm.inverse(*p0)]
    sim = GroupSim(make_group(q0))
    fb = st_module.new_fb("MotionJog")
    for _ in range(30):
        sim.scan(fb, Enable=True, Command=list(command), MaxSpeed=max_speed,
                 Acceleration=300.0, ElbowUp=True, Geometry=GEO, CycleTime=DT)
    values = np.concatenate([sim.pos().ravel(), sim.vel().ravel(), np.ravel(sim.cartesian),
                             sim.group["Acceleration"]])
    assert np.all(np.isfinite(values))
    pts = np.vstack([arm.forward(*sim.start), np.array(sim.cartesian)])
    vel = np.vstack([np.zeros(3), np.diff(pts, axis=0) / DT])
    assert np.max(np.linalg.norm(np.diff(vel, axis=0), axis=1)) <= 3.0 * (1 + 1e-3) + 1e-2


# --- 4. MotionLinear: a joint limit between the samples -----------------------------------

LINE_P0, LINE_P1 = (80.0, -100.0, 160.0), (80.0, 90.0, 160.0)


def shoulder_extremes() -> tuple[float, float]:
    """Highest shoulder angle on the line (float64, 6,401 points) and at the block's 65
    samples."""
    a, b = np.array(LINE_P0), np.array(LINE_P1)
    fine = np.array([arm.inverse(*(a + (b - a) * t))[1] for t in np.linspace(0, 1, 6401)])
    return float(fine.max()), float(fine[::100].max())


def test_line_limit_between_samples_no_stall(st_module: Any) -> None:
    """Original code: the line started, met the shoulder limit between samples and stalled
    one scan (base 35.8 -> 0 -> 33.8 deg/s: 3,580 deg/s^2 against 400). Now the edge finds
    the limit and refuses the line (10 JointLimit) with the group untouched."""
    true_max, sampled_max = shoulder_extremes()
    assert true_max - sampled_max > 3e-3  # the limit lies between the samples
    upper = float(np.float32((true_max + sampled_max) / 2))
    q0 = [float(np.float32(q)) for q in arm.inverse(*LINE_P0)]
    group = make_group(q0, max_vel=MAX_VEL, max_acc=MAX_ACC)
    group["Limits"]["UpperDeg"][1] = upper
    sim = GroupSim(group)
    fb = st_module.new_fb("MotionLinear")
    inputs = {"Execute": True, "Target": list(LINE_P1), "Velocity": 50.0,
              "Acceleration": 200.0, "LineMethod": 2, "Fineness": 1.0, "ElbowUp": True,
              "Geometry": GEO, "CycleTime": DT}
    sim.assert_rejected(fb, JOINT_LIMIT, **inputs)


def test_line_braking_on_error_has_no_stall(st_module: Any) -> None:
    """A limit lowered under a running line (the last resort): the block brakes from the
    last point it wrote. Original code: the point repeated one scan (24.0 -> 0 -> 22.0
    deg/s, 2,400 deg/s^2 against 400)."""
    q0 = [float(np.float32(q)) for q in arm.inverse(*LINE_P0)]
    sim = GroupSim(make_group(q0, max_vel=MAX_VEL, max_acc=MAX_ACC))
    fb = st_module.new_fb("MotionLinear")
    inputs = {"Execute": True, "Target": list(LINE_P1), "Velocity": 50.0,
              "Acceleration": 200.0, "LineMethod": 2, "Fineness": 1.0, "ElbowUp": True,
              "Geometry": GEO, "CycleTime": DT}
    for k in range(2000):
        if k == 100:
            sim.group["Limits"]["UpperDeg"][1] = sim.group["Position"][1] + 0.3
        sim.scan(fb, **inputs)
        if not fb.Busy:
            break
    assert fb.Error and fb.ErrorId == JOINT_LIMIT
    vel, acc = joint_rates(sim)
    assert np.max(np.abs(acc)) <= MAX_ACC * (1 + 1e-3) + 0.5
