"""Shared machinery of the jerk-limited generator tests (st/MotionJerk*.st) and of
bench/jerk_vs_ruckig.py: the case families drawn from a seeded generator, Ruckig (PyPI
`ruckig`, the reference) on the same inputs, and independent float64 checks of a profile
returned by the ST.

The independent checks never use the ST's own knots: a profile's start state and its phase
times and jerks (T, J, and the brake's) are integrated here in float64 to find where it ends
and the largest |velocity| and |acceleration| it reaches (exactly: per phase, the
acceleration is linear and the velocity's extremum is where the acceleration crosses zero).
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

F32_EPS = 2.0**-23  # float32's unit roundoff: the "float32 tolerance" of positions

#: the case families of the issue: rest-to-rest, moving starts with acceleration, non-zero
#: target velocity, very short and very long moves, near-degenerate limits; plus starts
#: outside the limits (the brake pre-trajectory) and separate minimum limits
FAMILIES = ("rest", "moving", "target_velocity", "short", "long", "degenerate", "outside",
            "asymmetric")


@dataclass(frozen=True)
class AxisCase:
    """One axis: start, target and limits (Ruckig's min_* are -max_* unless separate)."""

    p0: float
    v0: float
    a0: float
    pf: float
    vf: float
    vmax: float
    amax: float
    jmax: float
    vmin: float | None = None
    amin: float | None = None
    af: float = 0.0

    @property
    def v_lo(self) -> float:
        return -self.vmax if self.vmin is None else self.vmin

    @property
    def a_lo(self) -> float:
        return -self.amax if self.amin is None else self.amin

    def limits_st(self) -> dict[str, Any]:
        """The MotionJerkLimits STRUCT."""
        return {"MaxVel": self.vmax, "MaxAcc": self.amax, "MaxJerk": self.jmax,
                "SeparateMin": self.vmin is not None or self.amin is not None,
                "MinVel": self.v_lo, "MinAcc": self.a_lo}


@dataclass(frozen=True)
class MultiCase:
    """Several axes planned together."""

    axes: tuple[AxisCase, ...]
    family: str = ""

    @property
    def dofs(self) -> int:
        return len(self.axes)


def _log_uniform(rng: random.Random, lo: float, hi: float) -> float:
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def _limits(rng: random.Random) -> tuple[float, float, float]:
    """Limits over four decades of speed with the two time constants free: the time to reach
    the velocity limit at full acceleration (vmax / amax, 5 ms .. 5 s) and to reach the
    acceleration limit at full jerk (amax / jmax, 2 ms .. 2 s), so that any of the three
    limits can bind."""
    vmax = _log_uniform(rng, 0.01, 100.0)
    amax = vmax / _log_uniform(rng, 0.005, 5.0)
    jmax = amax / _log_uniform(rng, 0.002, 2.0)
    return vmax, amax, jmax


def _state_inside(rng: random.Random, vmax: float, amax: float, jmax: float,
                  vlo: float | None = None, alo: float | None = None) -> tuple[float, float]:
    """A velocity and acceleration inside the limits from which the velocity limit is not
    crossed inevitably (v0 + a0|a0| / 2j stays within [vlo, vmax])."""
    vlo = -vmax if vlo is None else vlo
    alo = -amax if alo is None else alo
    for _ in range(100):
        v0 = rng.uniform(vlo, vmax)
        a0 = rng.uniform(alo, amax)
        v_at_a0 = v0 + a0 * abs(a0) / (2.0 * jmax)
        if vlo <= v_at_a0 <= vmax:
            return v0, a0
    return rng.uniform(vlo, vmax), 0.0


def axis_case(rng: random.Random, family: str) -> AxisCase:
    """One random single-axis case of `family` (FAMILIES)."""
    vmax, amax, jmax = _limits(rng)
    # the distance of a typical move: a few times the distance to brake from vmax
    scale = vmax * (vmax / amax + amax / jmax)
    p0 = rng.uniform(-10.0, 10.0) * scale
    if family == "rest":
        return AxisCase(p0, 0.0, 0.0, p0 + rng.uniform(-5.0, 5.0) * scale, 0.0, vmax, amax,
                        jmax)
    if family == "moving":
        v0, a0 = _state_inside(rng, vmax, amax, jmax)
        return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale, 0.0, vmax, amax, jmax)
    if family == "target_velocity":
        v0, a0 = _state_inside(rng, vmax, amax, jmax)
        return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale,
                        rng.uniform(-vmax, vmax), vmax, amax, jmax)
    if family == "short":
        # 1e-7 .. 1e-2 of the typical distance, from rest or slowly moving
        d = _log_uniform(rng, 1e-7, 1e-2) * scale * rng.choice((-1.0, 1.0))
        slow = rng.random() < 0.5
        v0 = rng.uniform(-1e-3, 1e-3) * vmax if slow else 0.0
        return AxisCase(p0, v0, 0.0, p0 + d, 0.0, vmax, amax, jmax)
    if family == "long":
        d = _log_uniform(rng, 1e1, 1e3) * scale * rng.choice((-1.0, 1.0))
        v0, a0 = _state_inside(rng, vmax, amax, jmax)
        vf = rng.uniform(-vmax, vmax) if rng.random() < 0.5 else 0.0
        return AxisCase(p0, v0, a0, p0 + d, vf, vmax, amax, jmax)
    if family == "degenerate":
        return _degenerate(rng, p0, scale)
    if family == "outside":
        # beyond the limits (velocity, acceleration or both): Ruckig brakes first
        v0 = rng.uniform(-1.6, 1.6) * vmax
        a0 = rng.uniform(-1.6, 1.6) * amax
        return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale, 0.0, vmax, amax, jmax)
    if family == "asymmetric":
        vlo = -_log_uniform(rng, 0.1, 3.0) * vmax
        alo = -_log_uniform(rng, 0.1, 3.0) * amax
        v0, a0 = _state_inside(rng, vmax, amax, jmax, vlo, alo)
        vf = rng.uniform(vlo, vmax) if rng.random() < 0.5 else 0.0
        return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale, vf, vmax, amax, jmax,
                        vmin=vlo, amin=alo)
    raise ValueError(f"unknown family {family!r}: one of {FAMILIES}")


