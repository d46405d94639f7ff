"""Safety of the controller's outputs against commands that land in the same scan, hostile
arguments and half-written blocks, on the in-process stepped PLC (stepped_controller.py): the
test writes the mailbox blocks into the image and makes every scan itself, and monitors check
after each scan

A  the output stage: per channel |step| <= Vel*g*dt, |step change| <= Acc*g*dt^2 (g = the
   calibration's us/deg), a re-powered channel starts from its last pulse, pulses inside the
   calibration's range, joint angles inside the travel, no REAL output NaN/Inf; calibration
   and limits change only at rest and never move a servo;
B  Stop always wins: never refused, the arm at rest within ceil(Vel/(min(Acc,100)*dt)) + 5
   scans, a later Stop brakes at least as hard; the braking planned from the stage's speed
   v0 is followed from its first scan (at rest within ceil(v0/(a*dt)) + 1 scans, no
   overshoot), also by a stage that trails its setpoint or has a low acceleration limit;
C  the check word covers the whole block (CRC-32 of its 44 bytes; NaN canonical, -0.0 = 0),
   whatever order its 16-bit registers land in;
D  absurd motion parameters are refused (8 BadParameter) and publish no NaN.

The check word is the protocol's CRC-32 unless ARMBENCH_CTL_CHECK names an earlier one
(weighted, sum), to show a defect on a controller that still expects it.
"""

from __future__ import annotations

import math
import random
from collections.abc import Iterator

import pytest
from stepped_controller import (
    BAD_CHECK,
    BAD_PARAMETER,
    BUSY,
    HELLO,
    JOG_START,
    JOG_STOP,
    JOG_UPDATE,
    JOG_WRIST,
    JOINT_LIMIT,
    MOVE_JOINTS,
    MOVE_JOINTS_PROFILE,
    MOVE_LINEAR,
    MOVE_TOOL_ANGLES,
    MOVE_TOOL_VECTOR,
    MOVE_XYZ,
    OK,
    RELAX,
    SET_CALIBRATION,
    SET_GRIPPER,
    SET_MOTION_LIMITS,
    STOP,
    AnswerMonitor,
    Arg,
    Bits,
    Client,
    OutputMonitor,
    SteppedController,
    StopMonitor,
    check_formula_from_env,
    load_controller,
)

from armbench.softplc.loader import LoadedProgram

DEFAULT_CAL = (1000.0, 2000.0, -60.0, 60.0)  # MinPulse, MaxPulse, MinAngle, MaxAngle


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


class Bench:
    """A controller at power-up with the three monitors and two clients in mailboxes 1, 2."""

    def __init__(self, program: LoadedProgram) -> None:
        self.ctl = SteppedController(program, check_formula_from_env())
        self.out = OutputMonitor()
        self.stop = StopMonitor(self.out)
        self.answers = AnswerMonitor()
        self.ctl.observers += [self.out, self.stop, self.answers]
        self.a = Client(self.ctl, 1, 101_001)
        self.b = Client(self.ctl, 2, 202_002)
        for client in (self.a, self.b):
            result = client.command(HELLO)
            assert result == OK, (f"Hello answered {result}" + (
                " (BadCheck: the controller does not take this check word; "
                "ARMBENCH_CTL_CHECK=sum is the old one)" if result == BAD_CHECK else ""))

    def assert_safe(self, context: str = "") -> None:
        if self.out.violations:
            pytest.fail(context + self.out.failure(), pytrace=False)
        if self.stop.violations:
            pytest.fail("\n".join(str(v) for v in self.stop.violations[:5]), pytrace=False)
        if self.answers.violations:
            pytest.fail("\n".join(self.answers.violations[:5]), pytrace=False)

    def move(self, base: float, shoulder: float, elbow: float, scans: int) -> None:
        assert self.a.command(MOVE_JOINTS, args=(base, shoulder, elbow)) == OK, \
            self.ctl.scan_commands()
        self.ctl.step(scans)


@pytest.fixture()
def bench(program: LoadedProgram) -> Iterator[Bench]:
    yield Bench(program)


