"""st/MotionProfiles.st against closed forms and the Robotics Toolbox.

References: closed forms written here in float64 from the kinematics of constant
acceleration (not from the ST), and roboticstoolbox-python's `trapezoidal_func` and
`quintic_func` (trajectory tools), evaluated side by side with the ST profile for the same
distance, duration and cruise speed. The ST computes in REAL (float32).
Run with -s to see the worst errors.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

rtb_traj = pytest.importorskip("roboticstoolbox.tools.trajectory")

NAN, INF = float("nan"), float("inf")
POS_TOL_DEG = 1e-3  # the bound against the Robotics Toolbox (docs/motion.md)

# (distance deg, initial velocity deg/s, vmax deg/s, acc deg/s^2): long, short (triangle),
# negative, blends from a moving start (faster, slower than the cruise speed)
TRAPEZOIDS = [
    (90.0, 0.0, 60.0, 120.0),
    (5.0, 0.0, 60.0, 120.0),
    (-70.0, 0.0, 45.0, 200.0),
    (120.0, 30.0, 60.0, 100.0),
    (120.0, 80.0, 60.0, 100.0),
    (-40.0, -20.0, 90.0, 300.0),
    (10.0, 40.0, 60.0, 100.0),
    (0.25, 0.0, 60.0, 120.0),
]


def point(res: dict[str, float]) -> tuple[float, float, float]:
    return res["Pos"], res["Vel"], res["Acc"]


def ref_trapezoid_min_time(d: float, v0: float, vmax: float, a: float) -> float | None:
    """Shortest rest-at-the-end time from phase distances (float64, written independently)."""
    dist, u = abs(d), (v0 if d >= 0 else -v0)
    if u < 0 and dist > 0:
        return None
    u = abs(u)
    if u * u / (2 * a) > dist * 1.0001:
        return None
    if dist == 0:
        return 0.0
    if u <= vmax:
        # triangle peak from (p^2 - u^2)/2a + p^2/2a = d
        peak = math.sqrt(a * dist + u * u / 2)
        if peak <= vmax:
            return (peak - u) / a + peak / a
        cruise = dist - (vmax**2 - u**2) / (2 * a) - vmax**2 / (2 * a)
        return (vmax - u) / a + vmax / a + cruise / vmax
    down = (u * u - vmax * vmax) / (2 * a) + vmax * vmax / (2 * a)
    if down > dist:
        return None
    return (u - vmax) / a + vmax / a + (dist - down) / vmax


def test_const_speed_closed_form(st_module: Any) -> None:
    for dist, speed in ((90.0, 30.0), (-45.0, 15.0), (0.0, 10.0)):
        for t in np.linspace(-0.5, abs(dist) / speed + 1.0, 41):
            res = point(st_module.call("MotionConstSpeedEval", dist, speed, float(t)))
            moved = min(speed * max(t, 0.0), abs(dist))
            assert res[0] == pytest.approx(math.copysign(moved, dist), abs=1e-4)
            moving = 0 < t < abs(dist) / speed
            assert res[1] == pytest.approx(math.copysign(speed, dist) if moving else 0.0)


def test_const_speed_bad_input_is_start(st_module: Any) -> None:
    for args in ((NAN, 1.0, 1.0), (10.0, 0.0, 1.0), (10.0, -5.0, 1.0), (10.0, INF, 1.0),
                 (10.0, 1.0, NAN)):
        assert point(st_module.call("MotionConstSpeedEval", *args)) == (0.0, 0.0, 0.0)


def test_sync_speed_makes_all_arrive_together(st_module: Any) -> None:
    dists = [80.0, -20.0, 5.0, 0.0]
    lead = max(dists, key=abs)
    speeds = [st_module.call("MotionSyncSpeed", d, lead, 40.0) for d in dists]
    for d, v in zip(dists, speeds, strict=True):
        if d:
            assert abs(d) / v == pytest.approx(abs(lead) / 40.0, rel=1e-6)
        else:
            assert v == 0.0
    assert st_module.call("MotionSyncSpeed", 5.0, 0.0, 40.0) == 0.0
    assert st_module.call("MotionSyncSpeed", NAN, 10.0, 40.0) == 0.0


def test_stop_closed_form(st_module: Any) -> None:
    for v0, dec in ((50.0, 100.0), (-30.0, 60.0), (0.0, 10.0)):
        t_stop = abs(v0) / dec
        for t in np.linspace(0.0, t_stop + 0.3, 31):
            tc = min(float(t), t_stop)
            want_pos = v0 * tc - math.copysign(0.5 * dec * tc * tc, v0)
            pos, vel, _ = point(st_module.call("MotionStopEval", v0, dec, float(t)))
            assert pos == pytest.approx(want_pos, abs=1e-4)
            assert vel == pytest.approx(v0 - math.copysign(dec * tc, v0), abs=1e-4)
    assert point(st_module.call("MotionStopEval", 10.0, 0.0, 1.0)) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(("dist", "v0", "vmax", "acc"), TRAPEZOIDS)
def test_trapezoid_min_time_closed_form(st_module: Any, dist: float, v0: float, vmax: float,
                                        acc: float) -> None:
    want = ref_trapezoid_min_time(dist, v0, vmax, acc)
    got = st_module.call("MotionTrapezoidMinTime", dist, v0, vmax, acc)
    if want is None:
        assert got == -1.0
    else:
        assert got == pytest.approx(want, rel=1e-5, abs=1e-6)


def test_trapezoid_infeasible_cases(st_module: Any) -> None:
    call = st_module.call
    assert call("MotionTrapezoidMinTime", 10.0, -5.0, 60.0, 100.0) == -1.0  # moving away
    assert call("MotionTrapezoidMinTime", 1.0, 60.0, 60.0, 100.0) == -1.0  # cannot brake
    assert call("MotionTrapezoidMinTime", 0.0, 0.0, 60.0, 100.0) == 0.0
    for bad in ((NAN, 0.0, 1.0, 1.0), (1.0, 0.0, 0.0, 1.0), (1.0, 0.0, 1.0, -1.0),
                (1.0, INF, 1.0, 1.0)):
        assert call("MotionTrapezoidMinTime", *bad) == -1.0
        plan = call("MotionTrapezoidPlan", bad[0], bad[1], 1.0, bad[3])
        if not (math.isfinite(bad[0]) and math.isfinite(bad[1]) and bad[3] > 0):
            assert plan["Valid"] is False


@pytest.mark.parametrize(("dist", "vmax", "acc"), [(90.0, 60.0, 120.0), (-70.0, 45.0, 200.0),
                                                   (5.0, 60.0, 120.0), (170.0, 30.0, 20.0)])
@pytest.mark.parametrize("stretch", [1.0, 1.3, 2.5])
def test_trapezoid_rest_to_rest_vs_robotics_toolbox(st_module: Any, figures: Any, dist: float,
                                                    vmax: float, acc: float,
                                                    stretch: float) -> None:
    """Same distance, duration and cruise speed as the toolbox: positions within 1e-3 deg."""
    t_min = st_module.call("MotionTrapezoidMinTime", dist, 0.0, vmax, acc)
    duration = t_min * stretch
    plan = st_module.call("MotionTrapezoidPlan", dist, 0.0, duration, acc)
    assert plan["Valid"] and plan["Duration"] == pytest.approx(duration, rel=1e-5)
    assert plan["Vc"] <= vmax * (1 + 1e-5)
    q0 = 10.0
    # a triangle's peak is 2D/T exactly; float32 may land a hair above, which the toolbox rejects
    cruise = min(plan["Vc"], 2 * abs(dist) / plan["Duration"])
    ref = rtb_traj.trapezoidal_func(q0, q0 + dist, plan["Duration"], math.copysign(cruise, dist))
    # the toolbox's own blend time, from T and V only, equals the ST's ramp time
    assert float(ref.tb) == pytest.approx(plan["Vc"] / acc, rel=1e-4)
    worst = 0.0
    for t in np.linspace(0.0, plan["Duration"], 201):
        pos, vel, _ = point(st_module.call("MotionTrapezoidEval", plan, float(t)))
        q, qd, _ = ref(float(t))
        worst = max(worst, abs(q0 + pos - float(q)))
        assert vel == pytest.approx(float(qd), abs=1e-3 * vmax + 1e-3)
    figures.case("MotionTrapezoidEval")
    figures.error("MotionTrapezoidEval", worst, "deg vs roboticstoolbox trapezoidal")
    assert worst <= POS_TOL_DEG


@pytest.mark.parametrize(("dist", "v0", "vmax", "acc"),
                         [c for c in TRAPEZOIDS if ref_trapezoid_min_time(*c) is not None])
@pytest.mark.parametrize("stretch", [1.0, 1.7])
def test_trapezoid_from_velocity_integrates(st_module: Any, dist: float, v0: float,
                                            vmax: float, acc: float, stretch: float) -> None:
    """Blend profile: starts at V0, ends at rest at D after exactly T, |a| <= A, speed within
    max(VMax, |V0|), and position is the integral of the velocity (trapezoid rule, float64)."""
    t_min = ref_trapezoid_min_time(dist, v0, vmax, acc)
    assert t_min is not None
    duration = t_min * stretch
    plan = st_module.call("MotionTrapezoidPlan", dist, v0, duration, acc)
    assert plan["Valid"]
    assert plan["Duration"] == pytest.approx(duration, rel=1e-4, abs=1e-5)
    ts = np.linspace(0.0, plan["Duration"], 2001)
    pts = np.array([point(st_module.call("MotionTrapezoidEval", plan, float(t))) for t in ts])
    assert pts[0, 0] == 0.0 and pts[0, 1] == pytest.approx(v0, abs=1e-5)
    assert pts[-1, 0] == pytest.approx(dist, abs=1e-5) and pts[-1, 1] == 0.0
    assert np.max(np.abs(pts[:, 2])) <= acc * (1 + 1e-6)
    assert np.max(np.abs(pts[:, 1])) <= max(vmax, abs(v0)) * (1 + 1e-5)
    integral = np.concatenate([[0.0], np.cumsum(np.diff(ts) * (pts[1:, 1] + pts[:-1, 1]) / 2)])
    assert np.max(np.abs(integral - pts[:, 0])) < 1e-3 * max(1.0, abs(dist))
    # velocity changes no faster than A between samples (no jump anywhere)
    assert np.max(np.abs(np.diff(pts[:, 1]))) <= acc * (ts[1] - ts[0]) * 1.001 + 1e-4


@pytest.mark.parametrize(("dist", "v0", "duration"), [(90.0, 0.0, 2.0), (-30.0, 0.0, 0.7),
                                                      (50.0, 40.0, 2.5), (-80.0, -10.0, 3.0),
                                                      (1e-3, 0.0, 0.05)])
def test_quintic_vs_robotics_toolbox(st_module: Any, figures: Any, dist: float, v0: float,
                                     duration: float) -> None:
    q0 = -20.0
    ref = rtb_traj.quintic_func(q0, q0 + dist, duration, qd0=v0, qdf=0.0)
    worst = 0.0
    for t in np.linspace(0.0, duration, 201):
        pos, vel, acc = point(st_module.call("MotionQuinticEval", dist, v0, duration, float(t)))
        q, qd, qdd = ref(float(t))
        worst = max(worst, abs(q0 + pos - float(q)))
        assert vel == pytest.approx(float(qd), abs=1e-4 * (abs(dist) / duration + abs(v0)) + 1e-5)
        assert acc == pytest.approx(float(qdd), abs=1e-3 * (abs(dist) / duration**2 + 1.0))
    figures.case("MotionQuinticEval")
    figures.error("MotionQuinticEval", worst, "deg vs roboticstoolbox quintic")
    assert worst <= POS_TOL_DEG


@pytest.mark.parametrize(("dist", "vmax", "amax", "jmax"),
                         [(90.0, 60.0, 120.0, 1000.0), (90.0, 600.0, 120.0, 1000.0),
                          (90.0, 600.0, 1200.0, 500.0), (-10.0, 60.0, 120.0, 1000.0)])
def test_quintic_min_time_is_tight(st_module: Any, dist: float, vmax: float, amax: float,
                                   jmax: float) -> None:
    """The shortest time keeps the toolbox's quintic within every limit and meets one of them."""
    t_min = st_module.call("MotionQuinticMinTime", dist, vmax, amax, jmax)
    ts = np.linspace(0.0, t_min, 20001)
    q, qd, qdd = rtb_traj.quintic_func(0.0, dist, t_min)(ts)
    jerk = np.gradient(qdd, ts)
    ratios = [np.max(np.abs(qd)) / vmax, np.max(np.abs(qdd)) / amax, np.max(np.abs(jerk)) / jmax]
    assert max(ratios) == pytest.approx(1.0, abs=2e-3)
    assert st_module.call("MotionQuinticMinTime", 0.0, vmax, amax, jmax) == 0.0
    assert st_module.call("MotionQuinticMinTime", dist, vmax, 0.0, jmax) == -1.0
    assert st_module.call("MotionQuinticMinTime", NAN, vmax, amax, jmax) == -1.0