def _degenerate(rng: random.Random, p0: float, scale: float) -> AxisCase:
    """Limits or states at the boundaries between profile shapes."""
    vmax, amax, jmax = _limits(rng)
    kind = rng.randrange(6)
    if kind == 0:
        # the acceleration plateau just vanishes: vmax = amax^2 / jmax (1 +- tiny)
        vmax = amax * amax / jmax * (1.0 + rng.choice((-1.0, 1.0)) * _log_uniform(rng, 1e-9, 1e-3))
    elif kind == 1:
        # nearly second order (huge jerk) or nearly first order (huge acceleration)
        if rng.random() < 0.5:
            jmax = amax * _log_uniform(rng, 1e3, 1e5)
        else:
            amax = vmax * _log_uniform(rng, 1e2, 1e4)
            jmax = amax * _log_uniform(rng, 1e1, 1e3)
    elif kind == 2:
        # tiny jerk: the move is all jerk phases
        jmax = amax * amax / vmax * _log_uniform(rng, 1e-4, 1e-2)
    elif kind == 3:
        # the distance that exactly reaches vmax with both plateaus (cruise of length ~0)
        pass
    scale = vmax * (vmax / amax + amax / jmax)
    if kind == 3:
        t_acc = amax / jmax
        dist_ramp = vmax * (vmax / amax + t_acc)  # rest to rest reaching vmax, no cruise
        d = dist_ramp * (1.0 + rng.choice((-1.0, 1.0)) * _log_uniform(rng, 1e-10, 1e-4))
        return AxisCase(p0, 0.0, 0.0, p0 + rng.choice((-1.0, 1.0)) * d, 0.0, vmax, amax, jmax)
    if kind == 4:
        # the start on the limits
        v0 = rng.choice((vmax, -vmax, 0.0))
        a0 = 0.0 if v0 != 0.0 else rng.choice((amax, -amax))
        if v0 == 0.0 and a0 * a0 / (2.0 * jmax) > vmax:
            a0 = math.copysign(math.sqrt(2.0 * jmax * vmax), a0)
        return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale,
                        rng.choice((0.0, vmax, -vmax)), vmax, amax, jmax)
    if kind == 5:
        # the target already reached, or the start exactly at the target's velocity
        vf = rng.uniform(-vmax, vmax)
        return AxisCase(p0, vf, 0.0, p0 + rng.choice((0.0, 1e-12 * scale)), vf, vmax, amax,
                        jmax)
    v0, a0 = _state_inside(rng, vmax, amax, jmax)
    return AxisCase(p0, v0, a0, p0 + rng.uniform(-5.0, 5.0) * scale,
                    rng.choice((0.0, rng.uniform(-vmax, vmax))), vmax, amax, jmax)


