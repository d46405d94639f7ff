"""Property tests of the jerk-limited generator's POUs (st/MotionJerk*.st), each called by name.

Inputs drawn by hypothesis: limits over four decades with free time constants, starts inside
and beyond the limits, target velocities, durations at and beyond the shortest. References,
all independent of the ST: numpy (cube roots, polynomial values, derivatives and roots),
float64 integration here of a profile's phase times and jerks from its start (where it ends,
its largest velocity and acceleration), Ruckig (PyPI `ruckig`) for the shortest durations,
and the rules of the headers restated in Python (which input is refused with which ErrorId).

The shape functions of steps 1 and 2 (MotionJerkS1*, MotionJerkS2*, MotionJerkVelS*) propose
profiles; the property of each is that whatever it accepts is right: it reaches the target
(after exactly the requested duration, for step 2), within the limits, and (step 1) never
faster than Ruckig's time-optimal duration.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from jerk_support import (
    AxisCase,
    StRunner,
    extremes,
    inside_at_start,
    jump_problems,
    limit_violations,
    ruckig_plan,
)

hypothesis = pytest.importorskip("hypothesis")
ruckig = pytest.importorskip("ruckig")
from hypothesis import assume, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

EPS = 2.220446049250313e-16


# ----------------------------------------------------------------------------- strategies


@st.composite
def limits(draw: Any) -> tuple[float, float, float]:
    vmax = 10.0 ** draw(st.floats(-2.0, 2.0))
    amax = vmax / 10.0 ** draw(st.floats(-2.3, 0.7))
    jmax = amax / 10.0 ** draw(st.floats(-2.7, 0.3))
    return vmax, amax, jmax


FRACTION = st.one_of(st.floats(-1.0, 1.0), st.sampled_from([0.0, 1.0, -1.0, 0.5, -0.5]))


@st.composite
def axis_cases(draw: Any, moving: bool = True, target_velocity: bool = True,
               outside: bool = False) -> AxisCase:
    """A single-axis case: a start inside the limits (not crossing the velocity limit
    inevitably) unless `outside`, any displacement from 0 to 10 typical moves."""
    vmax, amax, jmax = draw(limits())
    scale = vmax * (vmax / amax + amax / jmax)
    p0 = draw(st.floats(-10.0, 10.0)) * scale
    d = draw(st.one_of(st.floats(-10.0, 10.0), st.sampled_from([0.0, 1e-9, -1e-6])))
    v0 = a0 = vf = 0.0
    if moving:
        k = 1.6 if outside else 1.0
        v0 = draw(FRACTION) * vmax * k
        a0 = draw(FRACTION) * amax * k
        if not outside and abs(v0 + a0 * abs(a0) / (2.0 * jmax)) > vmax:
            a0 = 0.0
    if target_velocity:
        vf = draw(FRACTION) * vmax
    return AxisCase(p0, v0, a0, p0 + d * scale, vf, vmax, amax, jmax)


def boundary(st_module: Any, case: AxisCase, velocity: bool = False) -> dict[str, Any]:
    """The working profile steps 1 and 2 start from: MotionJerkBrake's, with the target."""
    _, outs = st_module.call_full(
        "MotionJerkBrake", VelocityInterface=velocity, P0=case.p0, V0=case.v0, A0=case.a0,
        VMax=case.vmax, VMin=case.v_lo, AMax=case.amax, AMin=case.a_lo, JMax=case.jmax,
        Prof={})
    prof: dict[str, Any] = outs["Prof"]
    prof.update(Pf=case.pf, Vf=case.vf, Af=case.af)
    return prof


def step1_data(prof: dict[str, Any], jmax: float) -> dict[str, float]:
    v0, a0, vf, af = prof["V"][0], prof["A"][0], prof["Vf"], prof["Af"]
    return {"v0": v0, "a0": a0, "vf": vf, "af": af, "pd": prof["Pf"] - prof["P"][0],
            "v0_v0": v0 * v0, "vf_vf": vf * vf, "a0_a0": a0 * a0, "a0_p3": a0 ** 3,
            "a0_p4": a0 ** 4, "af_af": af * af, "af_p3": af ** 3, "af_p4": af ** 4,
            "jMax_jMax": jmax * jmax}


def step2_data(prof: dict[str, Any], tf: float, jmax: float) -> dict[str, float]:
    v0, a0, vf, af = prof["V"][0], prof["A"][0], prof["Vf"], prof["Af"]
    pd = prof["Pf"] - prof["P"][0]
    return {"v0": v0, "a0": a0, "tf": tf, "vf": vf, "af": af, "pd": pd, "tf_tf": tf * tf,
            "tf_p3": tf ** 3, "tf_p4": tf ** 4, "vd": vf - v0, "vd_vd": (vf - v0) ** 2,
            "ad": af - a0, "ad_ad": (af - a0) ** 2, "v0_v0": v0 * v0, "vf_vf": vf * vf,
            "a0_a0": a0 * a0, "a0_p3": a0 ** 3, "a0_p4": a0 ** 4, "a0_p5": a0 ** 5,
            "a0_p6": a0 ** 6, "af_af": af * af, "af_p3": af ** 3, "af_p4": af ** 4,
            "af_p5": af ** 5, "af_p6": af ** 6, "jMax_jMax": jmax * jmax,
            "g1": -pd + tf * v0, "g2": -2.0 * pd + tf * (v0 + vf)}


