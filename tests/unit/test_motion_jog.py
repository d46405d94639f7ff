"""MotionJog (st/MotionJog.st): Cartesian jog with acceleration, workspace and joint limits.

References: the reach shell of document 002's arm (|a3 - a4| .. a3 + a4 from the shoulder
axis, armbench.plant.arm), the group's joint limits, the float64 reference IK, and the
rate limit itself (the tool velocity changes by at most Acceleration * dt per scan).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import (
    BAD_GEOMETRY,
    BAD_JOINT_COUNT,
    BAD_PARAMETER,
    DT,
    NOT_FINITE,
    GroupSim,
    make_group,
)

from armbench.plant import arm

GEO = arm.DEFAULT_GEOMETRY.as_st()
P_START = (180.0, -40.0, 150.0)
SPEED, ACC = 60.0, 300.0
NAN, INF = float("nan"), float("inf")


def start(point: tuple[float, float, float] = P_START, **limits: float) -> GroupSim:
    q0 = [float(np.float32(q)) for q in arm.inverse(*point)]
    return GroupSim(make_group(q0, **limits))


def jog_inputs(command: tuple[float, float, float], enable: bool = True,
               **change: Any) -> dict[str, Any]:
    return {"Enable": enable, "Command": list(command), "MaxSpeed": SPEED,
            "Acceleration": ACC, "ElbowUp": True, "Geometry": GEO, "CycleTime": DT, **change}


def cart_velocities(sim: GroupSim, p0: np.ndarray) -> np.ndarray:
    pts = np.vstack([p0, np.array(sim.cartesian)])
    return np.diff(pts, axis=0) / DT


def assert_smooth(sim: GroupSim, p0: np.ndarray, v0: np.ndarray | None = None) -> None:
    vel = cart_velocities(sim, p0)
    vel = np.vstack([np.zeros(3) if v0 is None else v0, vel])
    steps = np.linalg.norm(np.diff(vel, axis=0), axis=1)
    assert np.all(np.isfinite(sim.pos())) and np.all(np.isfinite(vel))
    assert np.max(steps) <= ACC * DT * (1 + 1e-3) + 1e-3
    assert np.max(np.linalg.norm(vel, axis=1)) <= SPEED * (1 + 1e-4)


def test_jog_stops_at_the_workspace_boundary(st_module: Any) -> None:
    sim = start(lower=-360.0, upper=360.0, max_vel=500.0)
    fb = st_module.new_fb("MotionJog")
    p0 = arm.forward(*sim.start)
    at_limit = []
    for _ in range(400):
        sim.scan(fb, **jog_inputs((1.0, 0.0, 0.0)))
        at_limit.append(bool(fb.AtLimit))
    assert fb.Busy and fb.AtLimit and not fb.Error
    # once it brakes for the boundary (same command) the speed only goes down: no chatter
    first = at_limit.index(True)
    assert all(at_limit[first:])
    speed = np.linalg.norm(cart_velocities(sim, p0), axis=1)
    assert np.all(np.diff(speed[first:]) <= 1e-3)
    pts = np.array(sim.cartesian)
    cp = [arm.shoulder_distance(*p) for p in pts]
    low, high = arm.reach_limits()
    assert max(cp) <= high + 1e-3
    assert cp[-1] > high - 3.0  # it got there, and stopped
    assert np.linalg.norm(pts[-1] - pts[-2]) < 1e-6
    assert pts[-1][1] == pytest.approx(P_START[1], abs=1e-3)  # straight along x
    assert_smooth(sim, p0)
    # the joints are the IK of the Cartesian setpoint all the way
    for q, p in zip(sim.positions[::25], pts[::25], strict=True):
        assert q == pytest.approx(list(arm.inverse(*p)), abs=2e-2)


@pytest.mark.parametrize(("command", "joint", "bound", "side"), [
    ((1.0, 0.0, 0.0), 2, 170.0, "UpperDeg"),   # elbow stretches out
    ((0.0, 1.0, 0.0), 0, 0.0, "UpperDeg"),     # base turns left
    ((0.0, 0.0, -1.0), 1, 40.0, "LowerDeg"),   # shoulder drops
])
def test_jog_stops_before_a_joint_limit(st_module: Any, command: tuple[float, float, float],
                                        joint: int, bound: float, side: str) -> None:
    sim = start()
    sim.group["Limits"][side][joint] = bound
    sign = 1.0 if side == "UpperDeg" else -1.0
    fb = st_module.new_fb("MotionJog")
    p0 = arm.forward(*sim.start)
    for _ in range(500):
        sim.scan(fb, **jog_inputs(command))
    pos = sim.pos()
    assert fb.AtLimit and not fb.Error
    assert np.max(sign * pos[:, joint]) <= sign * bound
    assert sign * pos[-1, joint] > sign * bound - 5.0
    assert np.all(pos >= -170.0) and np.all(pos <= 170.0)
    assert_smooth(sim, p0)
    # back off: the opposite command moves away again
    for _ in range(30):
        sim.scan(fb, **jog_inputs((-command[0], -command[1], -command[2])))
    assert not fb.AtLimit and sign * sim.positions[-1][joint] < sign * pos[-1, joint]


def test_enable_false_brakes_then_done(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJog")
    p0 = arm.forward(*sim.start)
    for _ in range(60):
        sim.scan(fb, **jog_inputs((0.0, 1.0, 0.0)))
    assert sim.group["Owner"] != 0
    scans = 0
    while True:
        sim.scan(fb, **jog_inputs((0.0, 1.0, 0.0), enable=False))
        scans += 1
        if fb.Done:
            break
        assert fb.Busy and scans < 100
    assert scans == math.ceil(SPEED / (ACC * DT) - 1e-6)
    assert sim.group["Owner"] == 0 and sim.velocities[-1] == [0.0, 0.0, 0.0]
    assert_smooth(sim, p0)
    sim.scan(fb, **jog_inputs((0.0, 1.0, 0.0), enable=False))
    assert not fb.Done


def test_command_clamped_and_nan_is_zero_with_error(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJog")
    p0 = arm.forward(*sim.start)
    for _ in range(40):
        sim.scan(fb, **jog_inputs((0.0, 0.0, -7.0)))
    vel = cart_velocities(sim, p0)
    assert vel[-1] == pytest.approx([0.0, 0.0, -SPEED], abs=1e-2)
    for _ in range(40):
        sim.scan(fb, **jog_inputs((0.0, 0.0, NAN)))
        assert fb.Error and fb.ErrorId == NOT_FINITE and fb.Busy
    vel = cart_velocities(sim, p0)
    assert np.linalg.norm(vel[-1]) < 1e-6
    sim.scan(fb, **jog_inputs((0.0, 0.0, 0.5)))
    assert not fb.Error
    # diagonal: the vector is limited to MaxSpeed
    for _ in range(60):
        sim.scan(fb, **jog_inputs((1.0, 1.0, 1.0)))
    vel = cart_velocities(sim, p0)
    assert np.linalg.norm(vel[-1]) == pytest.approx(SPEED, rel=1e-3)
    assert_smooth(sim, p0)


@pytest.mark.parametrize(("change", "code"), [
    ({"MaxSpeed": 0.0}, BAD_PARAMETER), ({"MaxSpeed": NAN}, BAD_PARAMETER),
    ({"Acceleration": -1.0}, BAD_PARAMETER), ({"Acceleration": INF}, BAD_PARAMETER),
    ({"CycleTime": 0.0}, BAD_PARAMETER), ({"Geometry": {**GEO, "A4": 0.0}}, BAD_GEOMETRY),
])
def test_bad_parameters_change_nothing(st_module: Any, change: dict[str, Any],
                                       code: int) -> None:
    start().assert_rejected(st_module.new_fb("MotionJog"), code,
                            **jog_inputs((1.0, 0.0, 0.0), **change))
    two = start()
    two.group["Joints"] = 2
    fb2 = st_module.new_fb("MotionJog")
    two.scan(fb2, **jog_inputs((1.0, 0.0, 0.0)))
    assert fb2.ErrorId == BAD_JOINT_COUNT


def test_jog_takes_over_a_moving_group_without_a_jump(st_module: Any) -> None:
    sim = start(max_acc=400.0)
    move = st_module.new_fb("MotionJointMove")
    q_target = list(arm.inverse(150.0, 80.0, 120.0)) + [0.0] * 3
    move_in = {"Execute": True, "Target": q_target, "Profile": 2, "Velocity": 20.0,
               "Acceleration": 100.0, "Jerk": 1.0, "CycleTime": DT}
    for _ in range(30):
        sim.scan(move, **move_in)
    v_before = np.array(sim.velocities[-1])
    jog = st_module.new_fb("MotionJog")
    for _ in range(50):
        sim.scan(jog, **jog_inputs((0.0, 0.0, 0.0)))
    sim.call(move, **move_in)
    assert move.CommandAborted and jog.Busy
    vel = sim.vel()
    # first jog scan continues the joint velocity (within the jog's own rate limit)
    assert np.max(np.abs(vel[30] - v_before)) < 5.0
    # and the jog brakes the tool to rest with no jump
    assert np.max(np.abs(np.diff(vel[29:], axis=0))) < 5.0
    assert np.max(np.abs(vel[-1])) < 1e-3
