"""The controller's jerk-limited motions on the in-process stepped PLC (stepped_controller.py),
with the output stage (A), Stop (B) and answer monitors of test_output_safety.py after every
scan: MoveJointsProfile with profile 4 (time-optimal jerk-limited), the jerk-limited Stop of
such a move, and JogStart with a jerk limit (Arg6).

Promises checked here, besides the monitors:
- a profile-4 move keeps to the output stage's limits by itself: the stage never holds a
  channel back (SlewLimited stays 0) from the move's start to its end, also when it takes over
  a moving arm;
- a Stop of a profile-4 move brakes jerk-limited: the acceleration of the braking ramps (its
  change per scan within the jerk the header gives: the move's, raised so that no ramp lasts
  over 0.02 s), no joint reverses, and every joint is at rest within
  ceil((|v0| + a0 dt / 2) / (D dt) + 1.5 * 0.02 / dt) + 1 scans (v0, a0 the stage's speed and
  the move's acceleration at the Stop, D the deceleration);
- compositions: profile 4 and Stop in the same scan (either order), a new move while one is
  busy, extreme but legal limits (tiny and huge jerk, a long move), a Stop in every scan;
- bad arguments are refused with their code and nothing moves;
- the jog's Arg6: a jerk-limited start, reversal and stop (the tool's acceleration changes by
  at most the jerk per scan), 0 = the jog as before, a bad value refused.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from stepped_controller import (
    BAD_PARAMETER,
    DT,
    HELLO,
    JOG_START,
    JOG_STOP,
    JOG_UPDATE,
    JOG_WRIST,
    MOVE_JOINTS,
    MOVE_JOINTS_PROFILE,
    OK,
    SET_MOTION_LIMITS,
    STOP,
    SteppedController,
    load_controller,
)
from test_output_safety import Bench

from armbench.softplc.loader import LoadedProgram

BAD_PROFILE, JERK_TOO_LONG = 20, 29
HALT_RAMP_S = 0.02
ARM = ("BASE", "SHOULDER", "ELBOW")
US_PER_DEG = 1000.0 / 120.0  # the default calibration's


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@pytest.fixture()
def bench(program: LoadedProgram) -> Iterator[Bench]:
    yield Bench(program)


class Watch:
    """Per scan: SlewLimited, the arm's stage angles and steps (deg per scan)."""

    def __init__(self, bench: Bench) -> None:
        self.limited: list[int] = []
        self.out: list[list[float]] = []
        self.steps: list[list[float]] = []
        self.busy: list[int] = []
        bench.ctl.observers.append(self)

    def __call__(self, ctl: SteppedController) -> None:
        self.limited.append(int(ctl.read("SLEWLIMITED")))
        self.out.append([float(ctl.read(f"OUT{j}DEG")) for j in ARM])
        self.busy.append(int(ctl.read("MOTIONBUSY")))

    def mark(self) -> int:
        return len(self.limited)


def profile4(bench: Bench, target: tuple[float, float, float], vel: float, acc: float,
             jerk: float, client: str = "a") -> int:
    c = bench.a if client == "a" else bench.b
    return c.command(MOVE_JOINTS_PROFILE, int1=4, args=(*target, vel, acc, jerk))


def run_until_idle(bench: Bench, limit: int = 5000) -> int:
    for k in range(limit):
        bench.ctl.step()
        if bench.ctl.read("MOTIONBUSY") == 0:
            return k + 1
    raise AssertionError("still busy")