def axis_cases(seed: int, per_family: int,
               families: tuple[str, ...] = FAMILIES) -> Iterator[tuple[str, AxisCase]]:
    """`per_family` cases of each family, deterministic for a seed."""
    for k, family in enumerate(families):
        rng = random.Random(seed * 1000 + k)
        for _ in range(per_family):
            yield family, axis_case(rng, family)


def multi_case(rng: random.Random, family: str, dofs: int) -> MultiCase:
    return MultiCase(tuple(axis_case(rng, family) for _ in range(dofs)), family)


# ----------------------------------------------------------------------------- Ruckig


@dataclass
class RuckigAnswer:
    """Ruckig's result on a case: its Result name, duration and trajectory."""

    result: str
    duration: float
    trajectory: Any = field(repr=False)
    min_durations: list[float] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.result == "Working"

    def at(self, t: float) -> tuple[list[float], list[float], list[float]]:
        p, v, a = self.trajectory.at_time(t)
        return list(p), list(v), list(a)


def ruckig_plan(axes: tuple[AxisCase, ...] | list[AxisCase], synchronization: str = "Time",
                interface: str = "Position",
                minimum_duration: float | None = None) -> RuckigAnswer:
    """Ruckig's offline calculation (Ruckig.calculate) of `axes` together; with
    `minimum_duration` every axis is synchronised to at least that duration (so a single
    axis goes through Ruckig's step 2)."""
    import ruckig

    n = len(axes)
    otg = ruckig.Ruckig(n)
    inp = ruckig.InputParameter(n)
    inp.current_position = [c.p0 for c in axes]
    inp.current_velocity = [c.v0 for c in axes]
    inp.current_acceleration = [c.a0 for c in axes]
    inp.target_position = [c.pf for c in axes]
    inp.target_velocity = [c.vf for c in axes]
    inp.target_acceleration = [c.af for c in axes]
    inp.max_velocity = [c.vmax for c in axes]
    inp.max_acceleration = [c.amax for c in axes]
    inp.max_jerk = [c.jmax for c in axes]
    if any(c.vmin is not None for c in axes):
        inp.min_velocity = [c.v_lo for c in axes]
    if any(c.amin is not None for c in axes):
        inp.min_acceleration = [c.a_lo for c in axes]
    # the binding spells Synchronization.None "No" (None is a Python keyword)
    inp.synchronization = getattr(ruckig.Synchronization,
                                  "No" if synchronization == "None" else synchronization)
    inp.control_interface = getattr(ruckig.ControlInterface, interface)
    if minimum_duration is not None:
        inp.minimum_duration = minimum_duration
    traj = ruckig.Trajectory(n)
    try:
        name = str(otg.calculate(inp, traj)).split(".")[-1]
    except ValueError as exc:
        # the binding's Result enum lacks -101 (ErrorTrajectoryDuration: longer than 7600 s)
        if "-101" not in str(exc):
            raise
        name = "ErrorTrajectoryDuration"
    except ruckig.RuckigError as exc:  # the binding throws instead of returning errors
        first = [ln for ln in str(exc).splitlines() if ln.strip()][0]
        return RuckigAnswer(f"Error: {first}", math.nan, None)
    mins = list(traj.independent_min_durations) if name == "Working" else []
    return RuckigAnswer(name, traj.duration if name == "Working" else math.nan, traj, mins)


# ----------------------------------------------------------------------------- checks


@dataclass(frozen=True)
class Extremes:
    """What a profile puts out, recomputed here in float64."""

    end: tuple[float, float, float]        # p, v, a at the end (its last knot)
    v_hi: float                            # largest velocity after the brake
    v_lo: float                            # smallest velocity after the brake
    a_hi: float
    a_lo: float
    j_abs: float                           # largest |jerk|
    duration: float
    jump: tuple[float, float, float]       # largest |p|, |v|, |a| step at a knot


def _phase(p: float, v: float, a: float, j: float, t: float) -> tuple[float, float, float]:
    return (p + t * (v + t * (a / 2.0 + t * j / 6.0)), v + t * (a + t * j / 2.0), a + t * j)


