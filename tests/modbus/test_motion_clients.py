"""Several clients and one motion group over Modbus: a motion aborted by another client is
reported as such (the motion registers name who started the current one), Stop and Relax
end a motion from anywhere, and hostile clients -- random jumps, reversals, NaN, bad
parameters, limit changes, jogs they abandon -- never make a servo step beyond its slew
limit (checked on consecutive recorded outputs)."""

from __future__ import annotations

import math
import random
import threading
import time
from collections.abc import Callable

from motion_checks import assert_slew_limited, worst_slew

from armbench.controller_client import (
    CMD_RELAX,
    ArmControllerClient,
    HandshakeError,
    MotionRecorder,
)
from armbench.softplc.modbus_client import ModbusIoError, PlcClient


def test_abort_by_another_client_is_reported(plc: ArmControllerClient,
                                             plc_address: tuple[str, int],
                                             motion_recorder: Callable[[], MotionRecorder]
                                             ) -> None:
    assert plc.move_joints(-40.0, 60.0, 60.0, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    assert plc.move_joints_profile((40.0, 110.0, 100.0), 2, 60.0, 300.0).error_id == 0
    mine = plc.last_ticket
    plc.wait_scans(30)
    with PlcClient(*plc_address) as modbus, ArmControllerClient(modbus, flavor=plc.flavor) as other:
        assert other.move_xyz(150.0, 20.0, 110.0).error_id == 0
        theirs = other.last_ticket
        outcome = plc.wait_motion(mine)
        assert outcome.state == "superseded" and outcome.by == theirs
        assert other.wait_motion(theirs).state == "done"
        other.wait_scans(5)
    run = rec.stop()
    assert {s.ticket for s in run.samples} >= {mine, theirs}
    assert_slew_limited(run)  # the takeover blends: no jump


def test_stop_from_anyone_brakes_smoothly(plc: ArmControllerClient,
                                          plc_address: tuple[str, int],
                                          motion_recorder: Callable[[], MotionRecorder]) -> None:
    assert plc.move_joints(-40.0, 60.0, 60.0, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    assert plc.move_joints_profile((40.0, 110.0, 100.0), 1, 120.0, 800.0).error_id == 0
    mine = plc.last_ticket
    plc.wait_scans(25)
    with PlcClient(*plc_address) as modbus, ArmControllerClient(modbus, flavor=plc.flavor) as other:
        assert other.stop(deceleration=500.0).error_id == 0
        assert plc.wait_motion(mine).state == "superseded"
        assert other.wait_motion().state == "done"
        other.wait_scans(5)
    run = rec.stop()
    assert run.samples[-1].out_vel == (0.0, 0.0, 0.0)
    assert run.samples[-1].out_deg[0] < 40.0  # stopped on the way
    assert_slew_limited(run)


def test_relax_ends_the_motion(plc: ArmControllerClient) -> None:
    assert plc.move_joints(-40.0, 60.0, 60.0, wait=True).error_id == 0
    assert plc.move_joints_profile((40.0, 110.0, 100.0), 2, 60.0, 300.0).error_id == 0
    plc.wait_scans(10)
    assert plc.command(CMD_RELAX).error_id == 0
    outcome = plc.wait_motion()
    assert outcome.state == "aborted"
    assert plc.status().pulses_us == (0.0, 0.0, 0.0)
    # the next motion starts where the output stage stands, smoothly
    assert plc.move_joints(0.0, 70.0, 65.0, wait=True).error_id == 0


def _hostile(address: tuple[str, int], flavor: str, seed: int, seconds: float,
             errors: list[str]) -> None:
    rnd = random.Random(seed)
    nasty = [math.nan, math.inf, -math.inf, 1e30, -1e30, -5.0, 0.0]
    t_end = time.monotonic() + seconds
    try:
        with PlcClient(*address) as modbus, \
                ArmControllerClient(modbus, timeout_s=10.0, flavor=flavor) as c:
            while time.monotonic() < t_end:
                k = rnd.randrange(9)
                if k == 0:
                    c.move_joints(rnd.uniform(-60, 60), rnd.uniform(10, 130), rnd.uniform(5, 125))
                elif k == 1:
                    c.move_xyz(rnd.uniform(100, 200), rnd.uniform(-80, 80), rnd.uniform(60, 160))
                elif k == 2:
                    v = rnd.choice([rnd.uniform(1, 300), rnd.choice(nasty)])
                    c.move_joints_profile((rnd.uniform(-60, 60), rnd.uniform(10, 130),
                                           rnd.uniform(5, 125)), rnd.randrange(-1, 5), v,
                                          rnd.uniform(-10, 3000), rnd.uniform(0, 1e5))
                elif k == 3:
                    c.move_linear((rnd.uniform(100, 200), rnd.uniform(-80, 80),
                                   rnd.uniform(60, 160)), rnd.uniform(-10, 400),
                                  rnd.uniform(1, 3000), rnd.choice([0.5, 2.0, math.nan]),
                                  rnd.randrange(-1, 4))
                elif k == 4:
                    c.jog_start((rnd.uniform(-2, 2), rnd.choice([rnd.uniform(-1, 1), math.nan]),
                                 rnd.uniform(-1, 1)), rnd.uniform(-5, 200), rnd.uniform(1, 2000))
                elif k == 5:
                    c.jog_update((rnd.uniform(-1, 1), rnd.uniform(-1, 1), rnd.uniform(-1, 1)))
                elif k == 6:
                    c.stop(rnd.choice([0.0, rnd.uniform(1, 5000), math.nan]))
                elif k == 7:
                    c.set_motion_limits(rnd.randrange(3), rnd.uniform(20, 200),
                                        rnd.uniform(200, 2000))
                else:  # reversal: full travel back and forth, twice in a row
                    for base in (-55.0, 55.0):
                        c.move_joints(base, 70.0, 65.0)
                time.sleep(rnd.choice([0.0, 0.003, 0.02]))
    except (HandshakeError, ModbusIoError) as exc:
        errors.append(f"client {seed}: {exc}")


def test_hostile_clients_never_exceed_the_slew_limit(
        plc: ArmControllerClient, plc_address: tuple[str, int],
        motion_recorder: Callable[[], MotionRecorder]) -> None:
    rec = motion_recorder()
    rec.start()
    errors: list[str] = []
    threads = [threading.Thread(target=_hostile,
                                args=(plc_address, plc.flavor.name, seed, 6.0, errors))
               for seed in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60.0)
    try:
        assert plc.stop().error_id == 0
        plc.wait_motion(timeout_s=20.0)
        plc.wait_scans(10)
    finally:
        for joint in range(3):  # the defaults again, for the suites that follow
            assert plc.set_motion_limits(joint, 150.0, 1000.0).error_id == 0
    run = rec.stop()
    assert errors == []
    step, acc = worst_slew(run)
    print(f"\nhostile: {len(run.samples)} scans sampled, {run.missed_scans} missed, "
          f"worst step {step:.3f} x limit, worst speed change {acc:.3f} x limit")
    assert sum(1 for _ in run.triples()) > 100
    assert_slew_limited(run)
    assert all(math.isfinite(v) for s in run.samples for v in (*s.out_deg, *s.out_vel))
