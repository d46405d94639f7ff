"""The wrist jog (32 JogWrist) and the gripper (33 SetGripper, channel 5) of
plc_project/Controller.st over Modbus only: runs against the soft PLC, or a real PLC with
``--plc-host``/``--plc-port`` like the rest of tests/modbus.

References, all independent of the PLC's code:
- a float64 numpy product of elementary transforms Rz(base) Tz(A1) Tx(A2) Ry(-shoulder) Tx(A3)
  Ry(180 - elbow) Tx(A4) Ry(-wrist pitch) Rx(roll) Tx(tool) (st/Kinematics5Axis.st's joint
  conventions), evaluated on the joint angles the servos are sent (the slew limiters'
  outputs), sampled every scan;
- the slew guarantee restated from st/ServoSlew.st's header (step <= MaxVel dt, step change
  <= MaxAcc dt^2) on every channel, with the limits the PLC reports;
- the braking distance v^2 / (2 a) of a constant deceleration;
- the MG996R mapping (1000..2000 us over the servo's -60..+60 deg) and the PCA9685's count
  (datasheet equation 1), computed here from the calibration the test sends.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from armbench.controller_client import (
    CMD_JOG_WRIST,
    CMD_SET_CALIBRATION,
    CMD_SET_GRIPPER,
    ERR_BAD_JOINT,
    ERR_BAD_PARAMETER,
    ERR_JOG_TIMEOUT,
    ERR_JOINT_LIMIT,
    ERR_NOT_FINITE,
    ERR_NOT_MOTION_OWNER,
    ERR_OK,
    JOG_DEADMAN_SCANS,
    JOINT_GRIPPER,
    KIND_JOG_WRIST,
    ArmControllerClient,
    Calibration,
)
from armbench.plant import arm
from armbench.registermap import Register
from armbench.softplc.modbus_client import PlcClient
from five_axis_ref import fk5, pitch_from_joints, tool_pitch

G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0  # FiveAxisGeometry.ToolMm default (Controller.st 5-AXIS)
DT = 0.01  # s, the controller's task interval
TOL_DEG = 1e-4  # float32 angles near 100 deg, a few ulps per step
F_UPDATE_HZ = 25e6 / (4096 * 122)  # PCA9685 at prescale 121 (datasheet equation 1)
# the 5-axis start pose (deg): inside every servo's default travel, tip in front of the base
Q_START = (10.0, 80.0, 100.0, -20.0, 10.0)


def fk(q: tuple[float, ...] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flange point, tool frame 4x4), float64 (tests/five_axis_ref.py)."""
    flange, tool = fk5(q, G, TOOL_MM)
    return flange[:3, 3], tool


@dataclass(frozen=True)
class _Span:
    """Registers from one located variable to another (the same table): one read."""

    table: str
    address: int
    length: int

    @classmethod
    def of(cls, regs: dict[str, Register], first: str, last: str) -> _Span:
        a, b = regs[first], regs[last]
        assert a.table == b.table, (first, last)
        return cls(a.table, a.address, b.address + b.count - a.address)

    def value(self, regs: dict[str, Register], words: list[int], name: str) -> float:
        r = regs[name.upper()]
        k = r.address - self.address
        return float(r.decode(words[k: k + r.count]))


@dataclass(frozen=True)
class Sample:
    """One scan of the channels this suite checks."""

    scan: int
    kind: int
    busy: bool
    error_id: int
    at_limit: bool
    out: tuple[float, ...]  # deg, channels 0..5 (slew limiter outputs)
    lim_vel: tuple[float, ...]
    lim_acc: tuple[float, ...]
    echo_tip: tuple[float, float, float]
    echo_pitch: float