def extremes(prof: dict[str, Any], p0: float, v0: float, a0: float) -> Extremes:
    """`prof` (an ST MotionJerkProfile) recomputed from the start (p0, v0, a0): the brake
    phases integrated from the start, then each of the seven phases integrated from its
    start knot (what MotionJerkAt and Ruckig's at_time evaluate; the knots of a limit that
    a case reaches are set exactly, e.g. a zero acceleration for the cruise), its end
    compared with the next knot (``jump``: the trajectory's steps, rounding only), its
    velocity and acceleration extrema taken exactly (the acceleration is linear in a phase,
    the velocity's extremum is where the acceleration crosses zero). The limits part covers
    the seven phases (the brake exists to bring a start outside the limits back inside)."""
    p, v, a = p0, v0, a0
    j_abs = 0.0
    duration = 0.0
    if prof["BrakeDuration"] > 0.0:
        for k in range(2):
            t = prof["BrakeT"][k]
            if k == 1 and t <= 0.0:
                break
            j_abs = max(j_abs, abs(prof["BrakeJ"][k]))
            p, v, a = _phase(p, v, a, prof["BrakeJ"][k], t)
            duration += t
    jump = [abs(p - prof["P"][0]), abs(v - prof["V"][0]), abs(a - prof["A"][0])]
    p, v, a = prof["P"][0], prof["V"][0], prof["A"][0]
    v_hi = v_lo = v
    a_hi = a_lo = a
    for k in range(7):
        t, j = prof["T"][k], prof["J"][k]
        j_abs = max(j_abs, abs(j))
        p1, v1, a1 = _phase(p, v, a, j, t)
        v_hi, v_lo = max(v_hi, v1), min(v_lo, v1)
        a_hi, a_lo = max(a_hi, a1), min(a_lo, a1)
        if j != 0.0:
            tz = -a / j  # the velocity's extremum inside the phase
            if 0.0 < tz < t:
                vz = _phase(p, v, a, j, tz)[1]
                v_hi, v_lo = max(v_hi, vz), min(v_lo, vz)
        p, v, a = prof["P"][k + 1], prof["V"][k + 1], prof["A"][k + 1]
        jump = [max(jump[0], abs(p1 - p)), max(jump[1], abs(v1 - v)),
                max(jump[2], abs(a1 - a))]
        v_hi, v_lo = max(v_hi, v), min(v_lo, v)
        a_hi, a_lo = max(a_hi, a), min(a_lo, a)
        duration += t
    return Extremes((p, v, a), v_hi, v_lo, a_hi, a_lo, j_abs, duration,
                    (jump[0], jump[1], jump[2]))


def jump_problems(case: AxisCase, ex: Extremes, duration: float) -> list[str]:
    """Steps at the knots beyond rounding: 1e-9 of the move's scale in position, of the
    limits in velocity and acceleration."""
    out = []
    span = max(abs(case.p0), abs(case.pf), abs(case.v0) * duration, case.vmax * duration, 1.0)
    if ex.jump[0] > 1e-9 * span:
        out.append(f"position steps by {ex.jump[0]!r} at a knot")
    if ex.jump[1] > 1e-9 * max(case.vmax, abs(case.v_lo), abs(case.v0), 1.0):
        out.append(f"velocity steps by {ex.jump[1]!r} at a knot")
    if ex.jump[2] > 1e-9 * max(case.amax, abs(case.a_lo), abs(case.a0), 1.0):
        out.append(f"acceleration steps by {ex.jump[2]!r} at a knot")
    return out


def pos_tolerance(case: AxisCase, duration: float) -> float:
    """float32 tolerance of a position along the move: float32's unit roundoff times the
    largest magnitude the move involves (its positions and the distance it can cover)."""
    span = max(abs(case.p0), abs(case.pf), abs(case.pf - case.p0),
               max(abs(case.vmax), abs(case.v_lo), abs(case.v0)) * duration, 1e-30)
    return F32_EPS * span


def limit_violations(case: AxisCase, ex: Extremes, rel: float = 1e-9) -> list[str]:
    """The limits a profile exceeds after its brake (empty when it stays inside), with a
    relative slack `rel` for float64 rounding."""
    out = []
    if ex.v_hi > case.vmax * (1.0 + rel) + 1e-12:
        out.append(f"velocity {ex.v_hi!r} > {case.vmax!r}")
    if ex.v_lo < case.v_lo * (1.0 + rel) - 1e-12:
        out.append(f"velocity {ex.v_lo!r} < {case.v_lo!r}")
    if ex.a_hi > case.amax * (1.0 + rel) + 1e-12:
        out.append(f"acceleration {ex.a_hi!r} > {case.amax!r}")
    if ex.a_lo < case.a_lo * (1.0 + rel) - 1e-12:
        out.append(f"acceleration {ex.a_lo!r} < {case.a_lo!r}")
    if ex.j_abs > case.jmax * (1.0 + 1e-12):
        out.append(f"jerk {ex.j_abs!r} > {case.jmax!r}")
    return out


