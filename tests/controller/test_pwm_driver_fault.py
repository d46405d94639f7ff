"""PwmDriverFault (%IX0.1): the I/O layer's word that the PCA9685 may not have taken the last
scan's channel words (an I2C error, an invalid word; on OpenPLC v4 also a servo the plugin
holds relaxed). The controller holds the arm on it (Controller.st, PWM DRIVER FAULT): the
running motion ends with MotionErrorId 111, every channel's pulse stands still where it is,
what would move is answered 111 DriverFault to its own client, and after the fault nothing
moves until a new command, which starts from the held pulse at rest.

The bit is set straight in the process image before a scan (the scan reads it as it reads
the PSM's word), so a fault can rise in any scan: with a command, for one scan only, every
other scan. The chip is modelled as the v3 PSM drives it (plc_project/psm/arm_io_psm.py): the
PSM cycle after scan k either writes scan k's words (the bit then reads FALSE at scan k + 1)
or fails and the chip keeps what it had (the bit reads TRUE at scan k + 1); after a failure
the PSM re-initialises and writes every channel's present word. The servo sees the chip's
pulses: no step between two of them may exceed the output stage's step limit."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest
from fast_plc import FastPlc
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule
from stepped_controller import (
    ARM_CHANNELS,
    CHANNELS,
    FOLLOW_IMU,
    HELLO,
    INIT_PWM,
    JOG_START,
    JOG_STOP,
    JOG_UPDATE,
    JOG_WRIST,
    LUT_MOVE_XYZ,
    MOVE_JOINTS,
    MOVE_JOINTS_PROFILE,
    MOVE_LINEAR,
    MOVE_TOOL_ANGLES,
    MOVE_XYZ,
    OK,
    RELAX,
    SET_GRIPPER,
    STOP,
    AnswerMonitor,
    Client,
    OutputMonitor,
    SteppedController,
    load_controller,
)

from armbench.controller_client import ERR_DRIVER_FAULT, ERR_OK, ArmControllerClient
from armbench.softplc.loader import LoadedProgram

DRIVER_FAULT = 111  # ArmControllerErrors.DriverFault (Controller.st RESULT CODES)
NOT_MOTION_OWNER = 108
FAULT_BIT = 1  # %IX0.1 in the image's discrete inputs (one byte per bit)


@pytest.fixture(scope="module")
def program() -> LoadedProgram:
    return load_controller()


@dataclass
class Bench:
    ctl: SteppedController
    out: OutputMonitor
    answers: AnswerMonitor
    a: Client
    b: Client

    def fault(self, on: bool) -> None:
        """The I/O layer's bit as the next scan reads it."""
        self.ctl.program.image.ix[FAULT_BIT] = int(on)

    def moving(self) -> list[bool]:
        return [s != 0.0 for s in self.out.steps]

    def quiet(self) -> None:
        assert not self.out.violations, self.out.failure()
        assert not self.answers.violations, self.answers.violations[:3]


@pytest.fixture
def bench(program: LoadedProgram) -> Iterator[Bench]:
    ctl = SteppedController(program)
    out, answers = OutputMonitor(), AnswerMonitor()
    ctl.observers += [out, answers]
    a, b = Client(ctl, 1, 1111), Client(ctl, 2, 2222)
    assert a.command(HELLO) == OK and b.command(HELLO) == OK
    bench = Bench(ctl, out, answers, a, b)
    yield bench
    bench.fault(False)


def motion_status(ctl: SteppedController) -> tuple[int, int, int]:
    return (int(ctl.read("MOTIONBUSY")), int(ctl.read("MOTIONERROR")),
            int(ctl.read("MOTIONERRORID")))


def at_rest_pose(bench: Bench) -> None:
    assert bench.a.command(MOVE_JOINTS, args=(0.0, 80.0, 60.0)) == OK
    bench.ctl.step(150)
    assert not any(bench.moving())