@pytest.mark.parametrize("vel,acc,jerk,limits", [
    (120.0, 800.0, 6000.0, None),
    (400.0, 5000.0, 2.0e4, None),              # beyond the joints' limits: capped
    (100.0, 900.0, 1.0e9, None),               # huge jerk: nearly a trapezoid
    (25.0, 40.0, 300.0, (30.0, 50.0)),         # slow joints
])
def test_profile4_move_is_never_held_back(bench: Bench, vel: float, acc: float, jerk: float,
                                          limits: tuple[float, float] | None) -> None:
    if limits is not None:
        for j in range(3):
            assert bench.a.command(SET_MOTION_LIMITS, int1=j, args=limits) == OK
    bench.move(-40.0, 40.0, 95.0, 2000 if limits else 200)
    w = Watch(bench)
    target = (45.0, 110.0, 30.0)
    assert profile4(bench, target, vel, acc, jerk) == OK
    scans = run_until_idle(bench, 20000)
    assert scans > 20
    assert not any(w.limited), f"held back in scans {[i for i, x in enumerate(w.limited) if x]}"
    assert w.out[-1] == pytest.approx(list(target), abs=1e-4)
    bench.assert_safe()


def test_profile4_takes_over_a_busy_move_without_being_held_back(bench: Bench) -> None:
    """A profile-4 move while a profile-4 move accelerates, then one while a trapezoid
    (profile 2) runs, then a trapezoid over a profile-4 move: each new move starts from the
    stage, continuous; the profile-4 ones never held back."""
    bench.move(-40.0, 40.0, 95.0, 200)
    w = Watch(bench)
    assert profile4(bench, (45.0, 110.0, 30.0), 140.0, 900.0, 8000.0) == OK
    bench.ctl.step(12)
    assert profile4(bench, (-20.0, 60.0, 110.0), 90.0, 600.0, 3000.0, "b") == OK
    run_until_idle(bench)
    assert not any(w.limited)
    assert bench.a.command(MOVE_JOINTS_PROFILE, int1=2,
                           args=(40.0, 100.0, 40.0, 100.0, 800.0, 0.0)) == OK
    bench.ctl.step(15)
    mark = w.mark()
    assert profile4(bench, (0.0, 70.0, 65.0), 120.0, 800.0, 5000.0, "b") == OK
    run_until_idle(bench)
    assert not any(w.limited[mark:])
    assert profile4(bench, (40.0, 100.0, 40.0), 120.0, 800.0, 5000.0) == OK
    bench.ctl.step(20)
    assert bench.b.command(MOVE_JOINTS, args=(-30.0, 60.0, 90.0)) == OK
    run_until_idle(bench)
    bench.assert_safe()


def stop_bound_scans(v0: float, a0: float, decel: float) -> int:
    """The header's bound for a jerk-limited Stop, in scans, plus one for the float32
    rounding of the plan's end (as for the constant-deceleration Stop)."""
    v = abs(v0) + min(abs(a0), decel) * DT / 2.0
    return math.ceil(v / (decel * DT) + 1.5 * HALT_RAMP_S / DT - 1e-9) + 1


@pytest.mark.parametrize("after,decel", [(6, 0.0), (20, 0.0), (45, 0.0), (6, 150.0),
                                         (20, 400.0)])
def test_stop_of_a_profile4_move_is_jerk_limited_and_bounded(bench: Bench, after: int,
                                                             decel: float) -> None:
    jerk, acc = 6000.0, 800.0
    bench.move(-40.0, 40.0, 95.0, 200)
    w = Watch(bench)
    assert profile4(bench, (45.0, 110.0, 30.0), 140.0, acc, jerk) == OK
    bench.ctl.step(after)
    assert not any(w.limited)
    v0 = [bench.out.steps[c] / (US_PER_DEG * DT) for c in range(3)]
    a0 = [float(np.diff(np.array(w.out[-3:])[:, c], 2)[0]) / DT ** 2 for c in range(3)]
    mark = w.mark()
    assert bench.b.command(STOP, args=(decel,)) == OK
    bench.ctl.step(300)
    d = 1000.0 if decel == 0.0 else decel
    out = np.array(w.out[mark - 3:])
    for c in range(3):
        x = out[:, c]
        steps = np.diff(x)
        moving = np.flatnonzero(steps[2:] != 0.0)
        took = int(moving[-1]) + 1 if len(moving) else 0
        assert took <= stop_bound_scans(v0[c], a0[c], d), (c, took, v0[c], a0[c])
        # no reversal: every step after the Stop has the sign of the speed at the Stop
        assert np.all(steps[2:] * np.sign(v0[c]) >= -1e-4), (c, steps[2:12])
        # the acceleration ramps: its change per scan within the Stop's jerk (the move's,
        # raised so that a ramp lasts at most 0.02 s; a0 beyond D is taken as D)
        acc_k = np.diff(x, 2) / DT ** 2
        js = max(jerk, (min(abs(a0[c]), d) + d) / HALT_RAMP_S)
        jumps = np.abs(np.diff(acc_k[1:took + 1])) / DT
        first_jump = max(0.0, abs(a0[c]) - d) / DT  # a0 taken within +/-D
        assert np.all(jumps <= js * 1.05 + first_jump + 2e-3 / DT ** 3), (c, jumps[:6], js)
    bench.assert_safe()