# ------------------------------------------------------------------------------------------
# 1..3  Relax and a motion (or SetGripper) in the same scan
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("moving", [False, True], ids=["at_rest", "moving"])
@pytest.mark.parametrize("relax_first", [True, False], ids=["relax_then_move", "move_then_relax"])
def test_relax_and_move_in_one_scan_never_jump(bench: Bench, moving: bool,
                                              relax_first: bool) -> None:
    """Shoulder and elbow powered (at rest, or moving fast), then Relax from one client and
    MoveJoints from another land in the same scan, in either mailbox order."""
    bench.move(0.0, 40.0, 95.0, 150)
    if moving:
        bench.move(0.0, 100.0, 35.0, 40)
        assert bench.ctl.read("MOTIONBUSY") == 1
    relax_box, move_box = (bench.a, bench.b) if relax_first else (bench.b, bench.a)
    relax_box.send(RELAX)
    move_box.send(MOVE_JOINTS, args=(0.0, 60.0, 80.0))
    bench.ctl.step(300)
    bench.assert_safe()


def test_gripper_relax_and_open_in_one_scan_never_jump(bench: Bench) -> None:
    """The gripper closed (0 %) and at rest, then Relax + SetGripper 100 % in one scan."""
    assert bench.a.command(SET_GRIPPER, args=(0.0,)) == OK
    bench.ctl.step(150)
    closed = bench.ctl.read("GRIPPERPULSEUS")
    assert closed != 0.0
    bench.a.send(RELAX)
    bench.b.send(SET_GRIPPER, args=(100.0,))
    bench.ctl.step(300)
    bench.assert_safe()


def test_fast_base_relax_and_new_move_keep_the_step_change(bench: Bench) -> None:
    """The base crossing at ~120 deg/s: Relax + a new MoveJoints in the same scan must not
    change the pulse step by more than Acc*g*dt^2."""
    bench.move(-55.0, 70.0, 65.0, 150)
    bench.move(55.0, 70.0, 65.0, 40)
    assert abs(float(bench.ctl.read("OUTBASEVEL"))) > 100.0
    bench.a.send(RELAX)
    bench.b.send(MOVE_JOINTS, args=(-20.0, 70.0, 65.0))
    bench.ctl.step(300)
    bench.assert_safe()


# ------------------------------------------------------------------------------------------
# 4  SetCalibration: only at rest, never moves a servo
# ------------------------------------------------------------------------------------------

def _set_cal(client: Client, joint: int, zero: float, cal: tuple[float, float, float, float],
             direction: int = 1) -> int:
    return client.command(SET_CALIBRATION, int1=joint, int2=direction, args=(zero, *cal))


def test_set_calibration_at_rest_keeps_the_pulse(bench: Bench) -> None:
    """Base powered at rest at 0 deg (1500 us): zero offset 0 -> 30 deg. The pulse stays
    1500 us and the reported joint angle becomes the one that pulse means now, 30 deg."""
    bench.move(0.0, 70.0, 65.0, 150)
    assert bench.ctl.read("BASEPULSEUS") == pytest.approx(1500.0, abs=1e-3)
    assert _set_cal(bench.a, 0, 30.0, DEFAULT_CAL) == OK
    assert bench.ctl.read("BASECALZERODEG") == 30.0
    pulses = []
    for _ in range(100):
        pulses.append(float(bench.ctl.read("BASEPULSEUS")))
        bench.ctl.step()
    moved = max(abs(p - 1500.0) for p in pulses)
    assert moved == 0.0, f"the base pulse left 1500 us by up to {moved:.6g} us: {pulses[:5]}"
    assert bench.ctl.read("OUTBASEDEG") == pytest.approx(30.0, abs=1e-3)
    bench.assert_safe()