def directions(case: AxisCase) -> list[dict[str, float]]:
    """The limit sets the shape functions are called with: up, and down (swapped, negated)."""
    return [dict(vMax=case.vmax, vMin=case.v_lo, aMax=case.amax, aMin=case.a_lo,
                 jMax=case.jmax),
            dict(vMax=case.v_lo, vMin=case.vmax, aMax=case.a_lo, aMin=case.amax,
                 jMax=-case.jmax)]


def assert_reaches(prof: dict[str, Any], case: AxisCase, duration: float | None = None,
                   position: bool = True) -> None:
    """Recomputed from the case's start (jerk_support.extremes): continuous, ends at the
    target (and after `duration`), within the limits when the start is inside them."""
    ex = extremes(prof, case.p0, case.v0, case.a0)
    assert not jump_problems(case, ex, ex.duration)
    scale = max(abs(case.p0), abs(case.pf), 1.0)
    if position:
        assert ex.end[0] == pytest.approx(case.pf, abs=1e-7 * scale)
    assert ex.end[1] == pytest.approx(case.vf, abs=1e-7 * max(case.vmax, 1.0))
    assert ex.end[2] == pytest.approx(case.af, abs=1e-7 * max(case.amax, 1.0))
    if duration is not None:
        assert ex.duration == pytest.approx(duration, rel=1e-9, abs=1e-12)
    if position and inside_at_start(case):
        assert not limit_violations(case, ex)
    else:
        assert ex.a_hi <= case.amax * (1 + 1e-9) + 1e-12 or prof["BrakeDuration"] > 0.0
        assert ex.j_abs <= case.jmax * (1 + 1e-12)


# ----------------------------------------------------------------------------- roots


@given(st.one_of(st.floats(-1e30, 1e30), st.sampled_from([0.0, -0.0, 1e-300, -8.0, 27.0])))
def test_cbrt_is_numpy_cbrt(st_module: Any, x: float) -> None:
    got = st_module.call("MotionJerkCbrt", x)
    want = float(np.cbrt(x))
    assert got == pytest.approx(want, rel=4 * EPS, abs=0.0)


@given(st.lists(st.one_of(st.floats(-10.0, 10.0), st.just(math.nan)), max_size=7))
def test_roots_insert_keeps_the_nonnegative_ascending(st_module: Any, xs: list[float]) -> None:
    roots = {"Count": 0, "X": [0.0] * 4}
    kept = []
    for x in xs:
        added, outs = st_module.call_full("MotionJerkRootsInsert", X=x, Roots=roots)
        roots = outs["Roots"]
        should = x >= 0.0 and len(kept) < 4
        assert added is should
        if should:
            kept.append(x)
    assert roots["Count"] == len(kept)
    assert roots["X"][:len(kept)] == sorted(kept)


def _nonneg_real_roots(coeffs: list[float]) -> list[float]:
    return sorted(float(r.real) for r in np.roots(coeffs)
                  if abs(r.imag) < 1e-9 * max(1.0, abs(r)) and r.real >= 0.0)


@given(st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3), st.floats(0.1, 10.0),
       st.booleans())
def test_cubic_roots_are_numpy_roots(st_module: Any, rs: list[float], a: float,
                                     complex_pair: bool) -> None:
    """A cubic built from its roots (or one root and a complex pair): the ST's non-negative
    roots are numpy's, when the roots are well apart (a double root is ill-conditioned)."""
    if complex_pair:
        coeffs = list(a * np.poly([rs[0], complex(rs[1], 1.0 + abs(rs[2])),
                                   complex(rs[1], -1.0 - abs(rs[2]))]).real)
        expect = [rs[0]] if rs[0] >= 0.0 else []
        assume(abs(rs[0]) > 1e-6)
    else:
        assume(min(abs(rs[i] - rs[j]) for i in range(3) for j in range(i)) > 1e-2)
        assume(all(abs(r) > 1e-6 for r in rs))
        coeffs = list(a * np.poly(rs))
        expect = sorted(r for r in rs if r >= 0.0)
    res = st_module.call("MotionJerkCubicRoots", *coeffs)
    got = res["X"][:res["Count"]]
    assert got == sorted(got)
    assert len(got) == len(expect), (got, expect, _nonneg_real_roots(coeffs))
    assert got == pytest.approx(expect, abs=1e-7)


