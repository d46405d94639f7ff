"""Joint moves over Modbus (MoveJointsProfile, MoveXyz through the motion layer): targets
reached, speeds within the limits, the output stage's slew guarantee on the recorded path,
and the durations of the closed forms (constant speed d/v + v/a with ramps at the limit,
trapezoid d/v + v/a or 2 sqrt(d/a)). Runs against the soft PLC or a real one by address."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import pytest
from motion_checks import DT, check_slew_limited

from armbench.controller_client import (
    ERR_BAD_PARAMETER,
    ERR_JOINT_LIMIT,
    ArmControllerClient,
    MotionRecorder,
    MotionRecording,
    MotionSample,
    MotionTicket,
)

START = (0.0, 70.0, 65.0)
TARGET = (40.0, 100.0, 40.0)
LIMIT_VEL, LIMIT_ACC = 150.0, 1000.0  # the controller's defaults (ServoSlew.st)
MIN_TRIPLES = 10  # triples of neighbouring scans the slew check must have seen
MAX_MOVES = 30  # moves recorded to find them on a loaded machine (one is enough on an idle one)


def trapezoid_time(d: float, v: float, a: float) -> float:
    return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)


@dataclass(frozen=True)
class Bracket:
    """A scan of the PLC known to lie in lo..hi (both included). The recorder samples the
    scans it gets to (one read each, tagged with ScanCount); a loaded machine makes it miss
    some, and an event that happened between two samples is only bracketed by them."""

    lo: int
    hi: int


def start_bracket(samples: list[MotionSample], ticket: MotionTicket) -> Bracket:
    """The first scan of the motion ``ticket``: between the last sample before it and the
    first that shows it busy."""
    first = next(i for i, s in enumerate(samples) if s.ticket == ticket and s.busy)
    assert first > 0, "the recorder's first sample already shows the motion running"
    return Bracket(samples[first - 1].scan + 1, samples[first].scan)


def arrival_bracket(samples: list[MotionSample], j: int, target: float) -> Bracket:
    """The first scan from which joint j's setpoint stays at its target: after the last
    sample away from it, at the latest the sample after that one."""
    away = [i for i, s in enumerate(samples) if abs(s.set_deg[j] - target) > 1e-3]
    assert away and away[-1] + 1 < len(samples), f"joint {j} was never seen moving and then at rest"
    last = away[-1]
    return Bracket(samples[last].scan + 1, samples[last + 1].scan)


def record_profile_move(plc: ArmControllerClient, rec: MotionRecorder, profile: int,
                        v: float, a: float) -> tuple[MotionRecording, MotionTicket]:
    """One move from START to TARGET, recorded; checks what every recording shows whatever
    scans it missed: the target reached and no setpoint faster than v."""
    assert plc.move_joints(*START, wait=True).error_id == 0
    rec.start()
    st = plc.move_joints_profile(TARGET, profile, v, a, jerk=4000.0)
    assert st.error_id == 0
    outcome, run = rec.record_until_idle(plc)
    assert outcome.state == "done", outcome
    final = run.samples[-1]
    for j in range(3):
        assert final.out_deg[j] == pytest.approx(TARGET[j], abs=1e-3)
        assert final.set_deg[j] == pytest.approx(TARGET[j], abs=1e-3)
    ticket = plc.last_ticket
    assert ticket is not None
    moving = [s for s in run.samples if s.ticket == ticket]
    peak = [max(abs(s.set_vel[j]) for s in moving) for j in range(3)]
    assert max(peak) <= v * (1 + 1e-4)
    return run, ticket


def check_arrival_times(run: MotionRecording, ticket: MotionTicket, profile: int,
                        v: float, a: float) -> None:
    """The closed forms' arrival times (3 scans of slack), on the PLC's scans: each arrival
    counts from the move's first scan, both bracketed by the samples around them, so a scan
    the recorder missed widens the bracket instead of moving the time."""
    start = start_bracket(run.samples, ticket)
    arrive = [arrival_bracket(run.samples, j, TARGET[j]) for j in range(3)]
    dist = [abs(t - s0) for t, s0 in zip(TARGET, START, strict=True)]

    def within(expected_s: float, lo: int, hi: int) -> bool:
        # lo..hi: the scans from the move's first scan to the arrival that the samples allow
        return (lo - 3) * DT <= expected_s <= (hi + 3) * DT

    if profile == 0:  # every joint at the speed v, ramps at the limit: own times
        for j in range(3):
            expected = trapezoid_time(dist[j], v, LIMIT_ACC)
            assert within(expected, arrive[j].lo - start.hi, arrive[j].hi - start.lo), \
                (f"joint {j}: arrival {expected:.4f} s expected, the samples put it at "
                 f"{(arrive[j].lo - start.hi) * DT:.2f}..{(arrive[j].hi - start.lo) * DT:.2f} s")
    else:  # synchronised: all arrive together (2 scans apart at most)
        latest_lo = max(b.lo for b in arrive)
        earliest_hi = min(b.hi for b in arrive)
        assert latest_lo - earliest_hi <= 2, f"arrivals {arrive} are more than 2 scans apart"
    if profile in (1, 2):
        ramp = LIMIT_ACC if profile == 1 else a
        expected = trapezoid_time(max(dist), v, ramp)
        last_lo, last_hi = max(b.lo for b in arrive), max(b.hi for b in arrive)
        assert within(expected, last_lo - start.hi, last_hi - start.lo), \
            (f"arrival {expected:.4f} s expected, the samples put it at "
             f"{(last_lo - start.hi) * DT:.2f}..{(last_hi - start.lo) * DT:.2f} s")


@pytest.mark.parametrize("profile", [0, 1, 2, 3])
def test_profile_reaches_target_within_limits(
        plc: ArmControllerClient, motion_recorder: Callable[[], MotionRecorder],
        profile: int) -> None:
    """Every recording is checked on the scans it holds; the move is made again until the
    slew check has seen MIN_TRIPLES triples of neighbouring scans (once, on an idle machine:
    the recorder samples every scan then; a loaded one lets it sample fewer)."""
    v, a = 80.0, 400.0
    rec = motion_recorder()
    triples = 0
    for _ in range(MAX_MOVES):
        run, ticket = record_profile_move(plc, rec, profile, v, a)
        check_arrival_times(run, ticket, profile, v, a)
        triples += check_slew_limited(run)
        if triples >= MIN_TRIPLES:
            return
    pytest.fail(f"{MAX_MOVES} moves recorded only {triples} triples of neighbouring scans "
                f"(the recorder missed most scans: the machine is too loaded to sample a "
                f"10 ms PLC at all)")


def test_move_xyz_is_a_smooth_joint_move(plc: ArmControllerClient,
                                         motion_recorder: Callable[[], MotionRecorder]) -> None:
    rec = motion_recorder()
    triples = 0
    for _ in range(MAX_MOVES):
        assert plc.move_joints(*START, wait=True).error_id == 0
        rec.start()
        st = plc.move_xyz(120.0, 60.0, 90.0)
        assert st.error_id == 0
        outcome, run = rec.record_until_idle(plc)
        assert outcome.state == "done"
        assert run.samples[-1].out_deg == pytest.approx(st.joints_deg, abs=1e-3)
        busy = [s.scan for s in run.samples if s.busy]
        assert busy and busy[-1] - busy[0] >= 10  # several scans, not a jump (PLC scans)
        triples += check_slew_limited(run)
        if triples >= MIN_TRIPLES:
            return
    pytest.fail(f"{MAX_MOVES} moves recorded only {triples} triples of neighbouring scans")


@pytest.mark.parametrize("args,code", [
    ((TARGET, 2, math.nan, 400.0), ERR_BAD_PARAMETER),
    ((TARGET, 2, -5.0, 400.0), ERR_BAD_PARAMETER),
    ((TARGET, 2, 80.0, 0.0), ERR_BAD_PARAMETER),
    ((TARGET, 7, 80.0, 400.0), 20),  # BadProfile (st/MotionProfiles.st)
    (((0.0, 70.0, 200.0), 2, 80.0, 400.0), ERR_JOINT_LIMIT),
])
def test_bad_joint_move_is_rejected_and_changes_nothing(
        plc: ArmControllerClient, args: tuple, code: int) -> None:  # type: ignore[type-arg]
    assert plc.move_joints(*START, wait=True).error_id == 0
    before = plc.motion()
    st = plc.move_joints_profile(*args)
    assert st.error_id == code
    after = plc.motion()
    assert after.ticket == before.ticket and after.out_deg == before.out_deg