@pytest.mark.parametrize("stop_first", [False, True], ids=["move_then_stop", "stop_then_move"])
def test_profile4_and_stop_in_the_same_scan(bench: Bench, stop_first: bool) -> None:
    """Both land in one scan (mailbox order decides). Move then Stop: the arm, moving from
    an earlier profile-4 move, brakes within the bound; Stop then move: the move runs to its
    target, never held back."""
    bench.move(-40.0, 40.0, 95.0, 200)
    assert profile4(bench, (45.0, 110.0, 30.0), 140.0, 800.0, 6000.0) == OK
    bench.ctl.step(15)
    w = Watch(bench)
    target = (-10.0, 60.0, 100.0)
    if stop_first:
        bench.a.send(STOP)
        bench.b.send(MOVE_JOINTS_PROFILE, int1=4, args=(*target, 100.0, 700.0, 5000.0))
    else:
        bench.a.send(MOVE_JOINTS_PROFILE, int1=4, args=(*target, 100.0, 700.0, 5000.0))
        bench.b.send(STOP)
    bench.ctl.step()
    assert bench.a.result() == OK and bench.b.result() == OK
    bench.ctl.step(400)
    if stop_first:
        assert w.out[-1] == pytest.approx(list(target), abs=1e-4)
        assert not any(w.limited)
    else:
        assert bench.ctl.read("MOTIONKIND") == 4 and bench.ctl.read("MOTIONDONE") == 1
    bench.assert_safe()


def test_a_stop_in_every_scan_of_a_profile4_move_brakes_as_hard_as_one(bench: Bench) -> None:
    """The base cruising at 30 deg/s (limits 30 deg/s, 100 deg/s^2) in a profile-4 move;
    Stop in every scan from two clients: at rest within the single Stop's bound."""
    base, acc = 0, 100.0
    assert bench.a.command(SET_MOTION_LIMITS, int1=base, args=(30.0, acc)) == OK
    bench.move(-55.0, 70.0, 65.0, 400)
    assert profile4(bench, (55.0, 70.0, 65.0), 30.0, 100.0, 2000.0) == OK
    bench.ctl.step(120)
    v0 = bench.out.steps[base] / (US_PER_DEG * DT)
    assert v0 == pytest.approx(30.0, rel=1e-3)
    assert bench.b.command(STOP) == OK
    stop_scan, last_moving = bench.ctl.scan, bench.ctl.scan
    for k in range(300):
        if bench.out.steps[base] != 0.0:
            last_moving = bench.ctl.scan
            (bench.a if k % 2 == 0 else bench.b).send(STOP)
        bench.ctl.step()
    took = last_moving - stop_scan + 1
    assert took <= stop_bound_scans(v0, 0.0, acc), (took, stop_bound_scans(v0, 0.0, acc))
    bench.assert_safe()


@pytest.mark.parametrize("jerk,vel,scans", [(0.5, 30.0, 150), (1.0e9, 120.0, 40),
                                            (3000.0, 0.2, 150)],
                         ids=["tiny_jerk", "huge_jerk", "long_move"])