@given(st.lists(st.floats(-5.0, 5.0), min_size=4, max_size=4), st.booleans())
def test_quartic_roots_are_numpy_roots(st_module: Any, rs: list[float],
                                       complex_pair: bool) -> None:
    if complex_pair:
        roots: list[complex] = [rs[0], rs[1], complex(rs[2], 0.5 + abs(rs[3])),
                                complex(rs[2], -0.5 - abs(rs[3]))]
        assume(abs(rs[0] - rs[1]) > 1e-2 and abs(rs[0]) > 1e-6 and abs(rs[1]) > 1e-6)
        expect = sorted(r for r in rs[:2] if r >= 0.0)
    else:
        roots = list(rs)
        assume(min(abs(rs[i] - rs[j]) for i in range(4) for j in range(i)) > 5e-2)
        assume(all(abs(r) > 1e-6 for r in rs))
        expect = sorted(r for r in rs if r >= 0.0)
    coeffs = list(np.poly(roots).real)
    res = st_module.call("MotionJerkQuarticRoots", *coeffs[1:])
    got = res["X"][:res["Count"]]
    assert got == sorted(got)
    assert len(got) == len(expect), (got, expect)
    assert got == pytest.approx(expect, abs=1e-6)


POLY = st.lists(st.floats(-100.0, 100.0), min_size=1, max_size=7)


def _poly(coeffs: list[float]) -> dict[str, Any]:
    return {"N": len(coeffs), "C": list(coeffs) + [0.0] * (7 - len(coeffs))}


@given(POLY, st.one_of(st.floats(-3.0, 3.0), st.sampled_from([0.0, 1.0, 1e-17])))
def test_poly_eval_is_numpy_polyval(st_module: Any, coeffs: list[float], x: float) -> None:
    got = st_module.call("MotionJerkPolyEval", Poly=_poly(coeffs), X=x)
    want = float(np.polyval(coeffs, x)) if abs(x) >= EPS else coeffs[-1]
    scale = sum(abs(c) * abs(x) ** k for k, c in enumerate(reversed(coeffs)))
    assert got == pytest.approx(want, abs=1e-13 * max(scale, 1.0))
    assert st_module.call("MotionJerkPolyEval", Poly={"N": 0, "C": [1.0] * 7}, X=x) == 0.0


@given(st.lists(st.floats(-100.0, 100.0), min_size=2, max_size=7), st.booleans())
def test_poly_deriv_is_numpy_polyder(st_module: Any, coeffs: list[float], monic: bool) -> None:
    res = st_module.call("MotionJerkPolyDeriv", Poly=_poly(coeffs), Monic=monic)
    want = list(np.polyder(coeffs))
    if monic:
        want = [1.0] + [w / (len(coeffs) - 1) for w in want[1:]]
    assert res["N"] == len(coeffs) - 1
    assert res["C"][:res["N"]] == pytest.approx(want, rel=1e-15, abs=1e-13)


@given(st.lists(st.floats(-5.0, 5.0), min_size=2, max_size=6), st.integers(0, 5),
       st.floats(0.05, 0.45))
def test_poly_shrink_finds_the_bracketed_root(st_module: Any, rs: list[float], pick: int,
                                              margin: float) -> None:
    rs = sorted(rs)
    assume(min(b - a for a, b in zip(rs, rs[1:], strict=False)) > 0.1)
    r = rs[pick % len(rs)]
    coeffs = list(np.poly(rs))
    lo, hi = r - margin * 0.1, r + margin * 0.1  # no other root within 0.045
    got = st_module.call("MotionJerkPolyShrink", Poly=_poly(coeffs), Lo=lo, Hi=hi)
    assert got == pytest.approx(r, abs=1e-9)


# ----------------------------------------------------------------------------- profiles


@st.composite
def phase_times(draw: Any) -> list[float]:
    return [draw(st.one_of(st.just(0.0), st.floats(0.0, 2.0))) for _ in range(7)]


@given(phase_times(), st.floats(0.1, 20.0), st.booleans(), st.floats(-1.0, 1.0),
       st.floats(-1.0, 1.0))