# each motion kind: its start command and the scans after which it moves at speed
MOTIONS = {
    "MoveJoints": (MOVE_JOINTS, 0, (40.0, 50.0, 90.0)),
    "MoveJointsProfile4": (MOVE_JOINTS_PROFILE, 4, (40.0, 50.0, 90.0, 100.0, 700.0, 5000.0)),
    "MoveLinear": (MOVE_LINEAR, 0, (150.0, 20.0, 120.0, 60.0, 400.0, 1.0)),
    "JogStart": (JOG_START, 0, (1.0, 0.0, 0.0, 60.0, 400.0)),
    "JogWrist": (JOG_WRIST, 2, (0.0, 40.0, 40.0, 300.0)),
    "SetGripper": (SET_GRIPPER, 0, (100.0,)),
}


@pytest.mark.parametrize("kind", list(MOTIONS))
def test_a_fault_freezes_every_motion_kind_and_nothing_moves_after_it(bench: Bench,
                                                                       kind: str) -> None:
    ctl = bench.ctl
    at_rest_pose(bench)
    if kind == "SetGripper":
        assert bench.a.command(SET_GRIPPER, args=(0.0,)) == OK
        ctl.step(200)
    code, int1, args = MOTIONS[kind]
    assert bench.a.command(code, int1=int1, args=args) == OK, ctl.scan_commands()
    ctl.step(15)
    assert any(bench.moving()), f"{kind} does not move: {ctl.pulses()}"
    before = ctl.pulses()
    edges = int(ctl.read("DRIVERFAULTS"))
    bench.fault(True)
    ctl.step()
    # the fault's scan: every channel stands where the last scan left it
    assert ctl.pulses() == before
    assert int(ctl.read("DRIVERFAULTHELD")) == 1 and int(ctl.read("DRIVERFAULTS")) == edges + 1
    if kind != "SetGripper":  # the gripper is no motion: its channel just stands
        assert motion_status(ctl) == (0, 1, DRIVER_FAULT)
    ctl.step(30)
    assert ctl.pulses() == before
    # what would move is refused to its own client; Stop and Relax never are
    assert bench.b.command(MOVE_JOINTS, args=(-20.0, 70.0, 65.0)) == DRIVER_FAULT
    assert bench.a.command(code, int1=int1, args=args) == DRIVER_FAULT
    assert bench.b.command(STOP) == OK
    ctl.step(5)
    assert ctl.pulses() == before
    bench.fault(False)
    ctl.step(150)
    assert ctl.pulses() == before, "something moved after the fault without a command"
    assert int(ctl.read("DRIVERFAULTHELD")) == 0
    # the next command starts where the stage stands, at rest, within the limits
    assert bench.b.command(MOVE_JOINTS, args=(-20.0, 70.0, 65.0)) == OK
    assert bench.a.command(SET_GRIPPER, args=(50.0,)) == OK
    ctl.step(300)
    bench.quiet()
    assert motion_status(ctl)[:2] == (0, 0)


def test_a_one_scan_fault_ends_the_motion_for_good(bench: Bench) -> None:
    ctl = bench.ctl
    assert bench.a.command(MOVE_JOINTS, args=(40.0, 50.0, 90.0)) == OK
    ctl.step(20)
    before = ctl.pulses()
    bench.fault(True)
    ctl.step()
    bench.fault(False)
    assert ctl.pulses() == before
    ctl.step(200)
    assert ctl.pulses() == before
    assert motion_status(ctl) == (0, 1, DRIVER_FAULT)
    assert int(ctl.read("DRIVERFAULTS")) == 1
    bench.quiet()