def test_extreme_profile4_then_stop(bench: Bench, jerk: float, vel: float, scans: int) -> None:
    """Legal but extreme: a jerk of 0.5 deg/s^3 (the move creeps off), 1e9 (all but a
    trapezoid), a move of hours at 0.2 deg/s... the move starts, is never held back, and a
    Stop brings it to rest within the bound whatever its jerk."""
    bench.move(-40.0, 40.0, 95.0, 200)
    w = Watch(bench)
    assert profile4(bench, (45.0, 110.0, 30.0), vel, 800.0, jerk) == OK
    bench.ctl.step(scans)
    assert bench.ctl.read("MOTIONBUSY") == 1 and not any(w.limited)
    v0 = [bench.out.steps[c] / (US_PER_DEG * DT) for c in range(3)]
    assert max(abs(v) for v in v0) > 0.0
    assert bench.b.command(STOP) == OK
    stop_scan, last = bench.ctl.scan, [bench.ctl.scan - 1] * 3
    for _ in range(300):
        for c in range(3):
            if bench.out.steps[c] != 0.0:
                last[c] = bench.ctl.scan
        bench.ctl.step()
    for c in range(3):
        assert last[c] - stop_scan + 1 <= stop_bound_scans(v0[c], 800.0, 1000.0), (c, v0[c])
    bench.assert_safe()


@pytest.mark.parametrize("int1,args,code", [
    (5, (45.0, 110.0, 30.0, 100.0, 800.0, 5000.0), BAD_PROFILE),
    (4, (45.0, 110.0, 30.0, 100.0, 800.0, 0.0), BAD_PARAMETER),
    (4, (45.0, 110.0, 30.0, 100.0, 800.0, -5000.0), BAD_PARAMETER),
    (4, (45.0, 110.0, 30.0, 100.0, 800.0, 1.0e20), BAD_PARAMETER),
    (4, (45.0, 110.0, 30.0, 100.0, 0.0, 5000.0), BAD_PARAMETER),
    (4, (45.0, 110.0, 30.0, 100.0, 800.0, math.nan), BAD_PARAMETER),
    (4, (45.0, 110.0, 30.0, 1.0e-4, 800.0, 5000.0), JERK_TOO_LONG),
])
def test_bad_profile4_arguments_move_nothing(bench: Bench, int1: int,
                                             args: tuple[float, ...], code: int) -> None:
    """Refused with the code; also while a profile-4 move runs, which goes on untouched."""
    bench.move(-40.0, 40.0, 95.0, 200)
    starts = bench.ctl.read("MOTIONSTARTS")
    pulses = bench.ctl.pulses()
    assert bench.a.command(MOVE_JOINTS_PROFILE, int1=int1, args=args) == code
    bench.ctl.step(5)
    assert bench.ctl.read("MOTIONSTARTS") == starts and bench.ctl.pulses() == pulses
    assert profile4(bench, (45.0, 110.0, 30.0), 100.0, 800.0, 5000.0) == OK
    bench.ctl.step(10)
    assert bench.b.command(MOVE_JOINTS_PROFILE, int1=int1, args=args) == code
    assert bench.ctl.read("MOTIONBUSY") == 1 and bench.ctl.read("MOTIONMAILBOX") == 1
    run_until_idle(bench)
    assert [float(bench.ctl.read(f"OUT{j}DEG")) for j in ARM] == pytest.approx(
        [45.0, 110.0, 30.0], abs=1e-4)
    bench.assert_safe()


# ------------------------------------------------------------------------------ jog


def cart(bench: Bench) -> list[float]:
    return [float(bench.ctl.read(f"CART{a}")) for a in "XYZ"]