def test_check_integrates_and_accepts_its_own_end(st_module: Any, ts: list[float], jf: float,
                                                  udud: bool, v0: float, a0: float) -> None:
    """The knots are the float64 integration of the phases; the profile is accepted with its
    own end as the target and generous limits, and refused when the target is moved by
    1e-6, when a phase is negative, or when the velocity limit is below its cruise."""
    prof = {"T": ts, "P": [0.0] * 8, "V": [v0] + [0.0] * 7, "A": [a0] + [0.0] * 7}
    signs = [1, 0, -1, 0, 1 if udud else -1, 0, -1 if udud else 1]
    p, v, a = 0.0, v0, a0
    vs, as_ = [v], [a]
    for t, s in zip(ts, signs, strict=True):
        j = jf * s if t > 0.0 else 0.0
        p, v, a = (p + t * (v + t * (a / 2 + t * j / 6)), v + t * (a + t * j / 2), a + t * j)
        vs.append(v)
        as_.append(a)
    big = 1e6
    prof.update(Pf=p, Vf=v, Af=a)
    args = dict(Udud=udud, Limits=7, SetLimits=False, Jf=jf, VMax=big, VMin=-big, AMax=big,
                AMin=-big, JLimit=0.0)
    ok, outs = st_module.call_full("MotionJerkCheck", **args, Prof=prof)
    assert ok
    q = outs["Prof"]
    assert q["P"][7] == pytest.approx(p, rel=1e-12, abs=1e-12)
    assert q["V"] == pytest.approx(vs, rel=1e-12, abs=1e-12)
    assert q["A"] == pytest.approx(as_, rel=1e-12, abs=1e-12)
    assert q["TSum"][6] == pytest.approx(sum(ts), rel=1e-15)
    moved = dict(prof, Pf=p + 1e-6)
    assert not st_module.call("MotionJerkCheck", **args, Prof=moved)
    if sum(ts) > 0.0:
        neg = dict(prof, T=[-1e-9] + ts[1:])
        assert not st_module.call("MotionJerkCheck", **args, Prof=neg)
    peak = max(abs(x) for x in vs[3:7])
    if peak > 1e-6:
        tight = dict(args, VMax=peak * 0.5, VMin=-peak * 0.5)
        assert not st_module.call("MotionJerkCheck", **tight, Prof=prof)
    # a jerk above the limit of a reduced-jerk case, the limit's sign aside
    assert not st_module.call("MotionJerkCheck", **dict(args, JLimit=-jf / 2), Prof=prof)
    # the velocity interface ignores the position
    assert st_module.call("MotionJerkCheckVelocity", Udud=udud, Limits=7, Jf=jf, AMax=big,
                          AMin=-big, JLimit=0.0, Prof=moved)
    assert not st_module.call("MotionJerkCheckVelocity", Udud=udud, Limits=7, Jf=jf,
                              AMax=big, AMin=-big, JLimit=0.0, Prof=dict(prof, Vf=v + 1e-6))


@given(axis_cases(outside=True), st.booleans())
def test_brake_brings_the_start_inside(st_module: Any, case: AxisCase, velocity: bool) -> None:
    """No brake from inside the limits and always one from beyond the acceleration limits
    (a velocity beyond its limit is braked unless the acceleration already turns it back);
    the brake's phases are of non-negative length at the jerk limit, their end (integrated
    here) has the acceleration back within the limits, and the profile starts there."""
    _, outs = st_module.call_full(
        "MotionJerkBrake", VelocityInterface=velocity, P0=case.p0, V0=case.v0, A0=case.a0,
        VMax=case.vmax, VMin=case.v_lo, AMax=case.amax, AMin=case.a_lo, JMax=case.jmax,
        Prof={})
    prof = outs["Prof"]
    inside = case.a_lo <= case.a0 <= case.amax if velocity else inside_at_start(case)
    if inside or prof["BrakeDuration"] == 0.0:
        # no brake from inside; beyond the acceleration limits always one
        assert prof["BrakeDuration"] == 0.0
        assert case.a_lo <= case.a0 <= case.amax
        assert (prof["P"][0], prof["V"][0], prof["A"][0]) == (case.p0, case.v0, case.a0)
        return
    assert prof["BrakeT"][0] >= 0.0 and prof["BrakeT"][1] >= 0.0
    assert all(abs(j) in (0.0, case.jmax) for j in prof["BrakeJ"])
    p, v, a = case.p0, case.v0, case.a0
    for k in range(2):
        t, j = prof["BrakeT"][k], prof["BrakeJ"][k]
        p, v, a = (p + t * (v + t * (a / 2 + t * j / 6)), v + t * (a + t * j / 2), a + t * j)
    assert (prof["P"][0], prof["V"][0], prof["A"][0]) == pytest.approx((p, v, a), rel=1e-12,
                                                                         abs=1e-12)
    assert case.a_lo * (1 + 1e-9) - 1e-9 <= a <= case.amax * (1 + 1e-9) + 1e-9


@given(st.floats(0.01, 10.0), FRACTION, st.floats(0.1, 10.0), st.floats(0.1, 10.0),
       st.floats(0.1, 100.0))
def test_velocity_brake_slows_down(st_module: Any, excess: float, a_frac: float, vmax: float,
                                   amax: float, jmax: float) -> None:
    """From above the velocity limit (or heading there) it ramps the acceleration down at
    the jerk limit, then holds the braking acceleration: the velocity falls, never rises
    beyond where the start's acceleration alone carries it."""
    v0 = vmax + excess
    a0 = a_frac * amax  # the brake of a velocity; an acceleration beyond is braked first
    _, outs = st_module.call_full("MotionJerkVelocityBrake", V0=v0, A0=a0, VMax=vmax,
                                  VMin=-vmax, AMin=-amax, JMax=jmax, Prof={})
    prof = outs["Prof"]
    t0, t1 = prof["BrakeT"]
    assert prof["BrakeJ"][0] == -jmax and t0 >= 0.0 and t1 >= 0.0
    v = v0 + t0 * (a0 - jmax * t0 / 2)
    a = a0 - jmax * t0
    v_end = v + a * t1
    assert v_end <= v0 + max(a0, 0.0) ** 2 / (2 * jmax) + 1e-9
    assert a >= -amax * (1 + 1e-9) - 1e-9


