"""Property tests of the motion POUs that had none: MotionVecLength, MotionJog (st/MotionJog.st);
MotionWristPose, MotionJogWrist (st/MotionJogWrist.st); MotionGroupCheck, MotionHalt
(st/MotionJoint.st); MotionBresenhamStart, MotionBresenhamAdvance, MotionArmIk,
MotionWithinLimits, MotionLinePointCheck, MotionLinear (st/MotionLine.st); MotionSyncSpeed,
MotionQuinticFits (st/MotionProfiles.st); SlewStepToward (st/ServoSlew.st).

Inputs over the documented range, float32 extremes and just beyond, NaN/Inf; for the
multi-scan blocks, command inputs changed while Busy (the path must equal a run with the
inputs held) and the headers' invariants checked scan by scan on finite differences of the
setpoints (speed and acceleration within the limits, the exact end point, never NaN, the
documented ErrorId on refusal, nothing changed by a refusal). References: closed forms in
float64 (hypot, the synchronised speed, the quintic's polynomial, the slew limiter's braking
sum G(s)), an exact integer Bresenham, and the bench's float64 arm models
(armbench.plant.arm, tests/five_axis_ref.py), never the ST's own output.
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
    DT,
    JOINT_LIMIT,
    NOT_FINITE,
    GroupSim,
    make_group,
)

from armbench.plant import arm
from five_axis_ref import fk5

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis_setup import examples  # noqa: E402

F32_MAX = float(np.finfo(np.float32).max)
REAL_1E30 = float(np.float32(1.0e30))
EXTREMES = [0.0, -0.0, 1e-45, 1e-38, 1e-30, 1e-6, 1.0, 1e6, 1e20, 1e30, 1.1e30, F32_MAX,
            math.inf, -math.inf, math.nan]
PATH_NOT_SMOOTH = 24
GEO = arm.DEFAULT_GEOMETRY.as_st()
G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0
GEO5 = {"Arm": G.as_st(), "ToolMm": TOOL_MM}
P_START = (180.0, -40.0, 150.0)


def f32(x: float) -> float:
    return float(np.float32(x))


def real(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.one_of(st.floats(lo, hi, width=32), st.sampled_from(EXTREMES),
                     st.sampled_from(EXTREMES).map(lambda v: -v))


def is_real(v: float) -> bool:
    """IsFiniteReal: finite and within the REAL 1.0E30."""
    return math.isfinite(v) and abs(v) <= REAL_1E30


def group_finite(group: dict[str, Any]) -> bool:
    return all(math.isfinite(v) for key in ("Position", "Velocity", "Acceleration")
               for v in group[key])


# --- Scalar functions -----------------------------------------------------------------------

@examples(300)
@given(v=st.lists(st.one_of(st.floats(width=32), st.sampled_from(EXTREMES)), min_size=3,
                  max_size=3))
def test_motion_vec_length(st_module: Any, v: list[float]) -> None:
    x, y, z = (f32(c) for c in v)
    got = st_module.call("MotionVecLength", x, y, z)
    if any(math.isnan(c) for c in (x, y, z)):
        assert math.isnan(got)
        return
    if all(math.isfinite(c) for c in (x, y, z)) and max(abs(x), abs(y), abs(z)) <= 1e38:
        ref = math.sqrt(x * x + y * y + z * z)
        assert math.isfinite(got) and abs(got - ref) <= 4e-7 * ref + 3e-45  # subnormal ulp


@examples(300)
@given(dist=real(-1e6, 1e6), lead=real(-1e6, 1e6), speed=real(0.0, 1e4))
# found by the 10x soak: a subnormal LeadDist below |Dist| made the ratio Inf, times 0 = NaN
@example(dist=1.0, lead=1.401298464324817e-45, speed=0.0)
# found by the soak with seed 1: a subnormal |Dist| / |LeadDist| (4.4e-41) times 1e20 put
# the drive's time off by 1.2e-5
@example(dist=1e-38, lead=225.0, speed=1e20)
def test_motion_sync_speed(st_module: Any, dist: float, lead: float, speed: float) -> None:
    dist, lead, speed = f32(dist), f32(lead), f32(speed)
    got = st_module.call("MotionSyncSpeed", dist, lead, speed)
    assert not math.isnan(got)
    if (not (is_real(dist) and is_real(lead) and is_real(speed)) or lead == 0.0
            or speed <= 0.0):
        assert got == 0.0
        return
    if abs(dist) <= abs(lead) and speed > 0.0:
        ref = speed * abs(dist) / abs(lead)
        assert 0.0 <= got <= speed * (1 + 1e-6)
        # a subnormal ratio |Dist| / |LeadDist| resolves to 1.4e-45, times LeadSpeed
        assert abs(got - ref) <= 1e-6 * ref + 3e-45 * max(speed, 1.0)
        # every drive then takes |LeadDist| / LeadSpeed
        if got > 1e-30 and ref > 1e-30:
            assert abs(abs(dist) / got - abs(lead) / speed) <= 1e-5 * abs(lead) / speed


@pytest.mark.parametrize(("dist", "lead", "speed"), [
    (1e20, 1e20, 1e20), (-1e30, 1e30, 1e30), (2e19, -4e19, 1e20), (3e15, 1e16, 2e23)])
def test_sync_speed_of_large_values_is_finite(st_module: Any, dist: float, lead: float,
                                              speed: float) -> None:
    """Regression: LeadSpeed * |Dist| was formed first and overflowed to Inf for values well
    inside the REAL range, although the result is at most LeadSpeed."""
    dist, lead, speed = f32(dist), f32(lead), f32(speed)
    got = st_module.call("MotionSyncSpeed", dist, lead, speed)
    ref = speed * abs(dist) / abs(lead)
    assert math.isfinite(got) and abs(got - ref) <= 1e-6 * ref


def quintic(dist: float, v0: float, dur: float, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """The rest-at-the-end quintic from (0, V0, 0) to (Dist, 0, 0) in time T (float64): its
    velocity, acceleration and jerk at t."""
    mat = np.array([[dur**3, dur**4, dur**5], [3 * dur**2, 4 * dur**3, 5 * dur**4],
                    [6 * dur, 12 * dur**2, 20 * dur**3]])
    c3, c4, c5 = np.linalg.solve(mat, [dist - v0 * dur, -v0, 0.0])
    vel = v0 + 3 * c3 * t**2 + 4 * c4 * t**3 + 5 * c5 * t**4
    acc = 6 * c3 * t + 12 * c4 * t**2 + 20 * c5 * t**3
    jerk = 6 * c3 + 24 * c4 * t + 60 * c5 * t**2
    return vel, acc, jerk


@examples(300)
@given(dist=st.floats(-1e3, 1e3, width=32), v0_frac=st.floats(-1.0, 1.5),
       dur=st.floats(f32(0.05), 20.0, width=32), vmax=st.floats(1.0, 500.0, width=32),
       amax=st.floats(1.0, 5000.0, width=32), jmax=st.floats(1.0, 1e5, width=32))
def test_motion_quintic_fits(st_module: Any, dist: float, v0_frac: float, dur: float,
                             vmax: float, amax: float, jmax: float) -> None:
    """TRUE: the dense float64 quintic keeps the limits with the header's 3 % for the peaks
    between the 65 samples, and never moves against the move; clearly inside the limits
    (10 % below) and never against the move: TRUE."""
    v0 = f32(v0_frac * vmax * math.copysign(1.0, dist if dist else 1.0))
    fits = st_module.call("MotionQuinticFits", dist, v0, dur, vmax, amax, jmax)
    t = np.linspace(0.0, dur, 2001)
    vel, acc, jerk = quintic(dist, v0, dur, t)
    vlim = max(vmax, abs(v0))
    ratio = max(np.abs(vel).max() / vlim, np.abs(acc).max() / amax, np.abs(jerk).max() / jmax)
    backwards = float(np.min(vel * math.copysign(1.0, dist))) if dist else 0.0
    if fits:
        assert ratio <= 1.03 + 1e-4
        assert backwards >= -1e-4 * vlim
    elif dist != 0.0 and ratio < 0.9 and backwards > 1e-4 * vlim:
        pytest.fail(f"a quintic within {ratio:.3f} of its limits does not fit")


@examples(200)
@given(values=st.lists(real(-1e3, 1e3), min_size=6, max_size=6))
def test_motion_quintic_fits_bad_input(st_module: Any, values: list[float]) -> None:
    dist, v0, dur, vmax, amax, jmax = (f32(v) for v in values)
    fits = st_module.call("MotionQuinticFits", dist, v0, dur, vmax, amax, jmax)
    if not (all(is_real(v) for v in (dist, v0, dur, vmax, amax, jmax))
            and dur > 0 and vmax > 0 and amax > 0 and jmax > 0):
        assert fits is False


def braking_sum(s: float, d: float) -> float:
    """G(s) = sum over i >= 0 of max(0, s - i D): the distance a step s needs to stop."""
    n = math.floor(s / d)
    return (n + 1) * s - d * n * (n + 1) / 2.0


@examples(400)
@given(rem=st.one_of(st.floats(0.0, 1e3), st.floats(0.0, 1e30), st.sampled_from(
           [0.0, 1e-45, 1e-30, 1e30, 1e38, F32_MAX])),
       acc=st.one_of(st.floats(1e-8, 10.0), st.sampled_from([1e-30, 1e-10, 1e3])))
def test_slew_step_toward(st_module: Any, rem: float, acc: float) -> None:
    rem, acc = f32(rem), f32(acc)
    sw = st_module.call("SlewStepToward", rem, acc)
    assert math.isfinite(sw) and sw >= 0.0
    if rem < acc:
        assert sw == rem  # the last step
        return
    if rem / acc > 1e12:
        return  # beyond float64's exact G below; finite and >= 0 is the promise
    # it can still stop there (float32 rounding of sw allowed), and it is at most one
    # StepAcc below the largest such step (the header's conservative bound)
    assert braking_sum(sw, acc) <= rem * (1 + 1e-5) + acc * 1e-5
    assert braking_sum(sw + acc * (1 + 1e-5) + sw * 1e-6, acc) >= rem * (1 - 1e-6)


# --- Groups and limits --------------------------------------------------------------------------

@st.composite
def groups(draw: Any) -> dict[str, Any]:
    g = make_group([draw(st.floats(-170.0, 170.0)) for _ in range(6)],
                   joints=draw(st.sampled_from([1, 3, 5, 6, 0, 7, -1])))
    lim = g["Limits"]
    for _ in range(draw(st.integers(0, 2))):
        key = draw(st.sampled_from(["LowerDeg", "UpperDeg", "MaxVelDeg", "MaxAccDeg",
                                    "Position", "Velocity"]))
        j = draw(st.integers(0, 5))
        value = draw(st.sampled_from([math.nan, math.inf, -math.inf, 1.1e30, 0.0, -1.0,
                                      -200.0, 200.0, 1e30]))
        (g if key in ("Position", "Velocity") else lim)[key][j] = value
    return g


def group_code(g: dict[str, Any], min_joints: int) -> int:
    """MotionGroupCheck's rule, in the header's order."""
    n = g["Joints"]
    if not min_joints <= n <= 6:
        return BAD_JOINT_COUNT
    lim = g["Limits"]
    for j in range(n):
        vals = [lim[k][j] for k in ("LowerDeg", "UpperDeg", "MaxVelDeg", "MaxAccDeg")]
        if (not all(is_real(f32(v)) for v in vals) or lim["MaxVelDeg"][j] <= 0
                or lim["MaxAccDeg"][j] <= 0 or lim["LowerDeg"][j] > lim["UpperDeg"][j]):
            return BAD_GROUP_LIMITS
    for j in range(n):
        if not (is_real(f32(g["Position"][j])) and is_real(f32(g["Velocity"][j]))):
            return BAD_GROUP_STATE
    return 0


@examples(150)
@given(g=groups(), min_joints=st.sampled_from([1, 3, 5]))
def test_motion_group_check(st_module: Any, g: dict[str, Any], min_joints: int) -> None:
    got = st_module.call("MotionGroupCheck", MinJoints=min_joints, Group=g)
    assert got == group_code(g, min_joints)


@examples(300)
@given(count=st.sampled_from([0, 1, 3, 6, 7, -2]),
       joints=st.lists(real(-200.0, 200.0), min_size=6, max_size=6),
       lower=st.lists(st.floats(-180.0, 0.0, width=32), min_size=6, max_size=6),
       upper=st.lists(st.floats(0.0, 180.0, width=32), min_size=6, max_size=6))
def test_motion_within_limits(st_module: Any, count: int, joints: list[float],
                              lower: list[float], upper: list[float]) -> None:
    joints = [f32(v) for v in joints]
    limits = {"LowerDeg": lower, "UpperDeg": upper, "MaxVelDeg": [100.0] * 6,
              "MaxAccDeg": [100.0] * 6}
    got = st_module.call("MotionWithinLimits", Count=count, Joints=joints, Limits=limits)
    want = 1 <= count <= 6 and all(lower[j] <= joints[j] <= upper[j] for j in range(count))
    assert got is want


# --- Bresenham ----------------------------------------------------------------------------------

def ref_bresenham(deltas: list[int], k: int) -> list[int]:
    """Grid point after k iterations: the major axis at k, each minor coordinate
    k * delta_minor / delta_major rounded half up (exact integers)."""
    d = [abs(x) for x in deltas]
    major = max(d)
    if major == 0:
        return [0, 0, 0]
    return [(2 * k * di + major) // (2 * major) for di in d]


@examples(100)
@given(deltas=st.lists(st.one_of(st.integers(-1_000_000, 1_000_000), st.sampled_from(
           [0, 1, -1, 1_000_000, -1_000_000])), min_size=3, max_size=3),
       chunks=st.lists(st.one_of(st.integers(-3, 50), st.integers(0, 300_000)), min_size=1,
                       max_size=6))
def test_bresenham_start_and_advance(st_module: Any, deltas: list[int],
                                     chunks: list[int]) -> None:
    state = st_module.call("MotionBresenhamStart", *deltas)
    d = [abs(x) for x in deltas]
    major = max(d)
    assert state["Steps"] == major and state["Taken"] == 0
    assert state["Major"] == 1 + d.index(major)  # the first of equals
    assert list(state["Count"]) == [0, 0, 0]
    taken = 0
    for steps in chunks:
        done, outs = st_module.call_full("MotionBresenhamAdvance", Steps=steps, State=state)
        state = outs["State"]
        want = min(max(steps, 0), major - taken)
        assert done == want
        taken += want
        assert state["Taken"] == taken
        # the major axis exact; the minors within the half-up rounding's tie (the ST's
        # integer decision variable breaks exact ties its own way)
        ref = ref_bresenham(deltas, taken)
        got = list(state["Count"])
        exact = [2 * taken * di / (2 * major) if major else 0 for di in d]
        for g_i, r_i, e_i in zip(got, ref, exact, strict=True):
            assert g_i == r_i or abs(g_i - e_i) <= 0.5
    assert taken <= major


# --- The arm's IK and line points -------------------------------------------------------------

points = st.tuples(st.floats(-350.0, 350.0), st.floats(-350.0, 350.0),
                   st.floats(-200.0, 450.0))


@examples(300)
@given(p=st.one_of(points, st.lists(real(-1e6, 1e6), min_size=3, max_size=3).map(tuple)),
       elbow_up=st.booleans())
def test_motion_arm_ik(st_module: Any, p: tuple[float, ...], elbow_up: bool) -> None:
    x, y, z = (f32(v) for v in p)
    before = [11.0, 22.0, 33.0, 44.0, 55.0, 66.0]
    code, outs = st_module.call_full("MotionArmIk", X=x, Y=y, Z=z, ElbowUp=elbow_up,
                                     Geometry=GEO, Joints=list(before))
    joints = outs["Joints"]
    assert code in (0, 1, 2, 3)
    if not all(is_real(v) for v in (x, y, z)):
        assert code == NOT_FINITE
    if code:
        assert joints == before  # untouched
        return
    assert joints[3:] == before[3:]
    assert np.abs(arm.forward(*joints[:3]) - [x, y, z]).max() < 2e-3 * max(
        1.0, abs(x), abs(y), abs(z)) / 10.0 + 5e-3
    if arm.is_reachable(x, y, z, margin=1.0) and math.hypot(x, y) > 1.0:
        ref = arm.inverse(x, y, z, elbow_up=elbow_up)
        assert np.abs(arm.forward(*ref) - arm.forward(*joints[:3])).max() < 5e-3


@examples(200)
@given(p0=points, p1=points, frac=st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1.0])),
       jump=st.floats(0.5, 30.0), shift=st.floats(-40.0, 40.0),
       upper=st.sampled_from([170.0, 60.0]))
def test_motion_line_point_check(st_module: Any, p0: tuple[float, ...], p1: tuple[float, ...],
                                 frac: float, jump: float, shift: float,
                                 upper: float) -> None:
    x0, y0, z0 = (f32(v) for v in p0)
    dx, dy, dz = (f32(b - a) for a, b in zip(p0, p1, strict=True))
    frac = f32(frac)
    px, py, pz = (a + frac * d for a, d in zip((x0, y0, z0), (dx, dy, dz), strict=True))
    limits = {"LowerDeg": [-upper] * 6, "UpperDeg": [upper] * 6, "MaxVelDeg": [100.0] * 6,
              "MaxAccDeg": [100.0] * 6}
    near = [0.0] * 6
    if arm.is_reachable(px, py, pz, margin=0.5) and math.hypot(px, py) > 1.0:
        near = list(arm.inverse(px, py, pz)) + [0.0] * 3
        near[1] += shift
    before = [7.0] * 6
    code, outs = st_module.call_full("MotionLinePointCheck", X0=x0, Y0=y0, Z0=z0, DX=dx, DY=dy,
                                     DZ=dz, Frac=frac, ElbowUp=True, Geometry=GEO,
                                     MaxJumpDeg=f32(jump), Joints=list(before),
                                     Near=list(near), Limits=limits)
    joints = outs["Joints"]
    assert code in (0, 1, 2, JOINT_LIMIT, PATH_NOT_SMOOTH)
    if code in (1, 2):
        assert joints == before
        return
    assert np.abs(arm.forward(*joints[:3]) - [px, py, pz]).max() < 5e-3
    inside = all(-upper <= q <= upper for q in joints[:3])
    jumps = max(abs(a - b) for a, b in zip(joints[:3], near[:3], strict=True))
    if code == 0:
        assert inside and jumps <= jump * (1 + 1e-6)
    elif code == JOINT_LIMIT:
        assert not inside
    else:
        assert inside and jumps > jump * (1 - 1e-6)


# --- MotionHalt ------------------------------------------------------------------------------

@examples(80)
@given(vel=st.lists(st.floats(-120.0, 120.0), min_size=3, max_size=3),
       decel=st.one_of(st.floats(50.0, 5000.0), st.sampled_from([400.0, 1e30])),
       later=st.lists(st.one_of(st.floats(1.0, 5000.0), st.sampled_from(
           [math.nan, 0.0, -1.0, math.inf])), min_size=1, max_size=4))
def test_motion_halt_brakes_within_the_limits(st_module: Any, vel: list[float], decel: float,
                                              later: list[float]) -> None:
    """Every joint brakes at min(Deceleration, MaxAccDeg) to rest, scan by scan; the
    Deceleration changed while Busy changes nothing; Done at rest, never NaN."""
    def run(changing: bool) -> tuple[GroupSim, Any]:
        g = make_group([10.0, -20.0, 30.0])
        g["Velocity"][:3] = [f32(v) for v in vel]
        sim, fb = GroupSim(g), st_module.new_fb("MotionHalt")
        for k in range(2000):
            d = later[k % len(later)] if changing and k else decel
            sim.scan(fb, Execute=True, Deceleration=f32(d), CycleTime=DT)
            assert not fb.Error and group_finite(sim.group)
            if not fb.Busy:
                break
        return sim, fb

    sim, fb = run(True)
    held, _ = run(False)
    assert fb.Done and sim.positions == held.positions
    a = min(f32(decel), 400.0)
    v = np.vstack([np.array(vel, dtype=np.float32), held.vel()])
    assert np.abs(np.diff(v, axis=0)).max() <= a * DT * (1 + 1e-5) + 1e-4
    assert np.all(v[1:] * np.sign(v[0]) >= -1e-6)  # never reverses
    assert np.all(held.vel()[-1] == 0.0)
    stop = np.array(held.positions[-1]) - [10.0, -20.0, 30.0]
    want = np.array(vel) * np.abs(vel) / (2 * a)
    assert np.abs(stop - want).max() <= np.abs(vel).max() * DT + 1e-3


@examples(100)
@given(decel=real(-10.0, 10.0), cycle=real(-1.0, 1.0))
def test_motion_halt_refuses_bad_parameters(st_module: Any, decel: float, cycle: float) -> None:
    decel, cycle = f32(decel), f32(cycle)
    g = make_group([10.0, -20.0, 30.0])
    g["Velocity"][:3] = [50.0, -20.0, 0.0]
    sim, fb = GroupSim(g), st_module.new_fb("MotionHalt")
    if is_real(decel) and decel > 0 and is_real(cycle) and cycle > 0:
        sim.scan(fb, Execute=True, Deceleration=decel, CycleTime=cycle)
        assert not fb.Error and group_finite(sim.group)
    else:
        sim.assert_rejected(fb, BAD_PARAMETER, Execute=True, Deceleration=decel,
                            CycleTime=cycle)


# --- MotionJog ---------------------------------------------------------------------------------

@examples(25)
@given(commands=st.lists(st.tuples(*[st.one_of(st.floats(-2.0, 2.0), st.sampled_from(
           [1.0, -1.0, 0.0, math.nan, math.inf, 1e30]))] * 3), min_size=5, max_size=60),
       speed=st.floats(5.0, 200.0), acc=st.floats(50.0, 2000.0),
       later=st.tuples(real(-1e3, 1e3), real(-1e4, 1e4)))
def test_motion_jog_scan_by_scan(st_module: Any, commands: list[tuple[float, ...]],
                                 speed: float, acc: float,
                                 later: tuple[float, float]) -> None:
    speed, acc = f32(speed), f32(acc)

    def run(changing: bool) -> tuple[GroupSim, list[int]]:
        q0 = [f32(q) for q in arm.inverse(*P_START)]
        sim, fb = GroupSim(make_group(q0)), st_module.new_fb("MotionJog")
        codes = []
        for k, cmd in enumerate(commands + [(0.0, 0.0, 0.0)] * 0):
            s, a = (f32(later[0]), f32(later[1])) if changing and k else (speed, acc)
            sim.scan(fb, Enable=True, Command=list(cmd), MaxSpeed=s, Acceleration=a,
                     ElbowUp=True, Geometry=GEO, CycleTime=DT)
            codes.append(fb.ErrorId if fb.Error else 0)
            assert fb.Busy and group_finite(sim.group)
        for _ in range(3000):  # Enable FALSE: brake, then Done
            sim.scan(fb, Enable=False, Command=[0.0] * 3, MaxSpeed=speed, Acceleration=acc,
                     ElbowUp=True, Geometry=GEO, CycleTime=DT)
            if fb.Done:
                break
        assert fb.Done and not fb.Busy
        return sim, codes

    sim, codes = run(True)
    held, held_codes = run(False)
    assert sim.positions == held.positions and codes == held_codes  # latched at the edge
    for cmd, code in zip(commands, codes, strict=True):
        assert code == (NOT_FINITE if not all(math.isfinite(c) for c in cmd) else 0)
    # finite differences of the float32 Cartesian setpoints (the block's own start point is
    # not an output, so they start at the first scan): a position resolves to 1.5e-5 mm
    # near 200 mm, a difference of two of them over 10 ms to ~6e-3 mm/s
    vel = np.diff(np.array(held.cartesian), axis=0) / DT
    assert np.linalg.norm(vel, axis=1).max() <= speed * (1 + 1e-4) + 6e-3
    assert np.linalg.norm(np.diff(vel, axis=0), axis=1).max() <= acc * DT * (1 + 1e-3) + 1.2e-2
    assert np.abs(held.pos()).max() <= 170.0 + 1e-4
    # the setpoints are the arm's: FK of the joints is the Cartesian setpoint
    for q, c in zip(held.positions[::7], held.cartesian[::7], strict=True):
        assert np.abs(arm.forward(*q) - c).max() < 5e-3


# --- MotionLinear --------------------------------------------------------------------------------

@examples(15)
@given(target=st.tuples(st.floats(120.0, 230.0), st.floats(-90.0, 90.0),
                        st.floats(60.0, 200.0)),
       velocity=st.floats(20.0, 400.0), acc=st.floats(100.0, 4000.0),
       later=st.tuples(st.floats(-300.0, 300.0), real(-1e3, 1e3)),
       max_vel=st.sampled_from([120.0, 30.0]))
def test_motion_linear_scan_by_scan(st_module: Any, target: tuple[float, float, float],
                                    velocity: float, acc: float, later: tuple[float, float],
                                    max_vel: float) -> None:
    """Method 2: joint speed and acceleration within the group's limits on the finite
    differences, the tool on the line, the end point exact, Progress monotonic; Target and
    Velocity changed while Busy change nothing."""
    target = tuple(f32(v) for v in target)
    inputs = {"Target": list(target), "Velocity": f32(velocity), "Acceleration": f32(acc),
              "LineMethod": 2, "Fineness": 1.0, "ElbowUp": True, "Geometry": GEO,
              "CycleTime": DT}

    def run(changing: bool) -> tuple[GroupSim, Any, list[float], list[float]]:
        q0 = [f32(q) for q in arm.inverse(*P_START)]
        sim = GroupSim(make_group(q0, max_vel=max_vel, max_acc=400.0))
        fb = st_module.new_fb("MotionLinear")
        progress, deviation = [], []
        for k in range(5000):
            cur = dict(inputs)
            if changing and k:
                cur["Target"] = [later[0], 0.0, 100.0]
                cur["Velocity"] = f32(later[1])
            sim.scan(fb, Execute=True, **cur)
            assert group_finite(sim.group)
            progress.append(fb.Progress)
            deviation.append(fb.Deviation)
            if not fb.Busy:
                break
        return sim, fb, progress, deviation

    sim, fb, progress, deviation = run(True)
    held, hfb, _, _ = run(False)
    assert sim.positions == held.positions and fb.ErrorId == hfb.ErrorId
    if fb.Error:
        assert fb.ErrorId in (1, 2, JOINT_LIMIT, PATH_NOT_SMOOTH, 25)
        assert sim.positions[-1] == sim.start  # a refused line changes nothing
        return
    assert fb.Done
    q = np.vstack([np.array(sim.start), sim.pos()])
    vel = np.diff(q, axis=0) / DT
    assert np.abs(vel).max() <= max_vel * (1 + 1e-4) + 1e-3
    assert np.abs(np.diff(np.vstack([np.zeros(3), vel]), axis=0)).max() / DT <= 400.0 * (
        1 + 1e-3) + 0.5
    assert np.abs(np.array(sim.cartesian[-1]) - target).max() < 1e-3
    assert np.abs(arm.forward(*sim.positions[-1]) - target).max() < 5e-3
    assert all(b >= a for a, b in zip(progress, progress[1:], strict=False))
    assert progress[-1] == 1.0 and max(deviation) < 0.05
    p0, p1 = arm.forward(*sim.start), np.array(target)
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    for c in sim.cartesian:
        off = np.array(c) - p0
        assert np.linalg.norm(off - np.dot(off, u) * u) < 0.05


# --- The wrist pose and jog of the 5-axis arm ------------------------------------------------

Q0_5 = [15.0, 80.0, 100.0, -20.0, 10.0]


@examples(200)
@given(pitch=real(-360.0, 360.0), roll=real(-1e3, 1e3), tip_fixed=st.booleans(),
       check_speed=st.booleans())
@example(pitch=91.0, roll=0.0, tip_fixed=True, check_speed=False)  # past the vertical
def test_motion_wrist_pose(st_module: Any, pitch: float, roll: float, tip_fixed: bool,
                           check_speed: bool) -> None:
    pitch, roll = f32(pitch), f32(roll)
    prev = [f32(v) for v in Q0_5] + [0.0]
    tip = fk5(prev[:5], G, TOOL_MM)[1][:3, 3]
    limits = {"LowerDeg": [-170.0] * 6, "UpperDeg": [170.0] * 6, "MaxVelDeg": [120.0] * 6,
              "MaxAccDeg": [400.0] * 6}
    fb = st_module.new_fb("MotionWristPose")
    fb(PitchDeg=pitch, RollDeg=roll, TipFixed=tip_fixed, ElbowUp=True, TipXMm=f32(tip[0]),
       TipYMm=f32(tip[1]), TipZMm=f32(tip[2]), Geometry=GEO5, CheckSpeed=check_speed,
       Period=DT, Prev=list(prev), Limits=limits)
    joints = list(fb.Joints)
    assert all(math.isfinite(v) for v in joints) and joints[5] == prev[5]
    if not fb.Ok:
        assert fb.Code != 0
        if fb.Code != JOINT_LIMIT:
            assert joints == prev  # the IK failed: Prev
        return
    assert fb.Code == 0
    inside = all(-170.0 <= v <= 170.0 for v in joints[:5])
    assert inside
    if check_speed:
        assert max(abs(a - b) for a, b in zip(joints[:5], prev[:5], strict=True)) <= (
            120.0 * DT * (1 + 1e-5))
    if tip_fixed:
        _, tool = fk5(joints[:5], G, TOOL_MM)
        assert np.abs(tool[:3, 3] - tip).max() < 0.02
        # the pitch is signed in the vertical plane through the tip (0 away from the base
        # axis, 90 up, 180 back towards it), over the whole turn: an elevation
        # (five_axis_ref.tool_pitch, -90..90) folds 91 deg onto 89 and cannot tell them apart
        x_axis, out = tool[:3, 0], tip[:2] / math.hypot(tip[0], tip[1])
        got_pitch = math.degrees(math.atan2(x_axis[2], float(x_axis[:2] @ out)))
        assert abs(math.remainder(got_pitch - pitch, 360.0)) < 1e-2
    else:
        assert joints[:3] == prev[:3] and joints[3] == pitch
        assert joints[4] == roll


@examples(20)
@given(rates=st.lists(st.tuples(st.one_of(st.floats(-200.0, 200.0), st.sampled_from(
           [math.nan, math.inf, 0.0])), st.floats(-200.0, 200.0)), min_size=5, max_size=50),
       tip_fixed=st.booleans(), speed=st.floats(5.0, 100.0), acc=st.floats(50.0, 1000.0),
       later=st.tuples(real(-1e5, 1e5), real(-1e7, 1e7)))
def test_motion_jog_wrist_scan_by_scan(st_module: Any, rates: list[tuple[float, float]],
                                       tip_fixed: bool, speed: float, acc: float,
                                       later: tuple[float, float]) -> None:
    speed, acc = f32(speed), f32(acc)

    def run(changing: bool) -> tuple[GroupSim, list[int], list[Any]]:
        sim = GroupSim(make_group([f32(v) for v in Q0_5], joints=5))
        fb = st_module.new_fb("MotionJogWrist")
        codes, tips = [], []
        for k, (p, r) in enumerate(rates):
            s, a = (f32(later[0]), f32(later[1])) if changing and k else (speed, acc)
            sim.scan(fb, Enable=True, PitchRate=p, RollRate=r, MaxSpeed=s, Acceleration=a,
                     TipFixed=tip_fixed, Geometry=GEO5, CycleTime=DT)
            codes.append(fb.ErrorId if fb.Error else 0)
            tips.append((fb.TipXMm, fb.TipYMm, fb.TipZMm))
            assert fb.Busy and group_finite(sim.group)
        for _ in range(3000):
            sim.scan(fb, Enable=False, PitchRate=0.0, RollRate=0.0, MaxSpeed=speed,
                     Acceleration=acc, TipFixed=tip_fixed, Geometry=GEO5, CycleTime=DT)
            if fb.Done:
                break
        assert fb.Done
        return sim, codes, tips

    sim, codes, _ = run(True)
    held, held_codes, tips = run(False)
    assert sim.positions == held.positions and codes == held_codes
    for (p, _), code in zip(rates, codes, strict=True):
        assert code == (NOT_FINITE if not math.isfinite(p) else 0)
    q = np.vstack([np.array(held.start), held.pos()])
    vel = np.diff(q, axis=0) / DT
    assert np.abs(vel).max() <= 120.0 * (1 + 1e-4) + 1e-3  # the group's speed limit
    assert np.abs(q).max() <= 170.0 + 1e-4
    if tip_fixed:
        tip0 = fk5(held.start, G, TOOL_MM)[1][:3, 3]
        for pos in held.positions:
            assert np.abs(fk5(pos, G, TOOL_MM)[1][:3, 3] - tip0).max() < 0.05
    else:
        wrist = np.array([v[3:5] for v in held.positions])
        # the pitch/roll pair: speed within MaxSpeed, speed change within Acceleration
        wvel = np.diff(np.vstack([np.array(held.start[3:5]), wrist]), axis=0) / DT
        assert np.linalg.norm(wvel, axis=1).max() <= speed * (1 + 1e-4) + 1e-3
        assert np.linalg.norm(np.diff(np.vstack([np.zeros(2), wvel]), axis=0), axis=1).max() <= (
            acc * DT * (1 + 1e-3) + 1e-2)
        assert all(pos[:3] == held.start[:3] for pos in held.positions)