def test_a_command_in_the_scan_the_fault_rises_is_refused(bench: Bench) -> None:
    ctl = bench.ctl
    assert bench.a.command(JOG_START, args=(1.0, 0.0, 0.0, 60.0, 400.0)) == OK
    ctl.step(20)
    before = ctl.pulses()
    move = bench.b.send(MOVE_JOINTS, args=(-30.0, 70.0, 65.0))
    update = bench.a.send(JOG_UPDATE, args=(-1.0, 0.0, 0.0))
    bench.fault(True)
    ctl.step()
    assert ctl.result_of(move) == DRIVER_FAULT and ctl.result_of(update) == DRIVER_FAULT
    assert ctl.pulses() == before
    assert motion_status(ctl) == (0, 1, DRIVER_FAULT)
    assert bench.a.command(JOG_STOP) == NOT_MOTION_OWNER  # the fault ended the jog already
    assert ctl.pulses() == before
    bench.fault(False)
    ctl.step(100)
    assert ctl.pulses() == before
    bench.quiet()


def test_every_command_that_moves_is_refused_while_the_fault_stands(bench: Bench) -> None:
    ctl = bench.ctl
    at_rest_pose(bench)
    before = ctl.pulses()
    bench.fault(True)
    refused = [(MOVE_XYZ, 0, (150.0, 0.0, 100.0)), (MOVE_JOINTS, 0, (10.0, 70.0, 65.0)),
               (MOVE_JOINTS_PROFILE, 2, (10.0, 70.0, 65.0, 50.0, 300.0, 0.0)),
               (MOVE_LINEAR, 0, (150.0, 20.0, 120.0, 60.0, 400.0, 1.0)),
               (JOG_START, 0, (1.0, 0.0, 0.0, 60.0, 400.0)), (JOG_UPDATE, 0, (1.0, 0.0, 0.0)),
               (LUT_MOVE_XYZ, 0, (150.0, 0.0, 100.0)),
               (MOVE_TOOL_ANGLES, 0, (150.0, 0.0, 100.0, 0.0, 0.0)),
               (JOG_WRIST, 2, (0.0, 40.0, 40.0, 300.0)), (SET_GRIPPER, 0, (30.0,)),
               (FOLLOW_IMU, 1, ())]
    for i, (code, int1, args) in enumerate(refused):
        client = bench.a if i % 2 else bench.b
        assert client.command(code, int1=int1, args=args) == DRIVER_FAULT, code
    assert ctl.pulses() == before
    # Relax is never refused: the servos go limp; a re-power later starts where they were
    assert bench.a.command(RELAX) == OK
    assert ctl.pulses()[:ARM_CHANNELS] == (0.0,) * ARM_CHANNELS
    assert bench.b.command(MOVE_JOINTS, args=(10.0, 70.0, 65.0)) == DRIVER_FAULT
    bench.fault(False)
    ctl.step(50)
    assert ctl.pulses()[:ARM_CHANNELS] == (0.0,) * ARM_CHANNELS
    assert bench.b.command(MOVE_JOINTS, args=(10.0, 70.0, 65.0)) == OK
    ctl.step(200)
    bench.quiet()


def test_a_fault_while_relaxed_leaves_no_catch_up(bench: Bench) -> None:
    ctl = bench.ctl
    assert bench.a.command(MOVE_JOINTS, args=(40.0, 50.0, 100.0)) == OK
    ctl.step(20)
    assert bench.a.command(RELAX) == OK  # relaxed in the middle of a move
    ctl.step(5)
    bench.fault(True)
    ctl.step(20)
    assert bench.b.command(MOVE_JOINTS, args=(-10.0, 70.0, 65.0)) == DRIVER_FAULT
    assert bench.a.command(SET_GRIPPER, args=(20.0,)) == DRIVER_FAULT
    assert ctl.pulses() == (0.0,) * len(CHANNELS)
    bench.fault(False)
    ctl.step(20)
    assert ctl.pulses() == (0.0,) * len(CHANNELS)
    # powered again at the pulse it was relaxed at (the monitor's re-power rule), at rest
    assert bench.b.command(MOVE_JOINTS, args=(-10.0, 70.0, 65.0)) == OK
    ctl.step(300)
    bench.quiet()
    assert int(ctl.read("DRIVERFAULTS")) == 1