@given(axis_cases(outside=True), st.floats(-0.5, 2.0))
def test_at_is_the_integral_of_the_phases(st_module: Any, case: AxisCase, frac: float) -> None:
    runner = StRunner(st_module)
    plan = runner.plan((case,))
    assume(plan.valid)
    prof = plan.profiles[0]
    t = frac * plan.duration
    pt = st_module.call("MotionJerkAt", Prof=prof, TimeS=t)
    p, v, a, j = pt["Pos"], pt["Vel"], pt["Acc"], pt["Jerk"]
    # integrate here from the start through the brake and the phases
    segs = ([(prof["BrakeT"][k], prof["BrakeJ"][k]) for k in range(2)]
            if prof["BrakeDuration"] > 0.0 else [])
    segs += list(zip(prof["T"], prof["J"], strict=True)) + [(math.inf, 0.0)]
    left = max(t, 0.0)
    x = (case.p0, case.v0, case.a0)
    jerk = 0.0
    for dur, jj in segs:
        step = min(left, dur)
        x = (x[0] + step * (x[1] + step * (x[2] / 2 + step * jj / 6)),
             x[1] + step * (x[2] + step * jj / 2), x[2] + step * jj)
        left -= step
        jerk = jj
        if left <= 0.0 and step < dur:
            break
    scale = max(abs(case.p0), abs(case.pf), case.vmax * plan.duration, 1.0)
    assert p == pytest.approx(x[0], abs=1e-9 * scale)
    assert v == pytest.approx(x[1], abs=1e-9 * max(case.vmax, abs(case.v0), 1.0))
    assert a == pytest.approx(x[2], abs=1e-9 * max(case.amax, abs(case.a0), 1.0))
    assert j == jerk
    if t > plan.duration:
        assert j == 0.0 and a == pytest.approx(case.af)


# ----------------------------------------------------------------------------- step 1


S1_SHAPES = ["MotionJerkS1AllVel", "MotionJerkS1Acc0Acc1", "MotionJerkS1NoneAcc0Acc1",
             "MotionJerkS1TwoStep"]


@settings(max_examples=150)
@given(axis_cases(), st.sampled_from(S1_SHAPES), st.integers(1, 4))
def test_step1_shapes_accept_only_right_profiles(st_module: Any, case: AxisCase, name: str,
                                                 shape: int) -> None:
    ref = ruckig_plan((case,))
    assume(ref.ok)
    bound = ref.duration
    if abs(case.a0) < 1e-9 * case.amax:
        # Ruckig is no lower bound at a vanishing start acceleration: from v0 = vmax = 1 to
        # 2 (amax = jmax = 1) it gives 3.0 s for a0 = 0 and 1e-6 but 4.0 s for a0 = 7.8e-168,
        # where 1 s at vmax and the 2 s brake reach the target in 3.0 s as well
        bound = min(bound, ruckig_plan((dataclasses.replace(case, a0=0.0),)).duration)
    # a move shorter than assert_reaches' position tolerance is reached by staying put (a
    # profile of 0 s for pf = 2e-9): only the duration of real moves is bounded
    moves = abs(case.pf - case.p0) > 1e-7 * max(abs(case.p0), abs(case.pf), 1.0)
    prof = boundary(st_module, case)
    data = step1_data(prof, case.jmax)
    for lims in directions(case):
        args: dict[str, Any] = dict(Terms=data, **lims)
        if name in ("MotionJerkS1Acc0Acc1", "MotionJerkS1NoneAcc0Acc1"):
            args["ReturnAfterFound"] = False
        if name == "MotionJerkS1TwoStep":
            args["Shape"] = shape
        _, outs = st_module.call_full(name, **args, W=prof, C={"Count": 0})
        cands = outs["C"]
        for item in cands["Item"][:cands["Count"]]:
            assert_reaches(item, case)
            assert not moves or item["TSum"][6] >= bound * (1 - 1e-9) - 1e-12