def test_set_calibration_that_excludes_the_pulse_is_refused(bench: Bench) -> None:
    """The base rests at 1500 us; a calibration whose pulse range starts at 1600 us would
    make the servo jump to 1600: 101 JointLimit and nothing changes."""
    bench.move(0.0, 70.0, 65.0, 150)
    result = _set_cal(bench.a, 0, 0.0, (1600.0, 2500.0, -10.0, 80.0))
    bench.ctl.step(50)
    assert result == JOINT_LIMIT, f"answered {result}; base pulse now " \
        f"{bench.ctl.read('BASEPULSEUS'):.6g} us"
    assert bench.ctl.read("BASECALMINPULSEUS") == 1000.0
    assert bench.ctl.read("BASEPULSEUS") == pytest.approx(1500.0, abs=1e-3)
    bench.assert_safe()


def test_set_calibration_while_moving_is_busy(bench: Bench) -> None:
    bench.move(-55.0, 70.0, 65.0, 150)
    bench.move(55.0, 70.0, 65.0, 30)
    result = _set_cal(bench.b, 0, 10.0, DEFAULT_CAL)
    bench.ctl.step(200)
    assert result == BUSY, f"answered {result} while the base moved"
    assert bench.ctl.read("BASECALZERODEG") == 0.0
    bench.assert_safe()


# ------------------------------------------------------------------------------------------
# 5  Stop always wins; limits only at rest
# ------------------------------------------------------------------------------------------

def _fast_base(bench: Bench) -> None:
    bench.move(-55.0, 70.0, 65.0, 150)
    bench.move(55.0, 70.0, 65.0, 40)
    assert abs(float(bench.ctl.read("OUTBASEVEL"))) > 100.0


@pytest.mark.parametrize("decel", [1e-3, -5.0, math.nan, 0.0, 50.0],
                         ids=["tiny", "negative", "nan", "zero", "below_floor"])
def test_stop_with_any_deceleration_brings_the_arm_to_rest(bench: Bench, decel: float) -> None:
    _fast_base(bench)
    result = bench.b.command(STOP, args=(decel,))
    # a deceleration outside 100..1e6 (0 = each joint's limit) is refused with 8, and the arm
    # brakes at each joint's limit all the same
    expect = OK if decel == 0.0 else BAD_PARAMETER
    assert result == expect, f"Stop({decel}) answered {result}"
    start = bench.ctl.scan
    peak = float(bench.ctl.read("OUTBASEDEG"))
    for _ in range(300):
        bench.ctl.step()
        peak = max(peak, float(bench.ctl.read("OUTBASEDEG")))
    assert bench.stop.braking is not None and bench.stop.braking.scan == start
    assert not bench.stop.violations, (
        f"base peak {peak:.6g} deg after Stop({decel}); " + str(bench.stop.violations[0]))
    bench.assert_safe(f"base peak {peak:.6g} deg after Stop({decel}); ")


def test_second_stop_brakes_harder(bench: Bench) -> None:
    """Stop at the 100 deg/s^2 floor (1.2 s from 120 deg/s), then another client's Stop(0)
    (each joint's limit, 1000 deg/s^2): the arm must be at rest within the second Stop's own
    braking time, not the first's."""
    _fast_base(bench)
    assert bench.a.command(STOP, args=(100.0,)) == OK
    bench.ctl.step(5)
    assert bench.b.command(STOP, args=(0.0,)) == OK
    vel = abs(float(bench.ctl.read("OUTBASEVEL")))
    acc = float(bench.ctl.read("LIMBASEACC"))
    bound = math.ceil(vel / (acc * 0.01)) + 5
    second = bench.ctl.scan
    rest = None
    for _ in range(300):
        bench.ctl.step()
        if rest is None and bench.out.steps[0] == 0.0:
            rest = bench.ctl.scan
    assert rest is not None
    took = rest - second
    assert took <= bound, (f"at rest {took} scans after the second Stop (from {vel:.4g} deg/s "
                           f"at {acc:g} deg/s^2 it needs at most {bound})")
    bench.assert_safe()


@pytest.mark.parametrize(("decel", "expect"), [(0.0, OK), (50.0, BAD_PARAMETER)],
                         ids=["limit", "refused_below_floor"])