def inside_at_start(case: AxisCase) -> bool:
    """The start is inside the limits and will not cross the velocity limit inevitably (the
    cases for which Ruckig promises to stay within the limits from the first instant)."""
    v_at_a0 = case.v0 + case.a0 * abs(case.a0) / (2.0 * case.jmax)
    return (case.v_lo <= case.v0 <= case.vmax and case.a_lo <= case.a0 <= case.amax
            and case.v_lo <= v_at_a0 <= case.vmax)


def percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    if not s:
        return math.nan
    return s[min(len(s) - 1, int(q * (len(s) - 1) + 0.5))]


# ----------------------------------------------------------------------------- the ST side


@dataclass
class StPlan:
    """MotionJerkPlanner's answer."""

    valid: bool
    error_id: int
    duration: float
    limiting: int
    profiles: list[dict[str, Any]]
    min_durations: list[float]


class StRunner:
    """The ST planner (one MotionJerkPlanner instance) and MotionJerkAt of a compiled module
    (armbench.compiler.compile_files of st/*.st, or the st_module fixture)."""

    SYNC = {"Time": 0, "Phase": 1, "None": 2, "TimeIfNecessary": 3}

    def __init__(self, module: Any, planner: Any | None = None) -> None:
        self.module = module
        self.fb = planner if planner is not None else module.new_fb("MotionJerkPlanner")

    def plan(self, axes: tuple[AxisCase, ...] | list[AxisCase], synchronization: str = "Time",
             interface: str = "Position", joints: int | None = None) -> StPlan:
        n = len(axes)
        pad = 6 - n

        def vec(values: list[float]) -> list[float]:
            return list(values) + [0.0] * pad

        unused = AxisCase(0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0).limits_st()
        limits = [c.limits_st() for c in axes] + [unused] * pad
        fb = self.fb
        fb(Joints=n if joints is None else joints, VelocityMode=interface == "Velocity",
           Sync=self.SYNC[synchronization],
           CurrentPos=vec([c.p0 for c in axes]), CurrentVel=vec([c.v0 for c in axes]),
           CurrentAcc=vec([c.a0 for c in axes]), TargetPos=vec([c.pf for c in axes]),
           TargetVel=vec([c.vf for c in axes]), TargetAcc=vec([c.af for c in axes]),
           Limits=limits)
        if not fb.Valid:
            return StPlan(False, fb.ErrorId, math.nan, 0, [], [])
        return StPlan(True, fb.ErrorId, fb.Duration, fb.LimitingJoint, fb.Profiles[:n],
                      fb.MinDurations[:n])

    def at(self, profile: dict[str, Any], t: float) -> tuple[float, float, float, float]:
        pt = self.module.call("MotionJerkAt", Prof=profile, TimeS=t)
        return pt["Pos"], pt["Vel"], pt["Acc"], pt["Jerk"]


def expected_error_ids(ref: RuckigAnswer) -> set[int]:
    """The ErrorIds (st/MotionJerkSync.st) that correspond to Ruckig's failure."""
    r = ref.result
    if r == "ErrorTrajectoryDuration":
        return {29}
    if "error in step 1" in r:
        return {27}
    if "step 2" in r or "synchronization" in r:
        return {28}
    if r == "ErrorInvalidInput" or "should be" in r or "exceeds" in r or "undercuts" in r \
            or "inevitably" in r:
        return {8, 26}
    return set()


@dataclass
class CaseCheck:
    """What one case gave: the duration error against Ruckig and what failed."""

    rel_duration_error: float = 0.0
    pos_error: float = 0.0          # largest |position - Ruckig's| along the trajectory
    pos_error_rel_tol: float = 0.0  # the same over its float32 tolerance (<= 1 passes)
    limit_ratio: float = 0.0        # largest |velocity|, |acceleration| or |jerk| reached
    #                                 over its limit (after a brake; <= 1 within the limits)
    problems: list[str] = field(default_factory=list)
    agreed_error: bool = False      # both refused the input, with corresponding codes