@given(st.lists(st.tuples(st.floats(0.0, 10.0), st.booleans()), min_size=0, max_size=6))
def test_block_from_candidates(st_module: Any, items: list[tuple[float, bool]]) -> None:
    """Ruckig's rules: 1 profile is the minimum; 2 give the minimum and one blocked interval
    between them; 3 or 5 the minimum and the others paired into blocked intervals; 0, 4 (not
    near-duplicates) and 6 are a failure."""
    cand = {"Count": len(items),
            "Item": [{"TSum": [0.0] * 6 + [d], "Up": up, "BrakeDuration": 0.0}
                     for d, up in items] + [{}] * (6 - len(items))}
    blk, _ = st_module.call_full("MotionJerkBlockFrom", C=cand)
    durs = [d for d, _ in items]
    n = len(items)
    near_dup = n == 4 and any(abs(durs[i] - durs[j]) < 256 * EPS and items[i][1] != items[j][1]
                              for i, j in ((0, 1), (2, 3), (0, 3)))
    if n in (0, 6) or (n == 4 and not near_dup):
        assert not blk["Valid"]
        return
    assert blk["Valid"]
    assert blk["TMin"] == min(durs)
    intervals = []
    if blk["HasA"]:
        intervals.append((blk["ALeft"], blk["ARight"]))
    if blk["HasB"]:
        intervals.append((blk["BLeft"], blk["BRight"]))
    if n == 1 or (n == 2 and abs(durs[0] - durs[1]) < 8 * EPS):
        assert not intervals
        return
    # every interval joins two of the given durations, the minimum's interval aside
    for left, right in intervals:
        assert left <= right and left in durs and right in durs
    assert len(intervals) == {2: 1, 3: 1, 4: 1, 5: 2}[n]


@settings(max_examples=200)
@given(axis_cases(outside=True))
def test_step1_is_ruckigs_time_optimum(st_module: Any, case: AxisCase) -> None:
    ref = ruckig_plan((case,))
    blk = st_module.call("MotionJerkStep1", Boundary=boundary(st_module, case), VMax=case.vmax,
                         VMin=case.v_lo, AMax=case.amax, AMin=case.a_lo, JMax=case.jmax)
    if not ref.ok:
        # only Ruckig's step-1 failures concern step 1 (one axis: no duration limit)
        assert "step 1" in ref.result and not blk["Valid"]
        return
    assert blk["Valid"]
    assert blk["TMin"] == pytest.approx(ref.duration, rel=1e-9, abs=1e-12)
    assert_reaches(blk["PMin"], case)


# ----------------------------------------------------------------------------- step 2


S2_SHAPES = ["MotionJerkS2Acc0Acc1Vel", "MotionJerkS2Vel", "MotionJerkS2Acc0Vel",
             "MotionJerkS2Acc1Vel", "MotionJerkS2Acc0Acc1", "MotionJerkS2Acc0",
             "MotionJerkS2Acc1", "MotionJerkS2None", "MotionJerkS2NoneSmooth"]


def _feasible_duration(st_module: Any, case: AxisCase, stretch: float) -> float | None:
    """A duration from the shortest one on that no blocked interval contains (exactly the
    shortest, or an interval's end, for stretch 1 and durations in an interval)."""
    blk = st_module.call("MotionJerkStep1", Boundary=boundary(st_module, case), VMax=case.vmax,
                         VMin=case.v_lo, AMax=case.amax, AMin=case.a_lo, JMax=case.jmax)
    if not blk["Valid"]:
        return None
    t = blk["TMin"] * stretch
    for has, left, right in (("HasA", "ALeft", "ARight"), ("HasB", "BLeft", "BRight")):
        if blk[has] and blk[left] < t < blk[right]:
            t = blk[right]
    return float(t)


@settings(max_examples=150)
@given(axis_cases(), st.sampled_from(S2_SHAPES), st.floats(1.0, 3.0))
def test_step2_shapes_accept_only_right_profiles(st_module: Any, case: AxisCase, name: str,
                                                 stretch: float) -> None:
    tf = _feasible_duration(st_module, case, stretch)
    assume(tf is not None and tf > 0.0)
    assert tf is not None
    prof = boundary(st_module, case)
    data = step2_data(prof, tf, case.jmax)
    for lims in directions(case):
        ok, outs = st_module.call_full(name, Terms=data, **lims, Prof=prof)
        if ok:
            assert_reaches(outs["Prof"], case, duration=tf)


@settings(max_examples=150)
@given(axis_cases(), st.floats(0.0, 1.0), st.booleans())
def test_step2_velocity_root_accepts_only_right_profiles(st_module: Any, case: AxisCase,
                                                         frac: float, udud: bool) -> None:
    tf = _feasible_duration(st_module, case, 1.5)
    assume(tf is not None and tf > 0.0)
    assert tf is not None
    prof = boundary(st_module, case)
    data = step2_data(prof, tf, case.jmax)
    for lims in directions(case):
        ok, outs = st_module.call_full("MotionJerkS2VelRoot", Terms=data, T0=frac * tf / 2,
                                       Udud=udud, **lims, Prof=prof)
        if ok:
            assert_reaches(outs["Prof"], case, duration=tf)