def test_stop_while_the_stage_trails_a_jog_brakes_in_minimum_time(
        bench: Bench, decel: float, expect: int) -> None:
    """WristRoll limited to 20 deg/s and 20 deg/s^2; a flange-fixed wrist jog at 19 deg/s
    with its own 150 deg/s^2 runs its setpoint away from the output stage (which may only
    speed up at 20), so at the Stop the stage runs at its 20 deg/s several degrees behind
    the setpoint. The Stop plans the braking from the stage's own angle and speed; the stage
    must follow that plan from its first scan: braking from v0 at a = 20 deg/s^2 it covers
    v0^2 / (2a) (no overshoot and back) and is at rest within ceil(v0 / (a dt)) + 1 scans
    (one for the float32 rounding of the plan's end)."""
    roll, dt, acc = 4, 0.01, 20.0
    assert bench.a.command(SET_MOTION_LIMITS, int1=roll, args=(20.0, acc)) == OK
    assert bench.a.command(JOG_WRIST, int1=2, args=(0.0, 19.0, 19.0, 150.0)) == OK
    for _ in range(8):  # JogUpdate within the dead-man's 50 scans
        bench.ctl.step(19)
        assert bench.a.command(JOG_UPDATE, args=(0.0, 19.0)) == OK
    lag = float(bench.ctl.read("SETWRISTROLLDEG")) - float(bench.ctl.read("OUTWRISTROLLDEG"))
    g = ((float(bench.ctl.read("WRISTROLLCALMAXPULSEUS"))
          - float(bench.ctl.read("WRISTROLLCALMINPULSEUS")))
         / (float(bench.ctl.read("WRISTROLLCALMAXANGLEDEG"))
            - float(bench.ctl.read("WRISTROLLCALMINANGLEDEG"))))  # us per deg
    v0 = bench.out.steps[roll] / (g * dt)  # deg/s, the stage's speed at the Stop
    x0 = float(bench.ctl.read("OUTWRISTROLLDEG"))
    assert lag > 1.0 and v0 == pytest.approx(20.0, rel=1e-3), \
        f"no trailing stage to stop: setpoint - stage {lag:.4g} deg, stage at {v0:.6g} deg/s"
    result = bench.b.command(STOP, args=(decel,))
    assert result == expect, f"Stop({decel}) answered {result}"
    stop_scan = bench.ctl.scan
    last_moving, peak = stop_scan, x0
    for _ in range(300):
        if bench.out.steps[roll] != 0.0:
            last_moving = bench.ctl.scan
        peak = max(peak, float(bench.ctl.read("OUTWRISTROLLDEG")))
        bench.ctl.step()
    took = last_moving - stop_scan + 1
    need = math.ceil(v0 / (acc * dt)) + 1
    distance = v0 * v0 / (2.0 * acc)
    assert peak - x0 <= distance + 1e-3 and took <= need, (
        f"braking from {v0:.6g} deg/s at {acc:g} deg/s^2 (setpoint {lag:.4g} deg ahead): "
        f"went {peak - x0:.6g} deg (plan {distance:.6g}) and moved {took} scans "
        f"(at most {need}); {bench.stop.report()}")
    bench.assert_safe()


