"""MotionLinear and the 3-D Bresenham functions (st/MotionLine.st).

References: an exact integer Bresenham written here (each minor coordinate is the
half-up rounding of k * delta_minor / delta_major, in Python integers), the straight line
itself (float64), the float64 reference kinematics of armbench.plant.arm, and document 001's
figure (compensation halves the start-up speed). Figures for the report: run with -s.
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
    BAD_PROFILE,
    DT,
    JOINT_LIMIT,
    NOT_FINITE,
    TOO_MANY_STEPS,
    UNREACHABLE,
    GroupSim,
    make_group,
    run_until_done,
)

from armbench.plant import arm

GEO = arm.DEFAULT_GEOMETRY.as_st()
NAN, INF = float("nan"), float("inf")
P_START = (180.0, -40.0, 150.0)
P_END = (150.3, 60.2, 99.7)
V_LINE = 50.0  # mm/s


def start_group(point: tuple[float, float, float] = P_START, **limits: float) -> GroupSim:
    # float32 from the start, as the PLC holds it: "nothing changed" compares exactly
    q0 = [float(np.float32(q)) for q in arm.inverse(*point)]
    return GroupSim(make_group(q0, **limits))


def line_inputs(target: tuple[float, float, float], method: int, fineness: float = 1.0,
                velocity: float = V_LINE, acceleration: float = 200.0) -> dict[str, Any]:
    return {"Execute": True, "Target": list(target), "Velocity": velocity,
            "Acceleration": acceleration, "LineMethod": method, "Fineness": fineness,
            "ElbowUp": True, "Geometry": GEO, "CycleTime": DT}


def ref_bresenham(deltas: tuple[int, int, int], k: int) -> list[int]:
    """Grid point after k iterations: the major axis at k, minors rounded half up (exact)."""
    d = [abs(x) for x in deltas]
    major = max(d)
    if major == 0:
        return [0, 0, 0]
    return [(2 * k * di + major) // (2 * major) for di in d]


@pytest.mark.parametrize("deltas", [(10, 3, 7), (7, 10, 3), (1, 1, 1), (0, 0, 5), (13, -8, 0),
                                    (-100, 37, -64), (999, 998, 1), (0, 0, 0), (6, 6, 3)])
def test_bresenham_matches_exact_integer_reference(st_module: Any, deltas: tuple[int, int, int]
                                                    ) -> None:
    state = st_module.call("MotionBresenhamStart", *deltas)
    steps = max(abs(x) for x in deltas)
    assert state["Steps"] == steps
    for k in range(1, steps + 2):
        done, outs = st_module.call_full("MotionBresenhamAdvance", Steps=1, State=state)
        state = outs["State"]
        assert done == (1 if k <= steps else 0)
        assert state["Count"] == ref_bresenham(deltas, min(k, steps)), k
    # all at once gives the same end, and never more than Steps iterations
    fresh = st_module.call("MotionBresenhamStart", *deltas)
    done, outs = st_module.call_full("MotionBresenhamAdvance", Steps=10 * steps + 3, State=fresh)
    assert done == steps and outs["State"]["Count"] == [abs(x) for x in deltas]


def line_deviation_per_axis(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Per-axis distance of each point from the line at the same major-axis coordinate."""
    dv = p1 - p0
    major = int(np.argmax(np.abs(dv)))
    m = (points[:, major] - p0[major]) / dv[major]
    ideal = p0 + np.outer(m, dv)
    return np.abs(points - ideal)


@pytest.mark.parametrize(("method", "fineness"), [(0, 1.0), (0, 3.7), (1, 1.0), (1, 0.4)])
def test_bresenham_line_stays_within_half_a_grid_step(st_module: Any, figures: Any,
                                                      method: int, fineness: float) -> None:
    sim = start_group()
    fb = st_module.new_fb("MotionLinear")
    inputs = line_inputs(P_END, method, fineness)
    run_until_done(sim, fb, **inputs)
    assert fb.Done and not fb.Error
    p0 = arm.forward(*sim.start)
    p1 = np.array(P_END)
    want_steps = math.ceil(np.max(np.abs(p1 - p0)) * fineness)
    assert fb.Steps == want_steps
    pts = np.array(sim.cartesian)
    dev = line_deviation_per_axis(pts, p0, p1)
    worst_steps = float(np.max(dev)) * fineness
    figures.case("MotionLinear")
    figures.error("MotionLinear", worst_steps, "grid steps per-axis deviation (methods 0, 1)")
    assert worst_steps <= 0.5 + 1e-3
    # the distance the block reports: Euclidean, at most sqrt(2)/2 of a step
    assert fb.Deviation <= 1e-3
    eucl = np.linalg.norm(np.cross(pts - p0, p1 - p0), axis=1) / np.linalg.norm(p1 - p0)
    assert np.max(eucl) * fineness <= math.sqrt(2) / 2 + 1e-3
    assert pts[-1] == pytest.approx(p1, abs=1e-3)
    # joints are the IK of the Cartesian setpoint (float64 reference IK)
    for q, p in zip(sim.positions[::7], pts[::7], strict=True):
        assert q == pytest.approx(list(arm.inverse(*p)), abs=2e-2)


