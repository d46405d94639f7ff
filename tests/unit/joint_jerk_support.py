"""Shared by tests/unit/test_motion_joint_jerk.py and bench/joint_move_profiles.py:
MotionJointMove profile-4 moves (a group and the block's inputs), random ones, and their
scan-by-scan comparison with Ruckig (PyPI `ruckig`, phase synchronisation, on exactly the
inputs the block latches: the group's REAL position, velocity and acceleration -- the
acceleration within +/- the joint's limit -- and the REAL limits min(Velocity, MaxVelDeg),
min(Acceleration, MaxAccDeg), Jerk).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Any

import numpy as np
from jerk_support import F32_EPS, AxisCase, ruckig_plan
from motion_support import GroupSim, make_group

DT = 0.01
DT32 = float(np.float32(DT))  # the block's REAL CycleTime: its time is scans * DT32
JERK_PROFILE = 4


def f32(x: float) -> float:
    return float(np.float32(x))


@dataclass(frozen=True)
class JointCase:
    """A group (per joint: position, velocity, acceleration, limits) and a profile-4 move."""

    start: tuple[float, ...]
    target: tuple[float, ...]
    max_vel: tuple[float, ...]
    max_acc: tuple[float, ...]
    velocity: float
    acceleration: float
    jerk: float
    vel0: tuple[float, ...] = ()
    acc0: tuple[float, ...] = ()

    @property
    def joints(self) -> int:
        return len(self.start)

    def group(self) -> dict[str, Any]:
        n = self.joints
        g = make_group(list(self.start), joints=n, lower=-1.0e6, upper=1.0e6)
        g["Limits"]["MaxVelDeg"] = list(self.max_vel) + [1.0] * (6 - n)
        g["Limits"]["MaxAccDeg"] = list(self.max_acc) + [1.0] * (6 - n)
        g["Velocity"] = list(self.vel0 or (0.0,) * n) + [0.0] * (6 - n)
        g["Acceleration"] = list(self.acc0 or (0.0,) * n) + [0.0] * (6 - n)
        return g

    def inputs(self, cycle: float = DT) -> dict[str, Any]:
        return {"Execute": True, "Target": list(self.target) + [0.0] * (6 - self.joints),
                "Profile": JERK_PROFILE, "Velocity": self.velocity,
                "Acceleration": self.acceleration, "Jerk": self.jerk, "CycleTime": cycle}

    def axes(self) -> list[AxisCase]:
        """Ruckig's inputs: what the block latches (REALs; limits capped; acceleration
        within the limit)."""
        out = []
        for j in range(self.joints):
            vmax = f32(min(self.velocity, self.max_vel[j]))
            amax = f32(min(self.acceleration, self.max_acc[j]))
            v0 = f32(self.vel0[j]) if self.vel0 else 0.0
            a0 = f32(self.acc0[j]) if self.acc0 else 0.0
            out.append(AxisCase(f32(self.start[j]), v0, max(-amax, min(amax, a0)),
                                f32(self.target[j]), 0.0, vmax, amax, f32(self.jerk)))
        return out


def random_case(rng: random.Random, kind: str, joints: int = 3) -> JointCase:
    """A move of `kind`: rest (from rest), moving (a start moving and accelerating inside
    the limits), fast (a start faster than the new speed limit: Ruckig brakes first)."""
    max_vel = tuple(f32(rng.uniform(60.0, 200.0)) for _ in range(joints))
    max_acc = tuple(f32(rng.uniform(200.0, 1500.0)) for _ in range(joints))
    velocity = f32(rng.uniform(20.0, 220.0))
    acceleration = f32(rng.uniform(100.0, 1600.0))
    jerk = f32(math.exp(rng.uniform(math.log(500.0), math.log(5.0e4))))
    start = tuple(f32(rng.uniform(-150.0, 150.0)) for _ in range(joints))
    target = tuple(f32(rng.uniform(-150.0, 150.0)) for _ in range(joints))
    if kind == "rest":
        return JointCase(start, target, max_vel, max_acc, velocity, acceleration, jerk)
    vmax = [min(velocity, v) for v in max_vel]
    amax = [min(acceleration, a) for a in max_acc]
    vel0, acc0 = [], []
    for j in range(joints):
        if kind == "fast":
            vel0.append(f32(rng.choice((-1.0, 1.0)) * vmax[j] * rng.uniform(1.1, 1.8)))
            acc0.append(0.0)
            continue
        for _ in range(100):
            v = rng.uniform(-vmax[j], vmax[j])
            a = rng.uniform(-amax[j], amax[j])
            if abs(v + a * abs(a) / (2.0 * jerk)) <= vmax[j]:
                break
        vel0.append(f32(v))
        acc0.append(f32(a))
    return JointCase(start, target, max_vel, max_acc, velocity, acceleration, jerk,
                     tuple(vel0), tuple(acc0))


@dataclass
class Run:
    pos: np.ndarray     # scans x joints
    vel: np.ndarray
    acc: np.ndarray
    duration: float
    scans: int


def run_move(st_module: Any, case: JointCase, cycle: float = DT,
             max_scans: int = 200_000) -> Run:
    sim = GroupSim(case.group())
    fb = st_module.new_fb("MotionJointMove")
    inputs = case.inputs(cycle)
    pos, vel, acc = [], [], []
    n = case.joints
    for k in range(1, max_scans + 1):
        sim.call(fb, **inputs)
        assert not fb.Error, f"ErrorId {fb.ErrorId} for {case}"
        g = sim.group
        pos.append(g["Position"][:n])
        vel.append(g["Velocity"][:n])
        acc.append(g["Acceleration"][:n])
        if not fb.Busy:
            assert fb.Done and g["Owner"] == 0
            return Run(np.array(pos), np.array(vel), np.array(acc), float(fb.Duration), k)
    raise AssertionError("still busy")


def span(ax: AxisCase, duration: float) -> float:
    return max(abs(ax.p0), abs(ax.pf), abs(ax.pf - ax.p0), max(ax.vmax, abs(ax.v0)) * duration,
               1e-30)


def check_against_ruckig(st_module: Any, case: JointCase) -> tuple[float, float]:
    """The per-scan comparison; returns (relative duration error, worst position error as
    a fraction of its float32 tolerance)."""
    axes = case.axes()
    ref = ruckig_plan(axes, "Phase")
    assert ref.ok, ref.result
    run = run_move(st_module, case)
    rel = abs(run.duration - ref.duration) / ref.duration
    assert rel <= 1e-4, (run.duration, ref.duration)
    # the scan that ends it: the first at or past the duration (a thousandth of a scan early)
    assert run.scans == max(1, math.ceil(ref.duration / DT32 - 1e-3))
    worst = 0.0
    for k in range(run.scans):
        p, v, a = ref.at((k + 1) * DT32)
        for j, ax in enumerate(axes):
            tol = F32_EPS * span(ax, ref.duration)
            err = abs(run.pos[k, j] - p[j])
            worst = max(worst, err / tol)
            assert err <= tol, (k, j, run.pos[k, j], p[j], tol)
            if k < run.scans - 1:
                assert abs(run.vel[k, j] - v[j]) <= F32_EPS * 4 * max(ax.vmax, abs(ax.v0))
                assert abs(run.acc[k, j] - a[j]) <= F32_EPS * 4 * ax.amax + 1e-9 * ax.jmax
    assert list(run.pos[-1]) == [f32(t) for t in case.target]
    assert not np.any(run.vel[-1]) and not np.any(run.acc[-1])
    return rel, worst


def check_limits_densely(st_module: Any, case: JointCase, factor: int = 20) -> None:
    """The same move at a cycle `factor` times shorter: every sample's velocity and
    acceleration (the block's outputs) within the limits, the acceleration changing by at
    most the jerk limit, and the finite differences of the positions too (float32 slack)."""
    dt = DT / factor
    run = run_move(st_module, case, dt)
    axes = case.axes()
    inside = all(ax.v0 == 0.0 or abs(ax.v0) <= ax.vmax for ax in axes)
    for j, ax in enumerate(axes):
        v, a = run.vel[:, j], run.acc[:, j]
        rel = 1e-6
        assert np.max(np.abs(a)) <= ax.amax * (1 + rel)
        assert np.max(np.abs(np.diff(a))) <= ax.jmax * dt * (1 + 1e-4) + 4 * F32_EPS * ax.amax
        if inside:
            assert np.max(np.abs(v)) <= ax.vmax * (1 + rel)
            pos = np.concatenate([[ax.p0], run.pos[:, j].astype(np.float64)])
            quantum = float(np.spacing(np.float32(np.max(np.abs(pos))))) / dt
            steps = np.diff(pos) / dt
            assert np.max(np.abs(steps)) <= ax.vmax * (1 + 1e-6) + quantum
            assert (np.max(np.abs(np.diff(steps))) <= ax.amax * dt * (1 + 1e-4) + 2 * quantum)