@pytest.mark.parametrize("acc", [10.6, 50.0])
def test_stop_at_a_low_acceleration_limit_brakes_in_minimum_time(bench: Bench,
                                                                 acc: float) -> None:
    """The base limited to 30 deg/s and `acc` deg/s^2 cruises at 30 deg/s; Stop(0) plans the
    braking at exactly `acc`: a step change of acc*g*dt^2 = 72.36 (10.6) or 341.33 (50)
    ulps of a pulse in [1024, 2048) us (g = 1000/120 us/deg, ulp 2^-13 us). Rounded to the
    nearest pulse, a stage clamping its step change at exactly that limit emits 72 resp. 341
    ulps per scan: it brakes softer than the plan, falls ahead of it ever more (by about
    0.36 ulp * n^2 / 2 after n scans) and must come back. It must instead cover
    v0^2 / (2 acc) and be at rest within ceil(v0 / (acc dt)) + 1 scans (one for the
    float32 rounding of the plan's end)."""
    base, dt = 0, 0.01
    assert bench.a.command(SET_MOTION_LIMITS, int1=base, args=(30.0, acc)) == OK
    bench.move(-55.0, 70.0, 65.0, 3000)
    bench.move(55.0, 70.0, 65.0, int(30.0 / (acc * dt)) + 20)  # past the speed-up: cruising
    g = 1000.0 / 120.0
    v0 = abs(bench.out.steps[base]) / (g * dt)
    x0 = float(bench.ctl.read("OUTBASEDEG"))
    assert v0 == pytest.approx(30.0, rel=1e-3), f"the base is not cruising: {v0:.6g} deg/s"
    assert bench.b.command(STOP, args=(0.0,)) == OK
    stop_scan = bench.ctl.scan
    last_moving, peak = stop_scan, x0
    for _ in range(int(v0 / (acc * dt)) + 100):
        if bench.out.steps[base] != 0.0:
            last_moving = bench.ctl.scan
        peak = max(peak, float(bench.ctl.read("OUTBASEDEG")))
        bench.ctl.step()
    took = last_moving - stop_scan + 1
    need = math.ceil(v0 / (acc * dt)) + 1
    distance = v0 * v0 / (2.0 * acc)
    assert peak - x0 <= distance + 1e-3 and took <= need, (
        f"braking from {v0:.6g} deg/s at {acc:g} deg/s^2 went {peak - x0:.6g} deg "
        f"(plan {distance:.6g}) and moved {took} scans (at most {need}); "
        f"{bench.stop.report()}")
    bench.assert_safe()


def test_a_stop_in_every_scan_brakes_as_hard_as_one(bench: Bench) -> None:
    """The base cruising at 30 deg/s (limits 30 deg/s, 100 deg/s^2), then Stop(0) in every
    scan from two clients in turn until it rests (an e-stop that repeats). Each Stop
    re-plans from the stage; the arm must still brake at 100 deg/s^2: at rest within
    ceil(v0 / (a dt)) + 1 scans of the first Stop, not slower with every re-plan."""
    base, dt, acc = 0, 0.01, 100.0
    assert bench.a.command(SET_MOTION_LIMITS, int1=base, args=(30.0, acc)) == OK
    bench.move(-55.0, 70.0, 65.0, 300)
    bench.move(55.0, 70.0, 65.0, 50)
    v0 = abs(bench.out.steps[base]) / (1000.0 / 120.0 * dt)
    assert v0 == pytest.approx(30.0, rel=1e-3), f"the base is not cruising: {v0:.6g} deg/s"
    assert bench.b.command(STOP) == OK
    stop_scan = bench.ctl.scan
    last_moving, stops = stop_scan, 1
    for k in range(200):
        if bench.out.steps[base] != 0.0:
            last_moving = bench.ctl.scan
            (bench.a if k % 2 == 0 else bench.b).send(STOP)
            stops += 1
        bench.ctl.step()
    took = last_moving - stop_scan + 1
    need = math.ceil(v0 / (acc * dt)) + 1
    assert took <= need, (f"{stops} Stops, one per scan: the base moved {took} scans braking "
                          f"from {v0:.6g} deg/s at {acc:g} deg/s^2 (at most {need}); "
                          f"{bench.stop.report()}")
    bench.assert_safe()


def test_set_motion_limits_while_moving_is_refused(bench: Bench) -> None:
    _fast_base(bench)
    result = bench.b.command(SET_MOTION_LIMITS, int1=0, args=(150.0, 1e-3))
    peak = float(bench.ctl.read("OUTBASEDEG"))
    for _ in range(400):
        bench.ctl.step()
        peak = max(peak, float(bench.ctl.read("OUTBASEDEG")))
    assert result == BUSY, f"answered {result} while the base moved; base peak {peak:.6g} deg"
    assert bench.ctl.read("LIMBASEACC") == 1000.0
    bench.assert_safe(f"base peak {peak:.6g} deg; ")