def jog_track(bench: Bench, jerk: float, scans_each: int = 60) -> np.ndarray:
    """JogStart +X, then -X (a reversal), then JogStop; the tool's Cartesian setpoints of
    every scan."""
    assert bench.a.command(MOVE_JOINTS, args=(0.0, 70.0, 65.0)) == OK
    bench.ctl.step(200)
    # the Cartesian setpoints are the jog's from its first scan on
    assert bench.a.command(JOG_START, args=(1.0, 0.0, 0.0, 60.0, 400.0, jerk)) == OK
    track = [cart(bench)]
    for stick, n in (((1.0, 0.0, 0.0), scans_each), ((-1.0, 0.0, 0.0), 2 * scans_each)):
        for k in range(n):
            if k % 20 == 0:
                assert bench.a.command(JOG_UPDATE, args=stick) == OK
            else:
                bench.ctl.step()
            track.append(cart(bench))
    assert bench.a.command(JOG_STOP) == OK
    track.append(cart(bench))
    for _ in range(100):
        bench.ctl.step()
        track.append(cart(bench))
    assert bench.ctl.read("MOTIONBUSY") == 0 and bench.ctl.read("MOTIONDONE") == 1
    return np.array(track)


def test_jog_with_a_jerk_limit_reverses_smoothly(bench: Bench) -> None:
    jerk, acc = 3000.0, 400.0
    x = jog_track(bench, jerk)[:, 0].astype(np.float64)
    a = np.diff(x, 2) / DT ** 2
    j = np.diff(x, 3) / DT ** 3
    # float32 positions near 150 mm: an ulp of 1.5e-5 mm is 15 mm/s^3 per ulp in the
    # third difference at 10 ms; allow 8 ulps
    noise = 8 * float(np.spacing(np.float32(np.max(np.abs(x))))) / DT ** 3
    assert np.max(np.abs(a)) <= acc * 1.001 + noise * DT
    assert np.max(np.abs(j)) <= jerk * 1.001 + noise, np.max(np.abs(j))
    assert np.max(x) - x[0] > 10.0 and x[-1] < np.max(x) - 10.0  # it went and came back
    bench.assert_safe()


def test_jog_without_a_jerk_limit_is_unchanged(bench: Bench, program: LoadedProgram) -> None:
    """Arg6 = 0 is the jog of before: the same track as a JogStart with five arguments, and
    its acceleration jumps (the jerk of a rate limit)."""
    zero = jog_track(bench, 0.0)
    other = Bench(program)
    assert other.a.command(MOVE_JOINTS, args=(0.0, 70.0, 65.0)) == OK
    other.ctl.step(200)
    assert other.a.command(JOG_START, args=(1.0, 0.0, 0.0, 60.0, 400.0)) == OK
    track = [cart(other)]
    for stick, n in (((1.0, 0.0, 0.0), 60), ((-1.0, 0.0, 0.0), 120)):
        for k in range(n):
            if k % 20 == 0:
                assert other.a.command(JOG_UPDATE, args=stick) == OK
            else:
                other.ctl.step()
            track.append(cart(other))
    assert other.a.command(JOG_STOP) == OK
    track.append(cart(other))
    for _ in range(100):
        other.ctl.step()
        track.append(cart(other))
    assert np.array_equal(zero, np.array(track))
    j = np.diff(zero[:, 0].astype(np.float64), 3) / DT ** 3
    assert np.max(np.abs(j)) > 10 * 3000.0


@pytest.mark.parametrize("jerk", [-1.0, math.nan, math.inf, 1.01e7],
                         ids=["negative", "nan", "inf", "beyond"])
def test_jog_with_a_bad_jerk_is_refused(bench: Bench, jerk: float) -> None:
    bench.move(0.0, 70.0, 65.0, 200)
    before = cart(bench)
    starts = bench.ctl.read("MOTIONSTARTS")
    assert bench.a.command(JOG_START, args=(1.0, 0.0, 0.0, 60.0, 400.0, jerk)) == BAD_PARAMETER
    bench.ctl.step(30)
    assert bench.ctl.read("MOTIONSTARTS") == starts and cart(bench) == before
    bench.assert_safe()


