"""st/ServoSlew.st: ServoSlewLimiter under hostile command sequences.

References, restated here from the contract (MOTION-CONTRACT.md) and the file header, never
read from the ST: per scan |step| <= MaxVelDeg * dt and |step change| <= MaxAccDeg * dt^2
(a lowered speed limit is reached by braking: |step| <= max(new limit, |previous step| - D));
a constant command is reached exactly, without overshoot and without limit cycling; from rest
a move of d takes the closed-form minimum time of a trapezoid (d / v + v / a, or
2 sqrt(d / a) for a triangle) within a few scans; NaN/Inf commands stop the joint within the
acceleration limit with ErrorId 3; bad limits, joint counts or cycle times give ErrorId 8.
The bound is checked on the float32 outputs with a tolerance of a few ulps of the output
(the rounding of the position itself, about 1e-5 deg near 100 deg).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

NOT_FINITE, BAD_PARAMETER = 3, 8
VMAX_DEFAULT, AMAX_DEFAULT = 150.0, 1000.0  # the header's MG996R derivation
DT = 0.01
HOSTILE = [math.nan, math.inf, -math.inf, 1.0e30, -1.0e30, 3.4e38, -3.4e38]


def ulp(x: float) -> float:
    return float(np.spacing(np.float32(abs(x) + 1.0)))


class Limiter:
    """A ServoSlewLimiter instance with its history of outputs."""

    def __init__(self, mod: Any, joints: int = 3) -> None:
        self.fb = mod.new_fb("ServoSlewLimiter")
        self.joints = joints
        self.out: list[list[float]] = []
        self.vel: list[list[float]] = []

    def step(self, cmd: Sequence[float], vmax: Sequence[float] | float = VMAX_DEFAULT,
             amax: Sequence[float] | float = AMAX_DEFAULT, dt: float = DT,
             reset: bool = False, joints: int | None = None) -> Any:
        v = [vmax] * 6 if isinstance(vmax, float) else list(vmax)
        a = [amax] * 6 if isinstance(amax, float) else list(amax)
        c = list(cmd) + [0.0] * (6 - len(cmd))
        fb = self.fb(Command=c, Joints=self.joints if joints is None else joints,
                     MaxVelDeg=v, MaxAccDeg=a, CycleTime=dt, Reset=reset)
        self.out.append(list(fb.Output))
        self.vel.append(list(fb.OutputVel))
        return fb


def check_bounds(out: list[list[float]], steps_max: list[list[float]],
                 steps_acc: list[list[float]], joints: int) -> float:
    """Assert the guarantee over a whole history; returns the largest |step| seen.
    steps_max[k][j], steps_acc[k][j]: S and D in force at scan k."""
    worst = 0.0
    for k in range(1, len(out)):
        for j in range(joints):
            step = out[k][j] - out[k - 1][j]
            tol = 4.0 * ulp(max(abs(out[k][j]), abs(out[k - 1][j])))
            worst = max(worst, abs(step))
            prev = out[k - 1][j] - out[k - 2][j] if k >= 2 else 0.0
            cap = max(steps_max[k][j], abs(prev) - steps_acc[k][j])
            assert abs(step) <= cap * (1 + 1e-6) + tol, (k, j, step, cap)
            assert abs(step - prev) <= steps_acc[k][j] * (1 + 1e-6) + 2 * tol, \
                (k, j, step, prev, steps_acc[k][j])
    return worst


def run_to_rest(lim: Limiter, cmd: Sequence[float], scans: int, hold: int = 30,
                **kw: Any) -> int:
    """Hold ``cmd``; returns the scan (from now) at which every joint reached it and then
    stayed on it for ``hold`` more scans (-1: not within ``scans``)."""
    arrived = -1
    for k in range(scans):
        lim.step(cmd, **kw)
        if all(lim.out[-1][j] == np.float32(cmd[j]) for j in range(lim.joints)):
            if arrived < 0:
                arrived = k
            elif k - arrived >= hold:
                return arrived
        else:
            arrived = -1
    return -1


def closed_form_time(d: float, v: float, a: float) -> float:
    """Minimum rest-to-rest time over distance d with speed v and acceleration a."""
    return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)


# ----------------------------------------------------------------------------- from rest
@pytest.mark.parametrize("d", [0.004, 0.05, 0.1, 1.0, 7.3, 22.5, 45.0, 90.0, 179.0])
def test_rest_to_rest_time_no_overshoot(st_module: Any, d: float) -> None:
    lim = Limiter(st_module, joints=1)
    lim.step([10.0], reset=True)
    target = 10.0 + d
    n = run_to_rest(lim, [target], 2000)
    assert n >= 0
    xs = [o[0] for o in lim.out]
    assert all(b >= a for a, b in zip(xs, xs[1:], strict=False)), "not monotone"
    assert max(xs) == np.float32(target), "overshoot"
    t_ref = closed_form_time(d, VMAX_DEFAULT, AMAX_DEFAULT)
    scans = n + 1  # scans that moved
    assert scans * DT >= t_ref - DT  # cannot beat the continuous optimum (by > 1 scan)
    assert scans * DT <= 1.01 * t_ref + 3 * DT  # plan at 99 % of the braking
    check_bounds(lim.out, [[VMAX_DEFAULT * DT]] * len(xs), [[AMAX_DEFAULT * DT * DT]] * len(xs),
                 1)
    assert lim.fb.Limited is False and lim.fb.Error is False


def test_reset_jumps_and_stands(st_module: Any) -> None:
    lim = Limiter(st_module)
    fb = lim.step([12.5, -40.0, 300.0], reset=True)
    assert list(fb.Output[:3]) == [12.5, -40.0, 300.0]
    assert list(fb.OutputVel[:3]) == [0.0, 0.0, 0.0]
    fb = lim.step([12.5, -40.0, 300.0])
    assert list(fb.Output[:3]) == [12.5, -40.0, 300.0] and not fb.Limited


# ----------------------------------------------------------------------------- hostile
def commands() -> Any:
    value = st.one_of(st.floats(-1000.0, 1000.0), st.sampled_from(HOSTILE),
                      st.floats(-1.0e30, 1.0e30))
    return st.lists(st.tuples(value, value, value), min_size=1, max_size=80)


def _pattern(kind: str, n: int, rnd: np.random.Generator) -> list[tuple[float, float, float]]:
    if kind == "reversal":  # full travel back and forth every scan
        return [((-1) ** k * 90.0, (-1) ** (k + 1) * 60.0, (-1) ** k * 1.0e30) for k in range(n)]
    if kind == "nan-burst":
        out = []
        for k in range(n):
            bad = (k // 7) % 2 == 1
            out.append((math.nan if bad else 80.0, -80.0 if not bad else math.inf,
                        float(rnd.uniform(-200, 200))))
        return out
    return [tuple(float(v) for v in rnd.uniform(-500, 500, 3)) for _ in range(n)]  # jumps


@examples(150)
@given(seq=commands(), tail=st.floats(-300.0, 300.0))
def test_hostile_sequences_never_exceed_limits(st_module: Any, seq: list[tuple[float, ...]],
                                               tail: float) -> None:
    lim = Limiter(st_module)
    lim.step([0.0, 0.0, 0.0], reset=True)
    for cmd in seq:
        fb = lim.step(cmd)
        bad = [not (math.isfinite(c) and abs(c) <= 1.0e30) for c in cmd]
        assert fb.Error == any(bad)
        if any(bad):
            assert fb.ErrorId == NOT_FINITE
        assert all(math.isfinite(v) for v in lim.out[-1])
    final = [tail, -tail / 2.0, tail / 3.0]
    n = run_to_rest(lim, final, 1500)
    assert n >= 0, "did not settle on a constant command"
    rows = len(lim.out)
    check_bounds(lim.out, [[VMAX_DEFAULT * DT] * 3] * rows, [[AMAX_DEFAULT * DT * DT] * 3] * rows,
                 3)


@pytest.mark.parametrize("kind", ["reversal", "nan-burst", "jumps"])
def test_patterns_never_exceed_limits(st_module: Any, kind: str) -> None:
    rnd = np.random.default_rng(9)
    lim = Limiter(st_module)
    lim.step([0.0, 0.0, 0.0], reset=True)
    for cmd in _pattern(kind, 400, rnd):
        lim.step(cmd)
    assert run_to_rest(lim, [5.0, 6.0, 7.0], 3000) >= 0
    rows = len(lim.out)
    worst = check_bounds(lim.out, [[VMAX_DEFAULT * DT] * 3] * rows,
                         [[AMAX_DEFAULT * DT * DT] * 3] * rows, 3)
    assert worst <= VMAX_DEFAULT * DT * (1 + 1e-6) + 1e-4


@examples(80)
@given(plan=st.lists(st.tuples(st.floats(-400.0, 400.0), st.floats(20.0, 400.0),
                               st.floats(50.0, 5000.0), st.integers(1, 40)),
                     min_size=1, max_size=8))
def test_limit_changes_mid_move(st_module: Any,
                                plan: list[tuple[float, float, float, int]]) -> None:
    """Limits (and commands) change while the joints move; the acceleration bound holds and
    a lowered speed limit is met by braking."""
    lim = Limiter(st_module)
    lim.step([0.0, 0.0, 0.0], reset=True)
    smax: list[list[float]] = [[VMAX_DEFAULT * DT] * 3]
    sacc: list[list[float]] = [[AMAX_DEFAULT * DT * DT] * 3]
    v = a = 0.0
    for target, v, a, scans in plan:
        for _ in range(scans):
            fb = lim.step([target, -target, 0.5 * target], vmax=v, amax=a)
            assert not fb.Error
            smax.append([v * DT] * 3)
            sacc.append([a * DT * DT] * 3)
    last = plan[-1][0]
    span = max(abs(x) for row in lim.out for x in row) + abs(last)
    peak = max(abs(x) for row in lim.vel for x in row)
    brake = peak * peak / (2.0 * a)  # may run on past the target at the new acceleration
    budget = int((span + brake) / (v * DT) + (peak + 2.0 * v) / (a * DT)) + 100
    n = run_to_rest(lim, [last, -last, 0.5 * last], budget, vmax=v, amax=a)
    assert n >= 0
    rows = len(lim.out)
    smax += [[v * DT] * 3] * (rows - len(smax))
    sacc += [[a * DT * DT] * 3] * (rows - len(sacc))
    check_bounds(lim.out, smax, sacc, 3)


# ----------------------------------------------------------------------------- errors
def test_nan_command_brakes_then_holds(st_module: Any) -> None:
    lim = Limiter(st_module, joints=1)
    lim.step([0.0], reset=True)
    for _ in range(40):
        lim.step([500.0])  # up to full speed
    speed = lim.vel[-1][0]
    assert speed == pytest.approx(VMAX_DEFAULT, rel=1e-5)
    for _ in range(40):
        fb = lim.step([math.nan])
        assert fb.Error and fb.ErrorId == NOT_FINITE
    vels = [v[0] for v in lim.vel[-40:]]
    # brakes at the acceleration limit (10 deg/s per scan) to zero, then stands still
    expected = [max(0.0, speed - AMAX_DEFAULT * DT * (k + 1)) for k in range(40)]
    assert vels == pytest.approx(expected, abs=0.02)
    assert lim.out[-1] == lim.out[-2]


@pytest.mark.parametrize("field,value", [
    ("vmax", math.nan), ("vmax", 0.0), ("vmax", -5.0), ("vmax", 2.0e5), ("amax", math.inf),
    ("amax", 0.0), ("amax", 1.0e8), ("dt", 0.0), ("dt", math.nan), ("dt", 11.0),
    ("joints", 0), ("joints", 7),
])
def test_bad_parameters(st_module: Any, field: str, value: float) -> None:
    lim = Limiter(st_module)
    lim.step([0.0, 0.0, 0.0], reset=True)
    for _ in range(30):
        lim.step([100.0, 100.0, 100.0])
    kw: dict[str, Any] = {field: value}
    for _ in range(60):
        fb = lim.step([100.0, 100.0, 100.0], **kw)
        assert fb.Error and fb.ErrorId == BAD_PARAMETER
    rows = len(lim.out)
    # the last valid limits (the defaults here) still bound every step
    check_bounds(lim.out, [[VMAX_DEFAULT * DT] * 3] * rows,
                 [[AMAX_DEFAULT * DT * DT] * 3] * rows, 3)
    assert all(math.isfinite(x) for row in lim.out for x in row)


def trapezoid(d: float, v: float, a: float, t: float) -> float:
    """Closed-form rest-to-rest trapezoid (triangle when short): position at time t."""
    ta = min(v / a, math.sqrt(d / a))
    vp = a * ta
    tc = (d - a * ta * ta) / vp if vp > 0 else 0.0
    if t <= ta:
        return 0.5 * a * t * t
    if t <= ta + tc:
        return 0.5 * a * ta * ta + vp * (t - ta)
    td = min(t - ta - tc, ta)
    return 0.5 * a * ta * ta + vp * tc + vp * td - 0.5 * a * td * td


@pytest.mark.parametrize("d,v,a", [(90.0, 120.0, 800.0), (3.0, 120.0, 800.0),
                                   (-45.0, 149.0, 990.0)])
def test_feasible_moving_command_is_followed_without_lag(st_module: Any, d: float, v: float,
                                                         a: float) -> None:
    """A plan within the limits (a motion block's) passes through unchanged, every scan."""
    lim = Limiter(st_module, joints=1)
    lim.step([20.0], reset=True)
    sign, dist = math.copysign(1.0, d), abs(d)
    total = closed_form_time(dist, v, a)
    worst = 0.0
    for k in range(1, int(total / DT) + 20):
        cmd = float(np.float32(20.0 + sign * trapezoid(dist, v, a, min(k * DT, total))))
        lim.step([cmd])
        worst = max(worst, abs(lim.out[-1][0] - cmd))
    assert worst <= 1e-4
    assert lim.out[-1][0] == np.float32(20.0 + d)