@pytest.mark.parametrize(("vel", "acc", "expect"), [
    (0.1, 10.0, OK), (2000.0, 1.0e5, OK), (0.09, 100.0, BAD_PARAMETER),
    (2001.0, 100.0, BAD_PARAMETER), (150.0, 9.9, BAD_PARAMETER), (150.0, 1.01e5, BAD_PARAMETER),
    (math.nan, 100.0, BAD_PARAMETER), (150.0, math.inf, BAD_PARAMETER)])
def test_set_motion_limits_range(bench: Bench, vel: float, acc: float, expect: int) -> None:
    result = bench.a.command(SET_MOTION_LIMITS, int1=0, args=(vel, acc))
    assert result == expect, f"SetMotionLimits({vel}, {acc}) answered {result}"
    if expect != OK:
        assert (bench.ctl.read("LIMBASEVEL"), bench.ctl.read("LIMBASEACC")) == (150.0, 1000.0)


# ------------------------------------------------------------------------------------------
# 6  absurd motion parameters
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("speed", [1e20, math.inf, math.nan, 0.0, -40.0],
                         ids=["1e20", "inf", "nan", "zero", "negative"])
def test_jog_start_with_absurd_speed_is_refused(bench: Bench, speed: float) -> None:
    bench.move(0.0, 70.0, 65.0, 150)
    result = bench.a.command(JOG_START, args=(1.0, 0.0, 0.0, speed, 300.0))
    bench.ctl.step(20)
    cart = [bench.ctl.read(n) for n in ("CARTX", "CARTY", "CARTZ")]
    bench.a.command(JOG_STOP)
    bench.b.command(STOP)
    bench.ctl.step(200)
    after = [bench.ctl.read(n) for n in ("CARTX", "CARTY", "CARTZ")]
    assert result == BAD_PARAMETER, (f"JogStart MaxSpeed {speed} answered {result}; "
                                     f"CartX/Y/Z {cart}, after JogStop/Stop {after}")
    bench.assert_safe()


# Every motion start with one of its REAL arguments made non-finite (slot, args).
_GOOD_ARGS: dict[int, tuple[float, ...]] = {
    MOVE_XYZ: (150.0, 0.0, 120.0),
    MOVE_JOINTS: (10.0, 70.0, 65.0),
    MOVE_JOINTS_PROFILE: (10.0, 70.0, 65.0, 60.0, 300.0, 3000.0),
    MOVE_LINEAR: (150.0, 20.0, 120.0, 30.0, 200.0, 1.0),
    JOG_START: (1.0, 0.0, 0.0, 40.0, 300.0, 2000.0),
    MOVE_TOOL_ANGLES: (150.0, 0.0, 100.0, -20.0, 10.0),
    MOVE_TOOL_VECTOR: (150.0, 0.0, 100.0, 1.0, 0.0, -0.3),
    JOG_WRIST: (0.0, 0.0, 30.0, 150.0),
}
_INT1 = {MOVE_JOINTS_PROFILE: 2, JOG_WRIST: 2}


@pytest.mark.parametrize("code", sorted(_GOOD_ARGS))
def test_non_finite_motion_arguments_are_refused(program: LoadedProgram, code: int) -> None:
    """Each REAL argument of each motion start in turn NaN, +Inf, -Inf: refused (nonzero
    result), no motion starts, no register goes NaN; the same command with finite arguments
    is accepted (so the refusals are not for some other reason)."""
    bench = Bench(program)
    bench.move(0.0, 70.0, 65.0, 150)
    bad: list[str] = []
    for slot in range(len(_GOOD_ARGS[code])):
        for value in (math.nan, math.inf, -math.inf):
            args: list[Arg] = list(_GOOD_ARGS[code])
            args[slot] = value
            starts = bench.ctl.read("MOTIONSTARTS")
            result = bench.a.command(code, int1=_INT1.get(code, 0), args=args)
            bench.ctl.step(3)
            if result == OK or bench.ctl.read("MOTIONSTARTS") != starts:
                bad.append(f"Arg{slot + 1} = {value}: answered {result}, motion starts "
                           f"{starts} -> {bench.ctl.read('MOTIONSTARTS')}")
            bench.b.command(STOP)
            bench.ctl.step(160)
    assert bench.a.command(code, int1=_INT1.get(code, 0), args=_GOOD_ARGS[code]) == OK
    bench.b.command(STOP)
    bench.ctl.step(160)
    assert not bad, f"code {code}: " + "; ".join(bad)
    bench.assert_safe()