def check_plan(runner: StRunner, axes: tuple[AxisCase, ...], synchronization: str = "Time",
               interface: str = "Position", samples: int = 16) -> CaseCheck:
    """Plan `axes` with the ST and with Ruckig and compare: validity / ErrorId, the duration,
    every axis' positions along the trajectory at `samples` + 2 times (and half a duration
    beyond the end), and -- integrated here from each axis' start -- that every axis ends at
    its target after the synchronised duration and stays within its limits."""
    out = CaseCheck()
    ref = ruckig_plan(axes, synchronization, interface)
    got = runner.plan(axes, synchronization, interface)
    if not ref.ok:
        if got.valid:
            out.problems.append(f"Ruckig: {ref.result}, the ST planned {got.duration!r} s")
        elif got.error_id not in expected_error_ids(ref):
            out.problems.append(f"Ruckig: {ref.result}, the ST's ErrorId {got.error_id}")
        else:
            out.agreed_error = True
        return out
    if not got.valid:
        out.problems.append(f"the ST refused (ErrorId {got.error_id}), Ruckig planned "
                            f"{ref.duration!r} s")
        return out
    out.rel_duration_error = abs(got.duration - ref.duration) / max(ref.duration, 1e-300)
    if ref.duration == 0.0:
        out.rel_duration_error = abs(got.duration)
    if out.rel_duration_error > 1e-4:
        out.problems.append(f"duration {got.duration!r} vs Ruckig's {ref.duration!r}")
    for k in range(len(axes)):
        mine = got.min_durations[k]
        theirs = ref.min_durations[k]
        if abs(mine - theirs) > 1e-4 * max(theirs, 1e-300) and theirs > 0.0:
            out.problems.append(f"axis {k + 1}: shortest duration {mine!r} vs {theirs!r}")
    times = [ref.duration * i / samples for i in range(samples + 1)] + [1.5 * ref.duration]
    for t in times:
        p_ref, v_ref, a_ref = ref.at(t)
        for k, case in enumerate(axes):
            p, v, a, _ = runner.at(got.profiles[k], t)
            if not all(math.isfinite(x) for x in (p, v, a)):
                out.problems.append(f"axis {k + 1} at {t}: not finite")
                continue
            if interface == "Position" and inside_at_start(case):
                # the ST's own evaluation, sampled: inside the limits too
                if not (case.v_lo * (1 + 1e-9) - 1e-12 <= v <= case.vmax * (1 + 1e-9) + 1e-12
                        and case.a_lo * (1 + 1e-9) - 1e-12 <= a
                        <= case.amax * (1 + 1e-9) + 1e-12):
                    out.problems.append(f"axis {k + 1} at t = {t!r}: v {v!r}, a {a!r} beyond "
                                        "the limits")
            err = abs(p - p_ref[k])
            tol = pos_tolerance(case, ref.duration)
            out.pos_error = max(out.pos_error, err)
            out.pos_error_rel_tol = max(out.pos_error_rel_tol, err / tol)
            if err > tol:
                out.problems.append(f"axis {k + 1} at t = {t!r}: position {p!r} vs Ruckig's "
                                    f"{p_ref[k]!r} (float32 tolerance {tol:.3g})")
    for k, case in enumerate(axes):
        prof = got.profiles[k]
        ex = extremes(prof, case.p0, case.v0, case.a0)
        own = prof["TSum"][6] + prof["BrakeDuration"]
        if abs(ex.duration - own) > 1e-9 * max(own, 1.0):
            out.problems.append(f"axis {k + 1}: phases sum to {ex.duration!r}, TSum {own!r}")
        synced = synchronization in ("Time", "Phase") or (
            synchronization == "TimeIfNecessary" and (case.vf != 0.0 or case.af != 0.0))
        if synced and abs(own - got.duration) > 1e-9 * max(got.duration, 1.0):
            out.problems.append(f"axis {k + 1}: lasts {own!r}, not the common {got.duration!r}")
        out.problems += [f"axis {k + 1}: {p}" for p in jump_problems(case, ex, own)]
        scale = max(abs(case.p0), abs(case.pf), 1.0)
        if interface == "Position" and abs(ex.end[0] - case.pf) > 1e-7 * scale:
            out.problems.append(f"axis {k + 1}: ends at {ex.end[0]!r}, target {case.pf!r}")
        if abs(ex.end[1] - case.vf) > 1e-7 * max(abs(case.vmax), abs(case.v_lo), 1.0):
            out.problems.append(f"axis {k + 1}: ends at velocity {ex.end[1]!r}, target "
                                f"{case.vf!r}")
        if abs(ex.end[2] - case.af) > 1e-7 * max(case.amax, 1.0):
            out.problems.append(f"axis {k + 1}: ends at acceleration {ex.end[2]!r}")
        if interface == "Position" and inside_at_start(case):
            out.problems += [f"axis {k + 1}: {p}" for p in limit_violations(case, ex)]
            out.limit_ratio = max(out.limit_ratio, ex.v_hi / case.vmax, ex.a_hi / case.amax,
                                  ex.j_abs / case.jmax,
                                  ex.v_lo / case.v_lo if case.v_lo < 0.0 else 0.0,
                                  ex.a_lo / case.a_lo)
        elif interface == "Velocity" and case.a_lo <= case.a0 <= case.amax:
            out.problems += [f"axis {k + 1}: {p}" for p in limit_violations(
                AxisCase(case.p0, case.v0, case.a0, case.pf, case.vf, math.inf, case.amax,
                         case.jmax, -math.inf, case.amin), ex)]
            out.limit_ratio = max(out.limit_ratio, ex.a_hi / case.amax, ex.a_lo / case.a_lo,
                                  ex.j_abs / case.jmax)
    return out