class ChannelRecorder:
    """Samples the motion and 5-axis/gripper blocks on its own connection: two FC3 reads,
    kept only when a third read finds the scan tag unchanged (both blocks are then from one
    scan). Scans it misses are missing, never interpolated."""

    def __init__(self, address: tuple[str, int], regs: dict[str, Register]) -> None:
        self.address = address
        self.regs = regs
        # %MD724..762 on OpenPLC: the motion block (scan tag, arm outputs, limits)
        self.a = _Span.of(regs, "MOTIONSCAN", "LIMELBOWACC")
        # %MD812..849 on OpenPLC: the 5-axis echo, wrist and gripper
        self.b = _Span.of(regs, "FIVESESSION", "GRIPPERMOVING")
        self.samples: list[Sample] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="wrist-recorder")

    def __enter__(self) -> ChannelRecorder:
        self._thread.start()
        deadline = time.monotonic() + 5.0
        while not self.samples and time.monotonic() < deadline:
            time.sleep(0.005)
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5.0)

    def wait_past(self, scan: int, timeout_s: float = 30.0) -> None:
        """Return once a sample of a scan after ``scan`` is in: the record then holds the
        standstill that follows, however slowly a loaded machine lets this recorder read
        (a fixed 0.1 s left it with no sample after the dead-man fired, under load)."""
        deadline = time.monotonic() + timeout_s
        while not (self.samples and self.samples[-1].scan > scan):
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise AssertionError(f"the recorder sampled no scan after {scan} in "
                                     f"{timeout_s:g} s")
            time.sleep(0.005)

    def _run(self) -> None:
        a, b = self.a, self.b
        with PlcClient(*self.address) as c:
            while not self._stop.is_set():
                wa = c.read_table(a.table, a.address, a.length)
                wb = c.read_table(b.table, b.address, b.length)
                tag = c.read_table(a.table, a.address, 2)
                if tag != wa[:2]:
                    continue
                scan = int(a.value(self.regs, wa, "MOTIONSCAN"))
                if self.samples and self.samples[-1].scan == scan:
                    time.sleep(0.001)
                    continue

                self.samples.append(self._decode(scan, wa, wb))

    def _decode(self, scan: int, wa: list[int], wb: list[int]) -> Sample:
        def ra(n: str) -> float:
            return self.a.value(self.regs, wa, n)

        def rb(n: str) -> float:
            return self.b.value(self.regs, wb, n)

        def ia(n: str) -> int:
            return int(ra(n))

        out = (ra("OutBaseDeg"), ra("OutShoulderDeg"), ra("OutElbowDeg"),
               rb("OutWristPitchDeg"), rb("OutWristRollDeg"), rb("OutGripperDeg"))
        vel = (ra("LimBaseVel"), ra("LimShoulderVel"), ra("LimElbowVel"),
               rb("LimWristPitchVel"), rb("LimWristRollVel"), rb("LimGripperVel"))
        acc = (ra("LimBaseAcc"), ra("LimShoulderAcc"), ra("LimElbowAcc"),
               rb("LimWristPitchAcc"), rb("LimWristRollAcc"), rb("LimGripperAcc"))
        return Sample(scan, ia("MotionKind"), bool(ia("MotionBusy")), ia("MotionErrorId"),
                      bool(ia("MotionAtLimit")), out, vel, acc,
                      (rb("FiveTipX"), rb("FiveTipY"), rb("FiveTipZ")),
                      rb("FiveToolPitchDeg"))

    def triples(self) -> Iterator[tuple[Sample, Sample, Sample]]:
        s = self.samples
        for a, b, c in zip(s, s[1:], s[2:], strict=False):
            if b.scan - a.scan == 1 and c.scan - b.scan == 1:
                yield a, b, c