# ------------------------------------------------------------------------------------------
# 7  the check word covers the arguments
# ------------------------------------------------------------------------------------------

def test_block_written_word_by_word_does_not_run_with_old_arguments(bench: Bench) -> None:
    """Check of the whole new block first, then its header, and its arguments only four
    scans later: the header never runs with the previous block's arguments."""
    ctl, a = bench.ctl, bench.a
    bench.move(10.0, 70.0, 65.0, 150)
    starts = ctl.read("MOTIONSTARTS")
    new = ctl.block(a.mailbox, a.session, a.next_seq(), MOVE_JOINTS,
                    args=(-40.0, 80.0, 75.0))
    ctl.write_word(a.mailbox, "CHECK", new.check)
    ctl.step()
    for name, value in (("SEQ", new.seq), ("SESSION", new.session), ("CODE", new.code),
                        ("INT1", 0), ("INT2", 0)):
        ctl.write_word(a.mailbox, name, value)
    ctl.written.setdefault(a.mailbox, set()).add((new.session, new.seq, new.check))
    ctl.step(4)
    answer = ctl.answer(a.mailbox)
    ran = (ctl.read("MOTIONSTARTS"), ctl.read("MOTIONSEQ"), ctl.read("BASEDEG"))
    for k, arg in enumerate((-40.0, 80.0, 75.0, 0.0, 0.0, 0.0)):
        ctl.write_word(a.mailbox, f"ARG{k + 1}", arg)
    ctl.step(150)
    assert answer.ack_seq == new.seq and answer.result == BAD_CHECK, (
        f"the header with the old arguments was answered {answer.result}; motion starts "
        f"{starts} -> {ran[0]}, motion seq {ran[1]}, base target {ran[2]}")
    assert ctl.read("MOTIONSTARTS") == starts and ctl.read("BASEDEG") == 10.0
    bench.assert_safe()


def test_foreign_arguments_in_a_pending_block_do_not_run(bench: Bench) -> None:
    """A's block waits in its mailbox; before the scan takes it, session B overwrites only
    Arg1..Arg3: the mixed block must not run (106)."""
    ctl, a = bench.ctl, bench.a
    bench.move(10.0, 70.0, 65.0, 150)
    starts = ctl.read("MOTIONSTARTS")
    blk = a.send(MOVE_JOINTS, args=(-40.0, 80.0, 75.0))
    for k, arg in enumerate((50.0, 100.0, 40.0)):
        ctl.write_word(a.mailbox, f"ARG{k + 1}", arg)
    ctl.step()
    result = a.result()
    target = ctl.read("BASEDEG")
    ctl.step(150)
    assert result == BAD_CHECK, (f"{blk.describe()} with Arg1..3 overwritten to (50, 100, 40) "
                                 f"was answered {result}; base target now {target}")
    assert ctl.read("MOTIONSTARTS") == starts
    bench.assert_safe()


@pytest.mark.parametrize(("arg", "expect"), [
    (Bits(0x7FA00001), BAD_PARAMETER),  # a signalling NaN payload: counted as 0x7FC00000
    (Bits(0xFFC00000), BAD_PARAMETER),  # a negative quiet NaN
    (Bits(0x80000000), OK),  # -0.0, counted as +0.0; 0 % is a valid opening
])
def test_check_word_counts_nan_canonical_and_negative_zero_as_zero(
        bench: Bench, arg: Bits, expect: int) -> None:
    """SetGripper with an odd NaN or -0.0: the check counts them canonically, so the block is
    taken (not 106) and judged on its argument."""
    result = bench.a.command(SET_GRIPPER, args=(arg,))
    assert result == expect, f"SetGripper({arg}) answered {result}"
    bench.ctl.step(100)
    bench.assert_safe()