def test_a_fault_at_power_up_refuses_motions_but_not_init_pwm(bench: Bench) -> None:
    ctl = bench.ctl
    ctl.reset()
    out = OutputMonitor()
    ctl.observers.append(out)
    a = Client(ctl, 3, 3333)
    bench.fault(True)
    assert a.command(HELLO) == OK
    assert a.command(MOVE_JOINTS, args=(0.0, 70.0, 65.0)) == DRIVER_FAULT
    a.send(INIT_PWM)
    for _ in range(20):
        ctl.step()
        if a.result() is not None:
            break
    assert a.result() == OK
    assert ctl.pulses() == (0.0,) * len(CHANNELS)
    assert int(ctl.read("DRIVERFAULTS")) == 1
    bench.fault(False)
    assert a.command(MOVE_JOINTS, args=(10.0, 70.0, 65.0)) == OK
    ctl.step(200)
    assert not out.violations, out.failure()


def test_a_flapping_fault_with_two_clients(bench: Bench) -> None:
    ctl = bench.ctl
    at_rest_pose(bench)
    sent = answered = 0
    for k in range(120):
        bench.fault(k % 3 == 1 or k % 7 == 0)
        target = (-30.0 + k % 60, 60.0 + k % 20, 70.0)
        bench.a.send(MOVE_JOINTS, args=target)
        if k % 2:
            bench.b.send(STOP)
        sent += 1 + k % 2
        ctl.step()
        answered += len(ctl.answered)
        for client in (bench.a, bench.b):
            result = client.result()
            assert result in (OK, DRIVER_FAULT, None)
    assert answered == sent
    bench.fault(False)
    ctl.step(300)
    bench.quiet()


# ------------------------------------------------------------------------------------------
# The v3 PSM's chip model and a stateful interleaving of faults and commands
# ------------------------------------------------------------------------------------------

@dataclass
class ChipModel:
    """The pulses the PCA9685 holds: the PSM cycle after a scan writes that scan's pulses,
    unless it fails (the fault the next scan reads); the servo follows the chip."""

    held: list[float] = field(default_factory=lambda: [0.0] * len(CHANNELS))
    last_on: list[float | None] = field(default_factory=lambda: [None] * len(CHANNELS))
    problems: list[str] = field(default_factory=list)

    def cycle(self, ctl: SteppedController, out: OutputMonitor, ok: bool) -> None:
        if not ok:
            return
        for c, p in enumerate(ctl.pulses()):
            vstep = out.limits(ctl, c)[0]
            ref = self.held[c] if self.held[c] != 0.0 else self.last_on[c]
            if p != 0.0 and ref is not None and abs(p - ref) > vstep * (1 + 1e-5) + 1e-3:
                self.problems.append(f"scan {ctl.scan} {CHANNELS[c]}: the servo's pulse "
                                     f"{ref:.3f} -> {p:.3f} us, limit {vstep:.3f} us")
            if p != 0.0:
                self.last_on[c] = p
            self.held[c] = p


COMMANDS = st.one_of(
    st.tuples(st.just(MOVE_JOINTS), st.just(0),
              st.tuples(st.floats(-50, 50), st.floats(40, 110), st.floats(30, 110))),
    st.tuples(st.just(MOVE_JOINTS_PROFILE), st.sampled_from([2, 4]),
              st.tuples(st.floats(-50, 50), st.floats(40, 110), st.floats(30, 110),
                        st.just(120.0), st.just(800.0), st.just(8000.0))),
    st.tuples(st.just(JOG_START), st.just(0),
              st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.just(80.0),
                        st.just(500.0))),
    st.tuples(st.just(SET_GRIPPER), st.just(0), st.tuples(st.floats(0, 100))),
    st.tuples(st.sampled_from([STOP, RELAX, JOG_STOP]), st.just(0), st.just(())),
)


