"""plc_project/controller/ServoOutputStage.st: ServoOutputChannel under hostile sequences.

The invariants are the header's, checked on the emitted float32 pulse against limits
computed here from the calibration (g = pulse span / servo-angle span, us per deg), never
read from the block: per powered scan |step| <= MaxVelDeg * g * dt and |step change| <=
MaxAccDeg * g * dt^2; the pulse is 0.0 (limp) or inside [MinPulseUs, MaxPulseUs], never NaN;
a channel powered again starts where it stopped, at rest; a calibration change alone never
moves the pulse; a constant command is reached exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
DT = 0.01
DEFAULT_CAL = {"ZeroOffsetDeg": 0.0, "Direction": 1, "MinPulseUs": 1000.0,
               "MaxPulseUs": 2000.0, "MinAngleDeg": -60.0, "MaxAngleDeg": 60.0}
HOSTILE = [math.nan, math.inf, -math.inf, 1.0e30, -1.0e30, 3.4e38, 0.0, -0.0, 1.0e-30]


@pytest.fixture(scope="module")
def stage_module() -> Any:
    from armbench.compiler import compile_files
    return compile_files([*sorted((REPO / "st").glob("*.st")),
                          REPO / "plc_project" / "controller" / "ServoOutputStage.st"])


def g_of(cal: dict[str, Any]) -> float:
    span_us = cal["MaxPulseUs"] - cal["MinPulseUs"]
    return float(span_us / (cal["MaxAngleDeg"] - cal["MinAngleDeg"]))


@dataclass
class Channel:
    """One ServoOutputChannel and the invariants over its history."""

    mod: Any
    fb: Any = None
    last_on: float | None = None  # last powered pulse
    prev_step: float = 0.0
    was_on: bool = False
    worst_step: float = 0.0  # largest |step| / limit seen
    worst_acc: float = 0.0
    pulses: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.fb = self.mod.new_fb("ServoOutputChannel")

    def step(self, powered: bool, cmd: float, cal: dict[str, Any] = DEFAULT_CAL,
             vel: float = 150.0, acc: float = 1000.0, replanned: bool = False) -> Any:
        out = self.fb(Powered=powered, CommandDeg=cmd, Calibration=cal, MaxVelDeg=vel,
                      MaxAccDeg=acc, CycleTime=DT, Replanned=replanned)
        p = float(out.PulseUs)
        self.pulses.append(p)
        assert math.isfinite(p), f"pulse {p}"
        g = g_of(cal)
        vs, as_ = vel * g * DT, acc * g * DT * DT
        if p == 0.0:
            assert not powered
            self.was_on = False
            self.prev_step = 0.0
            return out
        assert powered
        assert cal["MinPulseUs"] - 1e-3 <= p <= cal["MaxPulseUs"] + 1e-3, p
        if self.last_on is None:
            # never powered before: the stage stood at the servo centre (servo angle 0)
            self.last_on = cal["MinPulseUs"] - cal["MinAngleDeg"] * g
        if self.last_on is not None:
            s = p - self.last_on
            tol = 1e-3 + 1e-5 * abs(p)
            assert abs(s) <= vs + tol, f"step {s} > {vs}"
            assert abs(s - self.prev_step) <= as_ + tol, \
                f"step change {s - self.prev_step} > {as_} (powered again: {not self.was_on})"
            self.worst_step = max(self.worst_step, abs(s) / vs)
            self.worst_acc = max(self.worst_acc, abs(s - self.prev_step) / as_)
            self.prev_step = s
        self.last_on = p
        self.was_on = True
        return out


def test_starts_limp_at_the_servo_centre_and_reaches_a_target_exactly(stage_module: Any) -> None:
    ch = Channel(stage_module)
    out = ch.step(False, 40.0)
    assert out.PulseUs == 0.0 and out.HeldPulseUs == 1500.0 and out.AngleDeg == 0.0
    for _ in range(200):
        out = ch.step(True, 40.0)
    assert out.PulseUs == pytest.approx(1500.0 + 40.0 * 1000.0 / 120.0, abs=1e-3)
    assert not out.Moving and not out.Limited
    first = ch.pulses.index(next(p for p in ch.pulses if p > 0.0))
    assert ch.pulses[first] - 1500.0 <= 1000.0 * 1000.0 / 120.0 * DT * DT + 1e-3  # from rest


def test_relax_then_power_again_starts_where_it_stopped(stage_module: Any) -> None:
    ch = Channel(stage_module)
    for _ in range(30):
        ch.step(True, 60.0)  # moving fast towards the end
    moving_at = ch.pulses[-1]
    assert ch.prev_step > 1.0
    ch.step(False, 60.0)
    out = ch.step(True, -60.0)  # a new command the other way, in the very next scan
    assert abs(out.PulseUs - moving_at) <= 1000.0 * 1000.0 / 120.0 * DT * DT + 1e-3


def test_calibration_change_alone_never_moves_the_servo(stage_module: Any) -> None:
    ch = Channel(stage_module)
    for _ in range(100):
        out = ch.step(True, 0.0)
    assert out.PulseUs == 1500.0
    shifted = dict(DEFAULT_CAL, ZeroOffsetDeg=30.0)
    out = ch.step(True, 0.0, cal=shifted)  # the caller has not re-read the angle yet
    assert abs(out.PulseUs - 1500.0) <= 1000.0 / 120.0 * 1000.0 * DT * DT + 1e-3  # at most one
    # acceleration step towards the new mapping. The caller commands the angle of the held
    # pulse under the new calibration (1500 us is servo angle 0 = joint 30 deg): nothing moves.
    ch2 = Channel(stage_module)
    for _ in range(100):
        out = ch2.step(True, 0.0)
    for _ in range(10):
        out = ch2.step(True, 30.0, cal=shifted)
        assert out.PulseUs == 1500.0 and out.AngleDeg == 30.0
    # an angle whose round trip through float32 misses the pulse by an ulp holds too
    odd = dict(DEFAULT_CAL, ZeroOffsetDeg=1.0 / 3.0)
    for _ in range(10):
        out = ch2.step(True, 1.0 / 3.0, cal=odd)
        assert out.PulseUs == 1500.0


def test_a_command_beyond_the_travel_brakes_at_the_end(stage_module: Any) -> None:
    ch = Channel(stage_module)
    for _ in range(400):
        out = ch.step(True, 1.0e6, vel=2000.0, acc=100.0)
    assert out.PulseUs == 2000.0 and not out.Moving


def test_non_finite_command_brakes_to_rest(stage_module: Any) -> None:
    ch = Channel(stage_module)
    for _ in range(30):
        ch.step(True, 60.0)
    for _ in range(60):
        out = ch.step(True, math.nan)
    assert out.Error and out.ErrorId == 3 and not out.Moving


command = st.one_of(st.floats(-200.0, 200.0), st.sampled_from(HOSTILE))
cal_choice = st.sampled_from([
    DEFAULT_CAL,
    dict(DEFAULT_CAL, ZeroOffsetDeg=30.0),
    dict(DEFAULT_CAL, Direction=-1, ZeroOffsetDeg=-20.0),
    dict(DEFAULT_CAL, MinPulseUs=600.0, MaxPulseUs=2400.0, MinAngleDeg=-90.0, MaxAngleDeg=90.0),
])
limits = st.tuples(st.sampled_from([0.1, 30.0, 150.0, 2000.0]),
                   st.sampled_from([10.0, 400.0, 1000.0, 1.0e5]))


@given(st.lists(st.tuples(st.booleans(), command, st.integers(1, 40)), min_size=1, max_size=12),
       cal_choice, limits)
def test_invariants_under_hostile_sequences(stage_module: Any,
                                            program: list[tuple[bool, float, int]],
                                            cal: dict[str, Any],
                                            lim: tuple[float, float]) -> None:
    ch = Channel(stage_module)
    for powered, cmd, scans in program:
        for _ in range(scans):
            ch.step(powered, cmd, cal=cal, vel=lim[0], acc=lim[1])


@given(st.lists(st.tuples(st.booleans(), command, st.integers(1, 40), st.booleans()),
                min_size=1, max_size=12), cal_choice, limits)
def test_invariants_whatever_replanned_says(stage_module: Any,
                                            program: list[tuple[bool, float, int, bool]],
                                            cal: dict[str, Any],
                                            lim: tuple[float, float]) -> None:
    """Replanned only moves the feed-forward's reference: a caller that says it re-planned
    when it did not (in the first scan of each run of scans) cannot break a limit."""
    ch = Channel(stage_module)
    for powered, cmd, scans, replanned in program:
        for k in range(scans):
            ch.step(powered, cmd, cal=cal, vel=lim[0], acc=lim[1], replanned=replanned and k == 0)


@pytest.mark.parametrize("decel", [200.0, 120.0])
def test_a_braking_replanned_from_a_trailing_stage_is_followed_exactly(
        stage_module: Any, decel: float) -> None:
    """A command that speeds up at 1000 deg/s^2 (five times the stage's 200) to 45 deg/s
    leaves the stage, at its 50 deg/s, degrees behind. A Stop's braking is then planned from
    the stage's own AngleDeg and VelDeg (x0, v0) at `decel` <= the stage's limit:
    x(t) = x0 + v0 t - decel t^2 / 2 until t = v0 / decel (MotionStopEval), with Replanned
    in its first scan. The stage must follow that plan scan by scan: never past
    x0 + v0^2 / (2 decel), at rest within ceil(v0 / (decel dt)) scans."""
    vel, acc = 50.0, 200.0
    ch = Channel(stage_module)
    cmd = speed = 0.0
    out = ch.step(True, cmd, vel=vel, acc=acc)
    for _ in range(30):
        speed = min(45.0, speed + 1000.0 * DT)
        cmd += speed * DT
        out = ch.step(True, cmd, vel=vel, acc=acc)
    x0, v0 = float(out.AngleDeg), float(out.VelDeg)
    assert v0 == pytest.approx(vel, rel=1e-4) and cmd - x0 > 2.0, (x0, v0, cmd)
    stop_t = v0 / decel
    need = math.ceil(stop_t / DT)
    worst = 0.0
    for k in range(1, need + 20):
        t = min(k * DT, stop_t)
        plan = x0 + v0 * t - decel * t * t / 2.0
        out = ch.step(True, plan, vel=vel, acc=acc, replanned=(k == 1))
        worst = max(worst, abs(float(out.AngleDeg) - plan))
        if k > need:
            assert not out.Moving, f"still moving {k} scans after the Stop (plan: {need})"
    assert worst <= 1e-3, f"the stage left the braking plan by up to {worst:.6g} deg"
    assert float(out.AngleDeg) == pytest.approx(x0 + v0 * v0 / (2.0 * decel), abs=1e-3)


def test_a_command_running_past_the_travel_end_is_braked_before_it(stage_module: Any) -> None:
    """A generator that drives on past the travel at nearly full speed (a slow Stop, a jog
    whose limits are wrong): the stage must start braking early enough to stop at 2000 us
    within its acceleration limit, not follow the command to the end and stop dead there."""
    ch = Channel(stage_module)
    cmd = 0.0
    for _ in range(200):
        ch.step(True, cmd)
    for _ in range(300):
        cmd += 140.0 * DT  # 140 deg/s, under the 150 deg/s limit, on past +60 deg
        out = ch.step(True, cmd)
    assert out.PulseUs == 2000.0 and not out.Moving
    assert ch.worst_acc <= 1.0 + 1e-3


def test_a_group_replanned_from_the_stage_angle_does_not_move_a_resting_servo(
        stage_module: Any) -> None:
    """The controller re-plans its group from the stage's own joint angle (AngleDeg, read back
    from the held pulse through float32). Commanding that angle to a resting channel must not
    move it by the ulp the round trip pulse -> angle -> pulse loses."""
    moved = []
    rng = np.random.default_rng(20261126)
    cals = [DEFAULT_CAL, dict(DEFAULT_CAL, ZeroOffsetDeg=70.0),
            dict(DEFAULT_CAL, ZeroOffsetDeg=65.0, Direction=-1),
            dict(DEFAULT_CAL, ZeroOffsetDeg=1.0 / 3.0, MinPulseUs=900.0, MaxPulseUs=2100.0)]
    for cal in cals:
        # about 1 angle in 500 loses an ulp on the round trip: draw many
        for target in cal["ZeroOffsetDeg"] + rng.uniform(-59.0, 59.0, 1500):
            ch = Channel(stage_module)
            for _ in range(30):
                out = ch.step(True, float(target), cal=cal, vel=2000.0, acc=1.0e5)
            assert not out.Moving
            held = float(out.PulseUs)
            for _ in range(3):
                out = ch.step(True, float(out.AngleDeg), cal=cal, vel=2000.0, acc=1.0e5)
                if float(out.PulseUs) != held:
                    moved.append((float(target), held, float(out.PulseUs)))
                    break
    assert not moved, f"{len(moved)} resting servos moved, e.g. {moved[:3]}"