@settings(max_examples=200)
@given(axis_cases(), st.floats(1.0, 4.0))
def test_step2_finds_a_profile_of_any_feasible_duration(st_module: Any, case: AxisCase,
                                                        stretch: float) -> None:
    """Every duration outside the blocked intervals has a profile (the premise of time
    synchronisation) wherever Ruckig's step 2 finds one, and what is found is right."""
    tf = _feasible_duration(st_module, case, stretch)
    assume(tf is not None and tf > 0.0)
    assert tf is not None
    ok, outs = st_module.call_full("MotionJerkStep2", Tf=tf, VMax=case.vmax, VMin=case.v_lo,
                                   AMax=case.amax, AMin=case.a_lo, JMax=case.jmax,
                                   Prof=boundary(st_module, case))
    # Ruckig's step 2 on the same axis and duration (its minimum_duration input
    # synchronises a single axis to tf); where it finds a profile the ST must too
    ref = ruckig_plan((case,), minimum_duration=tf)
    blk = st_module.call("MotionJerkStep1", Boundary=boundary(st_module, case), VMax=case.vmax,
                         VMin=case.v_lo, AMax=case.amax, AMin=case.a_lo, JMax=case.jmax)
    ends = [blk["TMin"]] + [blk[k] for k, has in (("ARight", "HasA"), ("BRight", "HasB"))
                            if blk[has]]
    # at step 1's own durations Ruckig takes step 1's profiles, not step 2's
    if ref.ok and ref.duration == tf and all(abs(tf - e) >= 2 * EPS for e in ends):
        assert ok
    if ok:
        assert_reaches(outs["Prof"], case, duration=tf)


# ----------------------------------------------------------------------------- velocity


@settings(max_examples=150)
@given(axis_cases(), st.sampled_from([1, 2]), st.booleans())
def test_velocity_step1_cases_and_entry(st_module: Any, case: AxisCase, shape: int,
                                        stop_first: bool) -> None:
    ref = ruckig_plan((case,), interface="Velocity")
    assume(ref.ok)
    prof = boundary(st_module, case, velocity=True)
    for lims in directions(case):
        _, outs = st_module.call_full(
            "MotionJerkVelS1Case", Shape=shape, ReturnAfterFound=stop_first, A0=prof["A"][0],
            Af=case.af, Vd=case.vf - prof["V"][0], aMax=lims["aMax"], aMin=lims["aMin"],
            jMax=lims["jMax"], W=prof, C={"Count": 0})
        for item in outs["C"]["Item"][:outs["C"]["Count"]]:
            assert_reaches(item, case, position=False)
            assert item["TSum"][6] >= ref.duration * (1 - 1e-9) - 1e-12
    blk = st_module.call("MotionJerkVelStep1", Boundary=prof, AMax=case.amax, AMin=case.a_lo,
                         JMax=case.jmax)
    assert blk["Valid"]
    assert blk["TMin"] == pytest.approx(ref.duration, rel=1e-9, abs=1e-12)


@settings(max_examples=150)
@given(axis_cases(), st.floats(1.0, 4.0), st.sampled_from([2, 7]))
def test_velocity_step2_cases_and_entry(st_module: Any, case: AxisCase, stretch: float,
                                        shape: int) -> None:
    prof = boundary(st_module, case, velocity=True)
    blk = st_module.call("MotionJerkVelStep1", Boundary=prof, AMax=case.amax, AMin=case.a_lo,
                         JMax=case.jmax)
    assume(blk["Valid"] and blk["TMin"] > 0.0 and not blk["HasA"])
    tf = blk["TMin"] * stretch
    for lims in directions(case):
        ok, outs = st_module.call_full("MotionJerkVelS2Case", Shape=shape, Tf=tf,
                                       aMax=lims["aMax"], aMin=lims["aMin"],
                                       jMax=lims["jMax"], Prof=prof)
        if ok:
            assert_reaches(outs["Prof"], case, duration=tf, position=False)
            assert outs["Prof"]["Pf"] == outs["Prof"]["P"][7]
    ok, outs = st_module.call_full("MotionJerkVelStep2", Tf=tf, AMax=case.amax, AMin=case.a_lo,
                                   JMax=case.jmax, Prof=prof)
    ref = ruckig_plan((case,), interface="Velocity", minimum_duration=tf)
    # at exactly the shortest duration Ruckig takes step 1's profile, not step 2's
    if ref.ok and ref.duration == tf and abs(tf - blk["TMin"]) >= 2 * EPS:
        assert ok
    if ok:
        assert_reaches(outs["Prof"], case, duration=tf, position=False)


# ----------------------------------------------------------------------------- planner


def _expected_check(case: AxisCase, velocity: bool, separate: bool) -> int:
    """The header's rules of MotionJerkAxisCheck, restated."""
    big = 1e15
    values = (case.p0, case.v0, case.a0, case.pf, case.vf, case.af)
    if not all(abs(x) <= big for x in values):
        return 8
    if not all(0.0 < x <= big for x in (case.vmax, case.amax, case.jmax)):
        return 8
    vmin, amin = (case.v_lo, case.a_lo)
    if separate and not (-big <= vmin <= 0.0 and -big <= amin < 0.0):
        return 8
    if not separate:
        vmin, amin = -case.vmax, -case.amax
    if not amin <= case.af <= case.amax:
        return 26
    if not velocity:
        if not vmin <= case.vf <= case.vmax:
            return 26
        if case.af < 0.0 and case.vf + case.af ** 2 / (2 * case.jmax) > case.vmax:
            return 26
        if case.af > 0.0 and case.vf - case.af ** 2 / (2 * case.jmax) < vmin:
            return 26
    return 0