class FaultsAndCommands(RuleBasedStateMachine):
    """Faults of any length interleaved with commands from two clients: the servo's pulse (the
    chip's, through the PSM model) never steps beyond the stage's limit, and every command is
    answered exactly once, in the scan it arrived, to its own client."""

    program: LoadedProgram | None = None

    def __init__(self) -> None:
        super().__init__()
        assert self.program is not None
        self.ctl = SteppedController(self.program)
        self.out, self.answers = OutputMonitor(), AnswerMonitor()
        self.ctl.observers += [self.out, self.answers]
        self.clients = [Client(self.ctl, 1, 51), Client(self.ctl, 2, 52)]
        for c in self.clients:
            assert c.command(HELLO) == OK
        self.chip = ChipModel()
        self.next_ok = True
        self.answered_before = int(self.ctl.read("COMMANDSANSWERED"))

    def _scan(self) -> None:
        # the PSM cycle after the last scan: its outcome is the bit this scan reads
        self.chip.cycle(self.ctl, self.out, self.next_ok)
        self.ctl.program.image.ix[FAULT_BIT] = int(not self.next_ok)
        sent = list(self.ctl.pending)
        self.ctl.step()
        got = {a.block.mailbox: a for a in self.ctl.answered}
        for blk in sent:
            assert blk.mailbox in got and got[blk.mailbox].block is blk, blk.describe()
        now = int(self.ctl.read("COMMANDSANSWERED"))
        assert now - self.answered_before == len(self.ctl.answered)
        self.answered_before = now

    @rule(ok=st.booleans())
    def psm_cycle(self, ok: bool) -> None:
        self.next_ok = ok

    @rule(which=st.integers(0, 1), cmd=COMMANDS, both=st.booleans())
    def command(self, which: int, cmd: tuple[int, int, tuple[float, ...]], both: bool) -> None:
        code, int1, args = cmd
        self.clients[which].send(code, int1=int1, args=args)
        if both:
            self.clients[1 - which].send(MOVE_JOINTS, args=(0.0, 70.0, 65.0))
        self._scan()

    @rule(n=st.integers(1, 40))
    def scans(self, n: int) -> None:
        for _ in range(n):
            self._scan()

    @invariant()
    def servo_never_jumps(self) -> None:
        assert not self.chip.problems, self.chip.problems[:3]
        assert not self.answers.violations, self.answers.violations[:3]


def test_faults_interleaved_with_commands(program: LoadedProgram) -> None:
    FaultsAndCommands.program = program
    machine = FaultsAndCommands.TestCase
    machine.settings = settings(max_examples=40, stateful_step_count=30, deadline=None,
                                suppress_health_check=[HealthCheck.too_slow])
    machine().runTest()


def test_a_client_over_modbus_sees_the_fault(fast_controller: FastPlc,
                                             ctl: ArmControllerClient) -> None:
    """The client library's view over the fast PLC's Modbus server: the command's Result and
    Status.driver_fault/driver_faults."""
    image, lock = fast_controller.plc.image, fast_controller.plc.lock
    before = ctl.status().driver_faults
    assert ctl.move_joints(0.0, 80.0, 60.0).error_id == ERR_OK
    with lock:
        image.ix[FAULT_BIT] = 1
    try:
        ctl.wait_scans(3)
        status = ctl.status()
        assert status.driver_fault and status.driver_faults == before + 1
        assert ctl.move_joints(10.0, 70.0, 65.0).error_id == ERR_DRIVER_FAULT
        assert not ctl.motion().busy
    finally:
        with lock:
            image.ix[FAULT_BIT] = 0
    ctl.wait_scans(3)
    assert not ctl.status().driver_fault
    assert ctl.move_joints(10.0, 70.0, 65.0, wait=True).error_id == ERR_OK