def assert_slew_limited(rec: ChannelRecorder, min_triples: int = 10) -> None:
    """Every channel 0..5, on every three neighbouring scans recorded: the step within the
    speed limit, the step's change within the acceleration limit (ServoSlew.st)."""
    n = 0
    for a, b, c in rec.triples():
        n += 1
        for j in range(6):
            s1, s2 = b.out[j] - a.out[j], c.out[j] - b.out[j]
            assert math.isfinite(s1) and math.isfinite(s2)
            cap = max(c.lim_vel[j] * DT, abs(s1) - c.lim_acc[j] * DT * DT)
            assert abs(s2) <= cap + TOL_DEG, (j, c.scan, s2, cap)
            assert abs(s2 - s1) <= c.lim_acc[j] * DT * DT + 2 * TOL_DEG, (j, c.scan, s2 - s1)
    assert n >= min_triples, f"only {n} triples of neighbouring scans recorded"


def go_to_start(plc: ArmControllerClient, q: tuple[float, ...] = Q_START) -> np.ndarray:
    """A MoveToolAngles to the pose of joints ``q``; returns its tool tip (reference FK)."""
    _, tool = fk(q)
    tip = tool[:3, 3]
    pitch = pitch_from_joints(q)
    st = plc.move_tool_angles((float(tip[0]), float(tip[1]), float(tip[2])), pitch, q[4],
                              wait=True)
    assert st.error_id == ERR_OK
    return tip


def keep_alive(plc: ArmControllerClient, pitch: float, roll: float, seconds: float) -> None:
    """Jog updates until the PLC has scanned ``seconds`` of its time: the jog moves in scans,
    and a loaded machine runs fewer of a soft PLC's scans per second of wall clock (1.2 s
    of wall clock gave 14 instead of 22 degrees of turn then)."""
    end = (plc.scan_count() + round(seconds / DT)) & 0xFFFFFFFF
    while 0 < (end - plc.scan_count()) & 0xFFFFFFFF < 0x80000000:  # end not reached
        assert plc.jog_wrist_update(pitch, roll).error_id == ERR_OK
        time.sleep(0.02)


def test_tip_fixed_wrist_jog_keeps_the_tip(plc: ArmControllerClient,
                                           plc_address: tuple[str, int]) -> None:
    tip0 = go_to_start(plc)
    rate, acc = 20.0, 100.0
    with ChannelRecorder(plc_address, plc.registers) as rec:
        assert plc.jog_wrist_start(rate, 0.0, 40.0, acc).error_id == ERR_OK
        m = plc.motion()
        assert m.kind == KIND_JOG_WRIST and m.busy
        keep_alive(plc, rate, 0.0, 1.2)
        assert plc.jog_stop().error_id == ERR_OK
        done = plc.wait_motion()
        assert done.state == "done"
        rec.wait_past(done.sample.scan + 2)
    samples = rec.samples
    drift = max(float(np.linalg.norm(fk(s.out)[1][:3, 3] - tip0)) for s in samples)
    print(f"\nworst tip drift during a tip-fixed wrist jog: {drift * 1000:.1f} um")
    assert drift < 0.05, drift
    # the tool pitch of the servos' joints turns at the commanded rate, never faster
    rates = [(tool_pitch(b.out) - tool_pitch(a.out)) / DT
             for a, b, _ in rec.triples() if a.kind == KIND_JOG_WRIST]
    assert max(rates) <= rate * (1 + 1e-3) + 0.05
    steady = [r for r in rates if abs(r - rate) < 0.1]
    assert len(steady) >= 20, sorted(rates)[-5:]
    turned = tool_pitch(samples[-1].out) - tool_pitch(Q_START)
    assert turned > rate * 1.0  # 1.2 s of jog, ramps included
    # the echo block followed the jog: its tip is the held tip, its pitch the servos'
    assert np.linalg.norm(np.array(samples[-1].echo_tip) - tip0) < 0.05
    assert samples[-1].echo_pitch == pytest.approx(tool_pitch(samples[-1].out), abs=0.01)
    assert_slew_limited(rec)