@pytest.mark.parametrize(("dist", "v0", "duration"),
                         [(90.0, 0.0, 3.0), (90.0, 0.0, 1.0), (50.0, 55.0, 1.5),
                          (50.0, 55.0, 0.9), (20.0, 55.0, 3.0), (-60.0, 10.0, 2.0)])
def test_quintic_fits_agrees_with_dense_check(st_module: Any, dist: float, v0: float,
                                              duration: float) -> None:
    vmax, amax, jmax = 60.0, 200.0, 2000.0
    ts = np.linspace(0.0, duration, 20001)
    q, qd, qdd = rtb_traj.quintic_func(0.0, dist, duration, qd0=v0)(ts)
    jerk = np.gradient(qdd, ts)
    cap = max(vmax, abs(v0)) * (1 + 1e-5)
    no_reversal = np.min(np.sign(dist) * qd) >= -1e-6 * vmax
    dense_ok = (np.max(np.abs(qd)) <= cap and np.max(np.abs(qdd)) <= amax
                and np.max(np.abs(jerk)) <= jmax and no_reversal)
    # every peak at most 97 % of its limit (the ST's own margin): nothing borderline to refuse
    clear = (np.max(np.abs(qd)) <= 0.97 * cap and np.max(np.abs(qdd)) <= 0.97 * amax
             and np.max(np.abs(jerk)) <= 0.97 * jmax and no_reversal)
    fits = st_module.call("MotionQuinticFits", dist, v0, duration, vmax, amax, jmax)
    # the ST keeps 3 % in hand for peaks between its 65 samples: it may refuse a borderline
    # profile, never accept one that breaks a limit
    if fits:
        assert dense_ok
    # ... and never refuse one that is clear of every limit (90/0/3 s and 50/55/1.5 s are)
    if clear:
        assert fits is True, f"a profile within 97 % of every limit refused: {dist, v0, duration}"
    assert st_module.call("MotionQuinticFits", dist, v0, duration, vmax, NAN, jmax) is False