def test_jog_jerk_of_a_takeover_stays(bench: Bench) -> None:
    """JogStart of another client takes the jog over: speed, acceleration and jerk stay
    (its own Arg4..6 are not looked at)."""
    assert bench.b.command(HELLO) == OK
    bench.move(0.0, 70.0, 65.0, 200)
    assert bench.a.command(JOG_START, args=(1.0, 0.0, 0.0, 60.0, 400.0, 3000.0)) == OK
    bench.ctl.step(10)
    track = [cart(bench)]
    assert bench.b.command(JOG_START, args=(-1.0, 0.0, 0.0, 60.0, 400.0, 0.0)) == OK
    track.append(cart(bench))
    for _ in range(40):
        bench.ctl.step()
        track.append(cart(bench))
    x = np.array(track)[:, 0].astype(np.float64)
    noise = 8 * float(np.spacing(np.float32(np.max(np.abs(x))))) / DT ** 3
    assert np.max(np.abs(np.diff(x, 3) / DT ** 3)) <= 3000.0 * 1.001 + noise
    assert bench.b.command(JOG_STOP) == OK
    bench.ctl.step(100)
    bench.assert_safe()


# ------------------------------------------------------------------------------ the start state


def stage_state(bench: Bench) -> tuple[list[float], list[float]]:
    """The output stage's five joint angles and the arm's three speeds (the wrist at rest)."""
    deg = [float(bench.ctl.read(f"OUT{j}DEG"))
           for j in (*ARM, "WRISTPITCH", "WRISTROLL")]
    vel = [float(bench.ctl.read(f"OUT{j}VEL")) for j in ARM] + [0.0, 0.0]
    return deg, vel


@dataclass(frozen=True)
class Axis:
    """One joint for Ruckig: start, target, limits."""

    p0: float
    v0: float
    a0: float
    pf: float
    vmax: float
    amax: float
    jmax: float


def axes_of(deg: list[float], vel: list[float], acc: list[float], target: list[float],
            v: float, a: float, j: float) -> list[Axis]:
    """The joints as profile 4 takes them (limits min(v, 150), min(a, 1000): the defaults;
    the start acceleration within the limit)."""
    vm, am = min(v, 150.0), min(a, 1000.0)
    return [Axis(deg[k], vel[k], max(-am, min(am, acc[k])), target[k], vm, am, j)
            for k in range(5)]


class RuckigPlan:
    """Ruckig's phase-synchronised trajectory (PyPI `ruckig`), the independent reference."""

    def __init__(self, axes: list[Axis], velocity_interface: bool = False) -> None:
        ruckig = pytest.importorskip("ruckig")
        n = len(axes)
        inp = ruckig.InputParameter(n)
        if velocity_interface:
            # the halt: each joint on its own, to rest (MotionHalt)
            inp.control_interface = ruckig.ControlInterface.Velocity
            inp.target_velocity = [0.0] * n
        inp.current_position = [x.p0 for x in axes]
        inp.current_velocity = [x.v0 for x in axes]
        inp.current_acceleration = [x.a0 for x in axes]
        inp.target_position = [x.pf for x in axes]
        inp.max_velocity = [x.vmax for x in axes]
        inp.max_acceleration = [x.amax for x in axes]
        inp.max_jerk = [x.jmax for x in axes]
        inp.synchronization = (ruckig.Synchronization.No if velocity_interface
                               else ruckig.Synchronization.Phase)
        self.traj = ruckig.Trajectory(n)
        assert str(ruckig.Ruckig(n).calculate(inp, self.traj)).endswith("Working")
        self.duration = float(self.traj.duration)

    def at(self, t: float) -> tuple[list[float], list[float], list[float]]:
        p, v, a = self.traj.at_time(t)
        return list(p), list(v), list(a)