def test_dead_man_brakes_a_silent_wrist_jog(plc: ArmControllerClient,
                                            plc_address: tuple[str, int]) -> None:
    go_to_start(plc)
    rate, acc = 30.0, 150.0
    with ChannelRecorder(plc_address, plc.registers) as rec:
        assert plc.jog_wrist_start(rate, 0.0, rate, acc, flange_fixed=True).error_id == ERR_OK
        started = plc.motion().scan
        outcome = plc.wait_motion(timeout_s=10.0)  # the client says nothing more
        rec.wait_past(outcome.sample.scan + 2)
    assert outcome.state == "error" and outcome.error_id == ERR_JOG_TIMEOUT
    s = [x for x in rec.samples if x.scan >= started]
    # the arm joints stand (flange-fixed), the wrist pitch moved
    assert all(abs(x.out[j] - s[0].out[j]) < TOL_DEG for x in s for j in range(3))
    fired = started + JOG_DEADMAN_SCANS + 1
    at_fire = min((x for x in s if x.scan >= fired), key=lambda x: x.scan)
    rest = s[-1]
    braked = abs(rest.out[3] - at_fire.out[3])
    bound = rate * rate / (2 * acc) + rate * DT * (at_fire.scan - fired + 1)
    print(f"\nwrist jog dead-man: braked {braked:.3f} deg from {rate} deg/s "
          f"(bound v^2/2a = {rate * rate / (2 * acc):.3f} deg)")
    assert braked <= bound + 1e-3
    moving = [x.scan for a, x, _ in rec.triples() if abs(x.out[3] - a.out[3]) > 1e-6]
    assert moving and moving[-1] <= fired + math.ceil(rate / (acc * DT)) + 3
    assert_slew_limited(rec)


def test_wrist_jog_ownership_takeover_and_bad_writes(plc: ArmControllerClient,
                                                     plc_address: tuple[str, int]) -> None:
    go_to_start(plc)
    with ChannelRecorder(plc_address, plc.registers) as rec, PlcClient(*plc_address) as modbus, \
            ArmControllerClient(modbus, flavor=plc.flavor) as other:
        assert plc.jog_wrist_start(5.0, 10.0).error_id == ERR_OK
        # another client cannot steer or stop it
        assert other.jog_wrist_update(60.0, 60.0).error_id == ERR_NOT_MOTION_OWNER
        assert other.jog_stop().error_id == ERR_NOT_MOTION_OWNER
        # bad writes by the owner: NaN shows MotionErrorId 3 while it lasts, huge rates are
        # clamped to the max speed (30 deg/s default)
        assert plc.jog_wrist_update(math.nan, 0.0).error_id == ERR_OK
        plc.wait_scans(3)
        assert plc.motion().error_id == ERR_NOT_FINITE
        assert plc.jog_wrist_update(-1.0e30, 1.0e30).error_id == ERR_OK
        keep_alive(plc, -1.0e30, 1.0e30, 0.6)
        # a bad start changes nothing: the running jog goes on, same ticket
        ticket = plc.motion().ticket
        st = other.command(CMD_JOG_WRIST, ints=(0, 0), args=(1.0, 1.0, math.nan, 0.0))
        assert st.error_id == ERR_BAD_PARAMETER
        st = other.command(CMD_JOG_WRIST, ints=(4, 0), args=(1.0, 1.0, 0.0, 0.0))
        assert st.error_id == ERR_BAD_PARAMETER
        assert plc.motion().ticket == ticket and plc.motion().busy
        # takeover: the other client's JogWrist takes the running jog, same speed and mode
        starts = plc.motion().starts
        assert other.jog_wrist_start(0.0, -10.0).error_id == ERR_OK
        m = plc.motion()
        assert m.busy and m.kind == KIND_JOG_WRIST and m.starts == starts + 1
        assert m.ticket.session == other.session
        assert plc.jog_wrist_update(1.0, 1.0).error_id == ERR_NOT_MOTION_OWNER
        assert other.jog_wrist_update(0.0, -10.0).error_id == ERR_OK
        # Stop from anyone ends it
        assert plc.stop().error_id == ERR_OK
        assert other.wait_motion().state == "superseded"
        done = plc.wait_motion()
        assert done.state == "done"
        rec.wait_past(done.sample.scan + 2)
    roll_speeds = [abs(b.out[4] - a.out[4]) / DT for a, b, _ in rec.triples()]
    assert max(roll_speeds) <= 30.0 * (1 + 1e-3) + 0.01  # the default max speed held
    assert all(math.isfinite(v) for x in rec.samples for v in x.out)
    assert_slew_limited(rec)