def collinear_case(rng: random.Random, dofs: int, moving: bool) -> MultiCase:
    """Axes whose displacements (and, when moving, velocities and accelerations) are one
    vector times exact powers of two (so that they are collinear to the last bit, as Ruckig's
    phase synchronisation requires: it compares to 2.2e-16), each with its own limits."""
    base = axis_case(rng, "moving" if moving else "rest")
    d = base.pf - base.p0
    axes = []
    for _ in range(dofs):
        k = rng.choice((-2.0, -1.0, -0.5, -0.25, 0.25, 0.5, 1.0, 2.0))
        vmax, amax, jmax = _limits(rng)
        # generous enough that the scaled start lies inside this axis' limits
        vmax = max(vmax, abs(k * base.v0) * 1.5)
        amax = max(amax, abs(k * base.a0) * 1.5)
        axes.append(AxisCase(0.0, k * base.v0, k * base.a0, k * d, 0.0, vmax, amax, jmax))
    return MultiCase(tuple(axes), "phase_moving" if moving else "phase_rest")


# ------------------------------------------------------------------ the compiler cross-check
#: the program both compiler cross-checks (MatIEC in test_motion_jerk_matiec.py, STruC++ in
#: tests/export/strucpp_cases.py) run: three axes planned together from a moving start to a
#: target velocity, sampled at CROSS_TIMES; a velocity-interface jog; 60 generator cycles
#: with a target change at cycle 30
CROSS_AXES = (AxisCase(0.5, 0.4, -0.3, 2.0, 0.2, 1.0, 2.0, 8.0),
              AxisCase(-1.0, 0.0, 0.0, -3.0, 0.0, 0.7, 3.0, 5.0),
              AxisCase(0.0, -0.2, 0.5, 0.25, 0.0, 2.0, 1.0, 3.0))
CROSS_JOG = AxisCase(0.0, 0.3, 0.0, 0.0, -0.8, 1.0, 2.0, 6.0)
CROSS_TIMES = (0.3, 1.1, 2.5)

#: the declarations CROSS_BODY needs, one a line, indented for a VAR block
CROSS_DECLS = """    Plan : MotionJerkPlanner;
    Jog : MotionJerkPlanner;
    Gen : MotionJerkGenerator;
    Lim : MotionJerkLimitSet;
    CurP : MotionJerkVector;
    CurV : MotionJerkVector;
    CurA : MotionJerkVector;
    TgtP : MotionJerkVector;
    TgtV : MotionJerkVector;
    Zero : MotionJerkVector;
    JogV : MotionJerkVector;
    JogT : MotionJerkVector;
    Pt : MotionJerkPoint;
    K : INT;"""


@dataclass(frozen=True)
class CrossOutputs:
    """Where the cross-check program stores its results: ST variables (or array elements)
    named by the caller. ``sample`` takes (time index from 0, axis from 1)."""

    duration: str
    error_id: str
    sample: Callable[[int, int], str]
    jog_duration: str
    jog_end: str
    gen_p1: str
    gen_v2: str
    gen_a3: str
    plans: str