ANY = st.one_of(st.floats(-10.0, 10.0), st.sampled_from([math.nan, math.inf, -math.inf, 0.0,
                                                         2e15, -1.0]))


@given(st.lists(ANY, min_size=11, max_size=11), st.booleans(), st.booleans())
def test_axis_check_follows_the_header(st_module: Any, xs: list[float], velocity: bool,
                                       separate: bool) -> None:
    case = AxisCase(xs[0], xs[1], xs[2], xs[3], xs[4], xs[5], xs[6], xs[7], vmin=xs[8],
                    amin=xs[9], af=xs[10])
    lim = {"MaxVel": case.vmax, "MaxAcc": case.amax, "MaxJerk": case.jmax,
           "SeparateMin": separate, "MinVel": xs[8], "MinAcc": xs[9]}
    got = st_module.call("MotionJerkAxisCheck", VelocityInterface=velocity, P0=case.p0,
                         V0=case.v0, A0=case.a0, Pf=case.pf, Vf=case.vf, Af=case.af,
                         Limits=lim)
    assert got == _expected_check(case, velocity, separate)


@given(st.integers(-1, 7), st.lists(st.floats(-5.0, 5.0), min_size=5, max_size=5))
def test_scale_of_picks_the_named_value(st_module: Any, which: int, xs: list[float]) -> None:
    got = st_module.call("MotionJerkScaleOf", Which=which, Pd=xs[0], V0=xs[1], A0=xs[2],
                         Vf=xs[3], Af=xs[4])
    assert got == (xs[which - 1] if 1 <= which <= 5 else 0.0)


@settings(max_examples=100)
@given(st.lists(axis_cases(outside=True), min_size=1, max_size=6),
       st.sampled_from(["Time", "Phase", "None", "TimeIfNecessary"]))
def test_planner_duration_is_ruckigs(st_module: Any, axes: list[AxisCase],
                                     synchronization: str) -> None:
    runner = StRunner(st_module, st_module.new_fb("MotionJerkPlanner"))
    got = runner.plan(axes, synchronization)
    ref = ruckig_plan(axes, synchronization)
    if not ref.ok:
        assert not got.valid
        assert got.error_id in (27, 28, 29)
        return
    assert got.valid, got.error_id
    assert got.duration == pytest.approx(ref.duration, rel=1e-9, abs=1e-12)
    for prof, case in zip(got.profiles, axes, strict=True):
        assert all(math.isfinite(x) for x in prof["T"] + prof["P"] + prof["V"] + prof["A"])
        ex = extremes(prof, case.p0, case.v0, case.a0)
        assert ex.end[0] == pytest.approx(case.pf, abs=1e-7 * max(abs(case.pf), 1.0))


@settings(max_examples=60)
@given(st.lists(st.tuples(st.integers(1, 60), st.floats(-3.0, 3.0), st.floats(-0.9, 0.9),
                          st.sampled_from([0.0, math.nan, 1e20])), min_size=1, max_size=8),
       st.booleans())
def test_generator_is_continuous_and_never_nan(st_module: Any,
                                               steps: list[tuple[int, float, float, float]],
                                               velocity: bool) -> None:
    """Any sequence of targets (some of them bad): every scan's setpoint is finite and
    within a cycle's worth of the limits from the last one."""
    lims = [{"MaxVel": 1.0, "MaxAcc": 4.0, "MaxJerk": 40.0},
            {"MaxVel": 2.0, "MaxAcc": 3.0, "MaxJerk": 15.0}]
    pad = [{"MaxVel": 1.0, "MaxAcc": 1.0, "MaxJerk": 1.0}] * 4
    gen = st_module.new_fb("MotionJerkGenerator")
    dt = 0.01
    prev = None
    for scans, pos, vel, bad in steps:
        for _ in range(scans):
            gen(Enable=True, CycleTime=dt, Joints=2, VelocityMode=velocity, Sync=0,
                TargetPos=[pos + bad, -pos] + [0.0] * 4, TargetVel=[vel, vel * 2] + [0.0] * 4,
                TargetAcc=[0.0] * 6, Limits=lims + pad, StartPos=[0.0] * 6,
                StartVel=[0.0] * 6, StartAcc=[0.0] * 6)
            state = gen.Position[:2] + gen.Velocity[:2] + gen.Acceleration[:2]
            assert all(math.isfinite(x) for x in state)
            if bad != 0.0 and not velocity:
                assert gen.Error and gen.ErrorId == 8
            if prev is not None:
                for j in range(2):
                    dv = abs(gen.Velocity[j] - prev[2 + j])
                    da = abs(gen.Acceleration[j] - prev[4 + j])
                    assert dv <= lims[j]["MaxAcc"] * dt * (1 + 1e-9) + 1e-12
                    assert da <= lims[j]["MaxJerk"] * dt * (1 + 1e-9) + 1e-12
            prev = state