def test_wrist_jog_stops_at_the_wrist_limit(plc: ArmControllerClient,
                                            plc_address: tuple[str, int]) -> None:
    go_to_start(plc)
    c = plc.wrist_calibration()[0]
    upper = max(c.zero_offset_deg + c.direction * a for a in (c.min_angle_deg, c.max_angle_deg))
    with ChannelRecorder(plc_address, plc.registers) as rec:
        assert plc.jog_wrist_start(60.0, 0.0, 60.0, 300.0, flange_fixed=True).error_id == ERR_OK
        keep_alive(plc, 60.0, 0.0, 2.0)
        held = plc.motion()
        assert held.busy and held.at_limit, held
        assert plc.jog_stop().error_id == ERR_OK
        assert plc.wait_motion().state == "done"
    top = max(x.out[3] for x in rec.samples)
    assert upper - 2.0 < top <= upper + TOL_DEG
    assert_slew_limited(rec)


def mg996r_pulse_us(joint_deg: float, cal: Calibration) -> float:
    servo = (joint_deg - cal.zero_offset_deg) * cal.direction
    return cal.min_pulse_us + (servo - cal.min_angle_deg) * (
        cal.max_pulse_us - cal.min_pulse_us) / (cal.max_angle_deg - cal.min_angle_deg)


def wait_gripper_still(plc: ArmControllerClient) -> None:
    deadline = time.monotonic() + 10.0
    while plc.gripper().moving:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    plc.wait_scans(2)