def cross_body(lit: Any, out: CrossOutputs) -> str:
    """The statements of the cross-check program, indented by two spaces; ``lit`` spells a
    float as an ST literal."""
    lines = []
    for name, values in (("CurP", [c.p0 for c in CROSS_AXES]),
                         ("CurV", [c.v0 for c in CROSS_AXES]),
                         ("CurA", [c.a0 for c in CROSS_AXES]),
                         ("TgtP", [c.pf for c in CROSS_AXES]),
                         ("TgtV", [c.vf for c in CROSS_AXES])):
        lines += [f"  {name}[{k}] := {lit(v)};" for k, v in enumerate(values, 1)]
    for k, c in enumerate(CROSS_AXES, 1):
        lines += [f"  Lim[{k}].MaxVel := {lit(c.vmax)};", f"  Lim[{k}].MaxAcc := {lit(c.amax)};",
                  f"  Lim[{k}].MaxJerk := {lit(c.jmax)};"]
    lines += ["  Plan(Joints := 3, VelocityMode := FALSE, Sync := 0, CurrentPos := CurP,",
              "       CurrentVel := CurV, CurrentAcc := CurA, TargetPos := TgtP,",
              "       TargetVel := TgtV, TargetAcc := Zero, Limits := Lim);",
              f"  {out.duration} := Plan.Duration;", f"  {out.error_id} := Plan.ErrorId;"]
    for i, t in enumerate(CROSS_TIMES):
        for k in range(1, 4):
            lines += [f"  Pt := MotionJerkAt(Prof := Plan.Profiles[{k}], TimeS := {lit(t)});",
                      f"  {out.sample(i, k)} := Pt.Pos;"]
    j = CROSS_JOG
    lines += [f"  JogV[1] := {lit(j.v0)};", f"  JogT[1] := {lit(j.vf)};",
              f"  Lim[4].MaxVel := {lit(j.vmax)};", f"  Lim[4].MaxAcc := {lit(j.amax)};",
              f"  Lim[4].MaxJerk := {lit(j.jmax)};", "  Lim[1] := Lim[4];",
              "  Jog(Joints := 1, VelocityMode := TRUE, Sync := 0, CurrentPos := Zero,",
              "      CurrentVel := JogV, CurrentAcc := Zero, TargetPos := Zero,",
              "      TargetVel := JogT, TargetAcc := Zero, Limits := Lim);",
              f"  {out.jog_duration} := Jog.Duration;",
              "  Pt := MotionJerkAt(Prof := Jog.Profiles[1], TimeS := Jog.Duration);",
              f"  {out.jog_end} := Pt.Pos;",
              "  FOR K := 1 TO 60 DO",
              "    IF K = 30 THEN",
              "      TgtP[2] := 1.0;",
              "    END_IF;",
              "    Gen(Enable := TRUE, CycleTime := 0.01, Joints := 3, VelocityMode := FALSE,",
              "        Sync := 0, TargetPos := TgtP, TargetVel := Zero, TargetAcc := Zero,",
              "        Limits := Lim, StartPos := CurP, StartVel := CurV, StartAcc := CurA);",
              "    IF Gen.NewPlan THEN",
              f"      {out.plans} := {out.plans} + 1;",
              "    END_IF;",
              "  END_FOR;",
              f"  {out.gen_p1} := Gen.Position[1];",
              f"  {out.gen_v2} := Gen.Velocity[2];",
              f"  {out.gen_a3} := Gen.Acceleration[3];"]
    return "\n".join(lines)


def cross_ruckig_generator() -> tuple[float, float, float]:
    """Ruckig.update over the cross-check program's 60 cycles (the jog's limits on axis 1,
    as the program sets Lim[1] := Lim[4] before starting the generator): position of axis
    1, velocity of axis 2, acceleration of axis 3."""
    import ruckig

    otg = ruckig.Ruckig(3, 0.01)
    inp, out = ruckig.InputParameter(3), ruckig.OutputParameter(3)
    inp.current_position = [c.p0 for c in CROSS_AXES]
    inp.current_velocity = [c.v0 for c in CROSS_AXES]
    inp.current_acceleration = [c.a0 for c in CROSS_AXES]
    target = [c.pf for c in CROSS_AXES]
    inp.max_velocity = [CROSS_JOG.vmax] + [c.vmax for c in CROSS_AXES[1:]]
    inp.max_acceleration = [CROSS_JOG.amax] + [c.amax for c in CROSS_AXES[1:]]
    inp.max_jerk = [CROSS_JOG.jmax] + [c.jmax for c in CROSS_AXES[1:]]
    for k in range(1, 61):
        if k == 30:
            target[1] = 1.0
        inp.target_position = target
        otg.update(inp, out)
        out.pass_to_input(inp)
    return out.new_position[0], out.new_velocity[1], out.new_acceleration[2]