def test_profile4_takeover_starts_from_the_running_moves_acceleration(bench: Bench) -> None:
    """A profile-4 move taking over a profile-4 move the stage follows: planned from the
    stage's angles and speeds and the running move's acceleration (Ruckig's plan of the
    first move at that time gives it): Ruckig's duration from that state."""
    bench.move(-40.0, 40.0, 95.0, 200)
    deg0, vel0 = stage_state(bench)
    first = [45.0, 110.0, 30.0, deg0[3], deg0[4]]
    ref1 = RuckigPlan(axes_of(deg0, vel0, [0.0] * 5, first, 140.0, 900.0, 8000.0))
    assert profile4(bench, (45.0, 110.0, 30.0), 140.0, 900.0, 8000.0) == OK
    k = 9
    bench.ctl.step(k - 1)
    _, _, acc = ref1.at(k * float(np.float32(DT)))
    assert max(abs(a) for a in acc[:3]) > 300.0  # it is accelerating
    deg, vel = stage_state(bench)
    second = [-20.0, 60.0, 110.0, deg[3], deg[4]]
    ref2 = RuckigPlan(axes_of(deg, vel, acc, second, 90.0, 600.0, 3000.0))
    assert profile4(bench, (-20.0, 60.0, 110.0), 90.0, 600.0, 3000.0, "b") == OK
    assert float(bench.ctl.read("MOTIONDURATION")) == pytest.approx(ref2.duration, rel=1e-4)
    run_until_idle(bench)
    bench.assert_safe()


def test_profile4_over_a_held_back_stage_starts_at_acceleration_zero(bench: Bench) -> None:
    """The wrist roll limited to 20 deg/s and 20 deg/s^2 under a flange-fixed wrist jog that
    speeds up at its own 150 deg/s^2: the stage holds the channel back. A profile-4 move to
    where the arm stands (so the wrist roll, coming back to where the stage was, sets the
    duration) then starts from the stage at acceleration 0, not at the jog's setpoint
    acceleration, which the stage does not follow: Ruckig's duration from that state."""
    roll = 4
    assert bench.a.command(SET_MOTION_LIMITS, int1=roll, args=(20.0, 20.0)) == OK
    bench.move(-40.0, 40.0, 95.0, 200)
    assert bench.a.command(JOG_WRIST, int1=2, args=(0.0, 19.0, 19.0, 150.0)) == OK
    bench.ctl.step(4)
    assert bench.ctl.read("SLEWLIMITED") == 1
    before = float(bench.ctl.read("OUTWRISTROLLDEG"))
    bench.ctl.step()
    deg, vel = stage_state(bench)
    vel[4] = (deg[4] - before) / float(np.float32(DT))
    assert vel[4] > 0.5
    axes = axes_of(deg, vel, [0.0] * 5, deg, 100.0, 800.0, 5000.0)
    axes[4] = Axis(deg[4], vel[4], 0.0, deg[4], 20.0, 20.0, 5000.0)
    ref = RuckigPlan(axes)
    assert profile4(bench, (deg[0], deg[1], deg[2]), 100.0, 800.0, 5000.0, "b") == OK
    assert float(bench.ctl.read("MOTIONDURATION")) == pytest.approx(ref.duration, rel=1e-3)
    run_until_idle(bench)
    bench.assert_safe()


def test_stop_of_a_quintic_move_brakes_at_constant_deceleration(bench: Bench) -> None:
    """The jerk-limited Stop is profile 4's only: a Stop of a profile-3 move (with a jerk of
    3000) brakes as before, its step dropping by the full D g dt^2 from the first scan."""
    bench.move(-40.0, 40.0, 95.0, 200)
    assert bench.a.command(MOVE_JOINTS_PROFILE, int1=3,
                           args=(45.0, 110.0, 30.0, 140.0, 900.0, 3000.0)) == OK
    bench.ctl.step(60)
    s0 = bench.out.steps[0]
    assert abs(s0) > 0.5
    assert bench.b.command(STOP) == OK
    s1 = bench.out.steps[0]
    bench.ctl.step()
    s2 = bench.out.steps[0]
    g_dt2 = US_PER_DEG * 1000.0 * DT ** 2  # the base's full deceleration per scan, us
    assert abs((s2 - s1) + np.sign(s0) * g_dt2) < 0.02 * g_dt2, (s0, s1, s2, g_dt2)
    bench.ctl.step(300)
    bench.assert_safe()