def test_gripper_channel(plc: ArmControllerClient, plc_address: tuple[str, int]) -> None:
    cal = Calibration(zero_offset_deg=10.0, direction=-1, min_pulse_us=900.0,
                      max_pulse_us=2100.0, min_angle_deg=-70.0, max_angle_deg=50.0)
    assert plc.set_calibration(JOINT_GRIPPER, cal).error_id == ERR_OK
    assert plc.gripper_calibration() == cal
    assert plc.set_calibration(JOINT_GRIPPER + 1, cal).error_id == ERR_BAD_JOINT
    assert plc.set_motion_limits(JOINT_GRIPPER, 80.0, 400.0).error_id == ERR_OK
    # joint travel: zero + direction * servo range = 10 - (-70..50) = -40..80 deg
    lower, upper = 10.0 - 50.0, 10.0 + 70.0
    with ChannelRecorder(plc_address, plc.registers) as rec:
        for pct in (25.0, 100.0, 0.0):
            assert plc.set_gripper(pct).error_id == ERR_OK
            wait_gripper_still(plc)
            g = plc.gripper()
            joint = lower + (upper - lower) * pct / 100.0
            assert g.opening_pct == pct and g.out_deg == pytest.approx(joint, abs=1e-4)
            expect_us = mg996r_pulse_us(joint, cal)
            assert g.pulse_us == pytest.approx(expect_us, abs=1e-3)
            assert plc.channel_words()[5] == round(expect_us * 4096 * F_UPDATE_HZ / 1e6)
        # bad openings: rejected, nothing moves
        before = plc.gripper()
        for bad in (math.nan, -0.5, 100.5, math.inf):
            assert plc.command(CMD_SET_GRIPPER, args=(bad,)).error_id == ERR_BAD_PARAMETER
        plc.wait_scans(3)
        assert plc.gripper() == before
    speeds = [abs(b.out[5] - a.out[5]) / DT for a, b, _ in rec.triples()]
    assert max(speeds) <= 80.0 * (1 + 1e-3) + 0.01 and max(speeds) > 40.0
    assert_slew_limited(rec)
    # a bad calibration changes nothing
    st = plc.command(CMD_SET_CALIBRATION, ints=(JOINT_GRIPPER, 1),
                     args=(0.0, 2100.0, 900.0, -60.0, 60.0))
    assert st.error_id != ERR_OK and plc.gripper_calibration() == cal
    # a client writing NaN over the gripper's registers (%MD838..849) changes nothing: the
    # program rewrites them from its own state every scan (under CODESYS they are input
    # registers, which no function code writes)
    before, word = plc.gripper(), plc.channel_words()[5]
    first = plc.registers["GRIPPERCALZERODEG"]
    if plc.flavor.openplc_map:
        with PlcClient(*plc_address) as raw:
            raw.write_registers(first.address, first.flavor.encode("REAL", math.nan) * 12)
    else:
        assert (first.table, plc.registers["GRIPPERCALMAXANGLEDEG"].table) == ("input", "input")
    plc.wait_scans(3)
    assert plc.gripper() == before and plc.gripper_calibration() == cal
    assert plc.channel_words()[5] == word
    # the default calibration is refused while the gripper stands at 2100 us, outside its
    # 1000..2000 us (the servo never moves for a calibration); at 1500 us it is taken and
    # the opening is re-read: 1500 us is servo angle -10 deg here (joint 20 deg, 50 %) and
    # the default's servo centre (joint 0 deg, 50 % of -60..60)
    assert plc.gripper().pulse_us == pytest.approx(2100.0, abs=1e-3)
    assert plc.set_calibration(JOINT_GRIPPER, Calibration()).error_id == ERR_JOINT_LIMIT
    assert plc.set_gripper(100.0 * (20.0 - lower) / (upper - lower)).error_id == ERR_OK
    wait_gripper_still(plc)
    assert plc.gripper().pulse_us == pytest.approx(1500.0, abs=1e-3)
    word = plc.channel_words()[5]
    assert plc.set_calibration(JOINT_GRIPPER, Calibration()).error_id == ERR_OK
    plc.wait_scans(3)
    g = plc.gripper()
    assert g.pulse_us == pytest.approx(1500.0, abs=1e-3) and plc.channel_words()[5] == word
    assert g.opening_pct == pytest.approx(50.0, abs=1e-3)


def test_gripper_does_not_disturb_an_arm_motion(plc: ArmControllerClient) -> None:
    assert plc.set_calibration(JOINT_GRIPPER, Calibration()).error_id == ERR_OK
    assert plc.move_joints(0.0, 80.0, 90.0, wait=True).error_id == ERR_OK
    st = plc.move_joints_profile((30.0, 70.0, 100.0), 2, 30.0, 100.0)
    assert st.error_id == ERR_OK
    ticket = plc.last_ticket
    assert plc.set_gripper(80.0).error_id == ERR_OK
    m = plc.motion()
    assert m.ticket == ticket and m.busy
    assert plc.wait_motion(ticket).state == "done"
    assert plc.motion().out_deg == pytest.approx((30.0, 70.0, 100.0), abs=1e-3)
    wait_gripper_still(plc)
    assert plc.gripper().pulse_us == pytest.approx(1000.0 + 1000.0 * 0.8, abs=1e-3)
    # Relax relaxes it: pulse off, channel word full off (bit 12); it stays where it stood
    out = plc.gripper().out_deg
    assert plc.relax().error_id == ERR_OK
    plc.wait_scans(2)
    g = plc.gripper()
    assert g.pulse_us == 0.0 and plc.channel_words()[5] == 0x1000 and g.out_deg == out
    # an arm move after Relax leaves the gripper limp; SetGripper wakes it where it stands
    assert plc.move_joints(0.0, 80.0, 90.0, wait=True).error_id == ERR_OK
    assert plc.gripper().pulse_us == 0.0
    assert plc.relax().error_id == ERR_OK  # leave channel 5 off for the suites after this