def test_block_with_a_wrong_check_is_never_run(bench: Bench) -> None:
    blk = bench.ctl.block(bench.a.mailbox, bench.a.session, bench.a.next_seq(), MOVE_JOINTS,
                          args=(30.0, 70.0, 65.0))
    bench.a.last = bench.ctl.write_block(blk.mailbox, blk.session, blk.seq, blk.code,
                                         args=(30.0, 70.0, 65.0), check=blk.check ^ 0x10)
    bench.ctl.step()
    assert bench.a.result() == BAD_CHECK
    assert bench.ctl.read("MOTIONSTARTS") == 0 and bench.ctl.read("BASEPULSEUS") == 0.0


# ------------------------------------------------------------------------------------------
# power-up: the output stage stands at the servo centres from the very first scan
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("first", ["move", "relax_then_move"])
def test_command_in_the_first_scan_starts_from_the_servo_centre(
        program: LoadedProgram, first: str) -> None:
    """Blocks already waiting when the PLC starts are run in scan 1: the arm must start from
    the servo centres (1500 us, shoulder 70 deg, elbow 65 deg), not from 0 deg."""
    ctl = SteppedController(program, check_formula_from_env())
    out = OutputMonitor()
    ctl.observers.append(out)
    a, b = Client(ctl, 1, 303_003), Client(ctl, 2, 404_004)
    if first == "relax_then_move":
        a.send(RELAX)
        ctl.step()
    b.send(MOVE_JOINTS, args=(0.0, 75.0, 60.0))
    ctl.step(200)
    assert b.result() == OK
    if out.violations:
        pytest.fail(out.failure(), pytrace=False)


def test_words_in_any_order_run_whole_or_not_at_all(bench: Bench) -> None:
    """A client (or two) writing a block's 16-bit registers one at a time, in any order, with
    scans in between: every taken block runs with exactly its own arguments or is answered
    106; a mix of the previous block's and the new one's words never moves the arm."""
    ctl, a = bench.ctl, bench.a
    rng = random.Random(20261126)
    bench.move(0.0, 70.0, 65.0, 150)
    fields = ("SEQ", "SESSION", "CODE", "INT1", "INT2", "ARG1", "ARG2", "ARG3", "ARG4", "ARG5",
              "ARG6", "CHECK")
    outcomes: dict[int, int] = {}
    for trial in range(60):
        base = (-30.0, 30.0)[trial % 2]
        blk = ctl.block(a.mailbox, a.session, a.next_seq(), MOVE_JOINTS,
                        args=(base, 70.0 + (trial % 3), 65.0))
        words = (blk.seq, blk.session, blk.code, blk.int1, blk.int2, *blk.args, blk.check)
        halves = [(name, shift, (w & 0xFFFFFFFF) >> shift & 0xFFFF)
                  for name, w in zip(fields, words, strict=True) for shift in (16, 0)]
        rng.shuffle(halves)
        ctl.written.setdefault(a.mailbox, set()).add((blk.session, blk.seq, blk.check))
        starts = ctl.read("MOTIONSTARTS")
        for name, shift, half in halves:
            reg = f"MBX{a.mailbox:02d}{name}"
            old = ctl._md_u[ctl.index(reg)]
            ctl.write_raw(reg, (old & ~(0xFFFF << shift)) | (half << shift))
            ctl.step(rng.choice((0, 0, 1)))
        ctl.step(3)
        answer = ctl.answer(a.mailbox)
        ran = ctl.read("MOTIONSTARTS") != starts
        outcomes[answer.result] = outcomes.get(answer.result, 0) + 1
        if answer.ack_seq == blk.seq and answer.result == OK:
            assert ran and ctl.read("BASEDEG") == base, (
                f"trial {trial}: Seq {blk.seq} answered 0 but ran with base "
                f"{ctl.read('BASEDEG')} instead of its own {base}")
        else:
            assert answer.result == BAD_CHECK and not ran, (trial, answer, ran)
            a.seq = answer.ack_seq  # the client goes on after the answered Seq
        ctl.step(60)
    assert outcomes.get(OK, 0) > 0 and outcomes.get(BAD_CHECK, 0) > 0, outcomes
    bench.assert_safe()