def halt_axis(p0: float, v0: float, a0: float, decel: float, jerk: float) -> Axis:
    """One joint of the jerk-limited Stop as MotionHalt's header plans it: the acceleration
    within +/-D, the jerk raised so that no ramp lasts over 0.02 s, a braking joint's jerk
    ending at rest (acceleration 0 when that would take less than a scan)."""
    a0 = max(-decel, min(decel, a0))
    js = max(jerk, (abs(a0) + decel) / HALT_RAMP_S)
    if (a0 < 0.0 <= v0) or (a0 > 0.0 >= v0):
        if abs(a0) / float(np.float32(DT)) * abs(v0) * 2.0 < a0 * a0:
            a0, js = 0.0, max(jerk, decel / HALT_RAMP_S)
        else:
            js = max(js, a0 * a0 / (2.0 * abs(v0)))
    return Axis(p0, v0, a0, 0.0, 1.0e3, decel, js)


@pytest.mark.parametrize("after,soft", [(6, False), (20, False), (45, False), (6, True),
                                        (30, True)])
def test_stop_of_a_profile4_move_is_ruckigs_braking(bench: Bench, after: int,
                                                    soft: bool) -> None:
    """The Stop's braking, joint by joint, is Ruckig's velocity interface from the stage's
    angle, its speed taken half a scan on at the move's acceleration (the move's own plan,
    Ruckig's, gives that acceleration) and that acceleration, with the Stop's limits: the
    stage follows it scan by scan (its angles within 2e-3 deg of Ruckig's). Then a second,
    harder Stop while it brakes: the braking goes on jerk-limited (the same rule from where
    it is, at the harder deceleration)."""
    bench.move(-40.0, 40.0, 95.0, 200)
    deg0, vel0 = stage_state(bench)
    target = [45.0, 110.0, 30.0, deg0[3], deg0[4]]
    ref1 = RuckigPlan(axes_of(deg0, vel0, [0.0] * 5, target, 140.0, 800.0, 6000.0))
    assert profile4(bench, (45.0, 110.0, 30.0), 140.0, 800.0, 6000.0) == OK
    bench.ctl.step(after - 1)
    dt32 = float(np.float32(DT))
    _, _, acc = ref1.at(after * dt32)
    deg, vel = stage_state(bench)
    decel = 150.0 if soft else 1000.0
    axes = [halt_axis(deg[j], vel[j] + max(-decel, min(decel, acc[j])) * dt32 / 2.0, acc[j],
                      decel, 6000.0) for j in range(3)]
    refs = [RuckigPlan([ax], velocity_interface=True) for ax in axes]
    assert bench.b.command(STOP, args=(150.0 if soft else 0.0,)) == OK
    worst = 0.0
    for m in range(1, 16):
        now, _ = stage_state(bench)
        for j in range(3):
            p, _, _ = refs[j].at(m * dt32)
            worst = max(worst, abs(now[j] - p[0]))
        bench.ctl.step()
    assert worst < 2e-3, worst
    if soft and after >= 20:
        # the harder Stop while the base still brakes at 150: from where it is at
        # 1000 deg/s^2, still ramping (the jerk of the braking it takes over)
        assert bench.out.steps[0] != 0.0
        w = Watch(bench)
        assert bench.a.command(STOP, args=(0.0,)) == OK
        bench.ctl.step(150)
        x = np.array(w.out)[:, 0].astype(np.float64)
        acc_k = np.diff(x, 2) / DT ** 2
        jumps = np.abs(np.diff(acc_k[:40])) / DT
        assert np.max(jumps) <= (150.0 + 1000.0) / HALT_RAMP_S * 1.05 + 2e-3 / DT ** 3, \
            np.max(jumps)
    bench.ctl.step(200)
    bench.assert_safe()