def window_speed(points: np.ndarray, start: int, width: int) -> float:
    """Mean speed along the line over scans start..start+width (progress along the line's
    direction / time; a staircase of grid steps is longer than the line it follows)."""
    unit = (points[-1] - points[0]) / np.linalg.norm(points[-1] - points[0])
    return float((points[start + width] - points[start]) @ unit / (width * DT))


def run_line(st_module: Any, method: int) -> tuple[GroupSim, Any, np.ndarray]:
    sim = start_group()
    fb = st_module.new_fb("MotionLinear")
    # one grid step per scan for the Bresenham methods: Fineness = 1 / (V dt) along the major
    p0 = arm.forward(*sim.start)
    dv = np.array(P_END) - p0
    length = float(np.linalg.norm(dv))
    fineness = length / (float(np.max(np.abs(dv))) * V_LINE * DT)
    run_until_done(sim, fb, **line_inputs(P_END, method, fineness))
    cart = np.vstack([p0, np.array(sim.cartesian)])
    joints = np.vstack([np.array(sim.start), sim.pos()])
    return sim, fb, np.hstack([cart, joints])


def test_start_speed_seed_compensation_vs_ours(st_module: Any, capsys: Any) -> None:
    """Document 001: compensation halves the start-up speed and leaves a second jump where it
    ends; ours starts from rest and has no jump beyond A * dt."""
    _, fb0, r0 = run_line(st_module, 0)
    _, fb1, r1 = run_line(st_module, 1)
    _, fb2, r2 = run_line(st_module, 2)
    n = fb0.Steps
    window = n // 8  # scans: long enough to average the grid's staircase out
    comp_end = 2 * (n // 4)  # scans of the compensated part (two periods per grid step)
    cart0, cart1, cart2 = r0[:, :3], r1[:, :3], r2[:, :3]
    joint0, joint1, joint2 = r0[:, 3:], r1[:, 3:], r2[:, 3:]

    start0 = window_speed(cart0, 0, window)
    start1 = window_speed(cart1, 0, window)
    start2 = window_speed(cart2, 0, 1)
    # joint angular speed (the seed's measure): the fastest joint over the window
    jstart0 = float(np.max(np.abs(joint0[window] - joint0[0]))) / (window * DT)
    jstart1 = float(np.max(np.abs(joint1[window] - joint1[0]))) / (window * DT)
    jstart2 = float(np.max(np.abs(joint2[1] - joint2[0]))) / DT
    ratio = start1 / start0
    jratio = jstart1 / jstart0
    second_jump1 = (window_speed(cart1, comp_end, window)
                    - window_speed(cart1, comp_end - window, window))
    speeds2 = np.linalg.norm(np.diff(cart2, axis=0), axis=1) / DT
    jump2 = float(np.max(np.abs(np.diff(speeds2))))
    with capsys.disabled():
        print(f"\nline {np.linalg.norm(cart0[-1] - cart0[0]):.1f} mm, {n} grid steps, "
              f"V = {V_LINE} mm/s, dt = {DT * 1000:.0f} ms")
        print(f"start speed: seed {start0:.2f} mm/s, seed+compensation {start1:.2f} mm/s "
              f"(ratio {ratio:.3f}; joints {jratio:.3f}), ours first scan {start2:.2f} mm/s")
        print(f"fastest joint at the start: seed {jstart0:.2f} deg/s, seed+compensation "
              f"{jstart1:.2f} deg/s, ours first scan {jstart2:.3f} deg/s")
        print(f"second jump: seed+compensation {second_jump1:.2f} mm/s; ours largest speed "
              f"change per scan {jump2:.3f} mm/s (A*dt = {200.0 * DT:.2f})")
    assert start0 == pytest.approx(V_LINE, rel=0.1)
    assert ratio == pytest.approx(0.5, abs=0.05)
    assert jratio == pytest.approx(0.5, abs=0.1)
    assert second_jump1 == pytest.approx(V_LINE / 2, rel=0.2)
    assert start2 <= 200.0 * DT * 1.01
    assert jstart2 < 0.05 * jstart0
    assert jump2 <= 200.0 * DT * 1.01
    # ours stays on the line (REAL rounding only) and ends at the target
    assert np.max(np.linalg.norm(np.cross(cart2 - cart2[0], cart2[-1] - cart2[0]), axis=1)
                  / np.linalg.norm(cart2[-1] - cart2[0])) < 1e-3
    # compensation: same path, (N + N/4) periods instead of N
    assert len(cart1) - len(cart0) == n // 4


def test_ours_keeps_joint_limits(st_module: Any) -> None:
    sim = start_group(max_vel=20.0, max_acc=60.0)
    fb = st_module.new_fb("MotionLinear")
    run_until_done(sim, fb, **line_inputs(P_END, 2, velocity=500.0, acceleration=5000.0))
    q = np.vstack([np.array(sim.start), sim.pos()])
    vel = np.diff(q, axis=0) / DT
    assert np.max(np.abs(vel)) <= 20.0
    assert np.max(np.abs(np.diff(vel, axis=0))) / DT <= 60.0
    assert sim.cartesian[-1] == pytest.approx(list(P_END), abs=1e-3)


def test_takeover_from_a_moving_group_brakes_then_draws(st_module: Any) -> None:
    sim = start_group(max_acc=400.0)
    move = st_module.new_fb("MotionJointMove")
    q_target = list(arm.inverse(150.0, 80.0, 120.0)) + [0.0] * 3
    move_in = {"Execute": True, "Target": q_target, "Profile": 2, "Velocity": 60.0,
               "Acceleration": 300.0, "Jerk": 1.0, "CycleTime": DT}
    for _ in range(20):
        sim.scan(move, **move_in)
    line = st_module.new_fb("MotionLinear")
    run_until_done(sim, line, **line_inputs(P_END, 2))
    sim.call(move, **move_in)
    assert move.CommandAborted and line.Done
    vel = np.vstack([np.zeros(3), sim.vel()])
    assert np.max(np.abs(np.diff(vel, axis=0))) <= 400.0 * DT * 1.05
    assert sim.cartesian[-1] == pytest.approx(list(P_END), abs=1e-3)


def test_zero_length_line_done_in_one_scan(st_module: Any) -> None:
    for method in (0, 1, 2):
        sim = start_group()
        fb = st_module.new_fb("MotionLinear")
        sim.scan(fb, **line_inputs(P_START, method))
        assert fb.Done and not fb.Busy and not fb.Error, method
        assert sim.positions[-1] == pytest.approx(sim.start, abs=1e-4)  # float32 of the start


BAD_LINES: list[tuple[str, dict[str, Any], int]] = [
    ("velocity NaN", {"Velocity": NAN}, BAD_PARAMETER),
    ("velocity 0", {"Velocity": 0.0}, BAD_PARAMETER),
    ("velocity -1", {"Velocity": -1.0}, BAD_PARAMETER),
    ("acceleration Inf (ours)", {"Acceleration": INF}, BAD_PARAMETER),
    ("acceleration 0 (ours)", {"Acceleration": 0.0}, BAD_PARAMETER),
    ("fineness 0", {"LineMethod": 0, "Fineness": 0.0}, BAD_PARAMETER),
    ("fineness NaN", {"LineMethod": 1, "Fineness": NAN}, BAD_PARAMETER),
    ("fineness negative", {"LineMethod": 0, "Fineness": -2.0}, BAD_PARAMETER),
    ("cycle time negative", {"CycleTime": -0.01}, BAD_PARAMETER),
    ("method 3", {"LineMethod": 3}, BAD_PROFILE),
    ("target NaN", {"Target": [NAN, 0.0, 100.0]}, NOT_FINITE),
    ("target out of reach", {"Target": [400.0, 0.0, 100.0]}, UNREACHABLE),
    ("geometry", {"Geometry": {**GEO, "A3": -1.0}}, BAD_GEOMETRY),
    ("too many steps", {"LineMethod": 0, "Fineness": 1.0e5}, TOO_MANY_STEPS),
]


@pytest.mark.parametrize(("change", "code"), [(c, k) for _, c, k in BAD_LINES],
                         ids=[n for n, _, _ in BAD_LINES])
def test_bad_line_changes_nothing(st_module: Any, change: dict[str, Any], code: int) -> None:
    start_group().assert_rejected(st_module.new_fb("MotionLinear"), code,
                                  **{**line_inputs(P_END, 2), **change})


def test_joint_limit_on_the_path_is_found_before_moving(st_module: Any) -> None:
    sim = start_group()
    q_end = arm.inverse(*P_END)
    # the base sweeps from about -12.5 to +21.8 deg: a limit at 10 deg lies on the path
    assert q_end[0] > 10.0
    sim.group["Limits"]["UpperDeg"][0] = 10.0
    before = sim.snapshot()
    fb = st_module.new_fb("MotionLinear")
    sim.scan(fb, **line_inputs(P_END, 2))
    assert fb.Error and fb.ErrorId == JOINT_LIMIT and sim.group == before
    two = start_group()
    two.group["Joints"] = 2
    sim.scan(fb, **{**line_inputs(P_END, 2), "Execute": False})
    two.scan(fb, **line_inputs(P_END, 2))
    assert fb.ErrorId == BAD_JOINT_COUNT
