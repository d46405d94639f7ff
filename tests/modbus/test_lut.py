"""The LUT variant over Modbus (LUT COMMANDS of plc_project/Controller.st: LutSolve,
LutMoveXyz, LutSolveBatch with InverseKinematikFixed): FK of the returned angles against the
commanded integer target, within the LUT's documented error. Runs against the soft PLC, or a
real PLC with ``--plc-host``/``--plc-port`` like the rest of tests/modbus.

References are independent of the PLC: the float64 DH-matrix forward kinematics and the
float64 geometric IK of :mod:`armbench.plant.arm`.

The documented error (st/KinematicsFixed.st ERROR BUDGET, docs/fixed-point.md): each joint
within 5.5E-3 deg of the exact IK of the same integer target. Turning one joint by d rad moves
the tool by at most d times its distance from that joint's axis, so the tool point of the
returned angles lies within d * (radius from the base axis + distance from the shoulder axis
+ forearm) of the target: :func:`position_bound`.
"""

from __future__ import annotations

import math
import struct
import time

import pytest
from motion_checks import angle_diff

from armbench.controller_client import (
    CMD_INIT_PWM,
    CMD_LUT_MOVE_XYZ,
    CMD_LUT_SOLVE,
    CMD_LUT_SOLVE_BATCH,
    ERR_BAD_COUNT,
    ERR_BUSY,
    ERR_JOINT_LIMIT,
    ERR_NOT_BATCH_OWNER,
    ERR_NOT_FINITE,
    ERR_SINGULAR,
    ERR_UNREACHABLE,
    LUT_MAX_MM100,
    ArmControllerClient,
    lut_target_mm,
)
from armbench.plant import arm

ANGLE_BOUND_DEG = 5.5e-3  # documented per-joint bound of InverseKinematikFixed
# ForwardKinematicFixed: <= 1.1E-5 x (a3 + a4) from the sine table plus 0.005 mm rounding of
# each coordinate (KinematicsFixed.st), as a distance over three coordinates
GEOM = arm.DEFAULT_GEOMETRY
ECHO_BOUND_MM = 1.1e-5 * (GEOM.a3 + GEOM.a4) * math.sqrt(3.0) + 0.005 * math.sqrt(3.0)


def position_bound(p_mm: tuple[float, float, float]) -> float:
    """Largest tool displacement (mm) that per-joint errors of ANGLE_BOUND_DEG can cause."""
    radius = math.hypot(p_mm[0], p_mm[1])
    shoulder = arm.shoulder_distance(*p_mm)
    return math.radians(ANGLE_BOUND_DEG) * (radius + shoulder + GEOM.a4)


def workspace_targets(n: int) -> list[tuple[int, int, int]]:
    """n integer targets (0.01 mm) spread over the reach shell, front and back side,
    1 mm away from the shells (a quasi-random sequence: the same points on every run); both
    elbow solutions exist for each."""
    low, high = arm.reach_limits()
    pts: list[tuple[int, int, int]] = []
    i = 0
    while len(pts) < n:
        i += 1
        u, v, w = (i * 0.618034) % 1.0, (i * 0.754878) % 1.0, (i * 0.569840) % 1.0
        cp = low + 1.0 + (high - low - 2.0) * u
        phi = -math.pi + 2.0 * math.pi * v
        base = -math.pi + 2.0 * math.pi * w
        radial = GEOM.a2 + cp * math.cos(phi)
        z = GEOM.a1 + cp * math.sin(phi)
        if abs(radial) < 5.0:
            continue  # next to the base axis the Base angle is ill-conditioned
        p = (round(100.0 * radial * math.cos(base)), round(100.0 * radial * math.sin(base)),
             round(100.0 * z))
        mm = tuple(c / 100.0 for c in p)
        if not arm.is_reachable(mm[0], mm[1], mm[2], margin=0.5):
            continue
        pts.append(p)
    return pts


def check_point(target_mm100: tuple[int, int, int], angles_deg100: tuple[int, int, int],
                echo_mm100: tuple[int, int, int], elbow_up: bool) -> tuple[float, float]:
    """Assert the documented error for one solved point; return (FK error mm, angle error
    deg) for the summary."""
    p = (target_mm100[0] / 100.0, target_mm100[1] / 100.0, target_mm100[2] / 100.0)
    q = tuple(a / 100.0 for a in angles_deg100)
    ref = arm.inverse(*p, elbow_up=elbow_up)
    worst_angle = max(angle_diff(q[j], ref[j]) for j in range(3))
    assert worst_angle <= ANGLE_BOUND_DEG, (target_mm100, angles_deg100, ref)
    fk = arm.forward(*q)
    err = math.dist(fk, p)
    assert err <= position_bound(p), (target_mm100, angles_deg100, err)
    echo = tuple(c / 100.0 for c in echo_mm100)
    assert math.dist(echo, fk) <= ECHO_BOUND_MM, (target_mm100, echo, fk)
    return err, worst_angle


def test_target_carrier_is_exact_over_the_whole_range() -> None:
    # what the PLC computes: REAL_TO_DINT(REAL(value / 100) * 100.0), float32 throughout
    def plc_side(k: int) -> int:
        f = struct.unpack(">f", struct.pack(">f", lut_target_mm(k)))[0]
        prod = struct.unpack(">f", struct.pack(">f", f * 100.0))[0]
        return round(prod)  # round half to even, as REAL_TO_DINT

    for k in [*range(-2000, 2001), *range(LUT_MAX_MM100 - 3000, LUT_MAX_MM100 + 1),
              *range(-LUT_MAX_MM100, -LUT_MAX_MM100 + 3000), 123457, -987653, 999999]:
        assert plc_side(k) == k
    with pytest.raises(ValueError, match="outside"):
        lut_target_mm(LUT_MAX_MM100 + 1)
    with pytest.raises(TypeError, match="integers"):
        lut_target_mm(1.5)  # type: ignore[arg-type]


@pytest.mark.parametrize("elbow_up", [True, False])
def test_lut_solve_round_trip(plc: ArmControllerClient, elbow_up: bool) -> None:
    worst_fk = worst_angle = 0.0
    solves_before = plc.lut_result().solves
    targets = workspace_targets(40)
    for t in targets:
        res = plc.lut_solve(*t, elbow_down=not elbow_up)
        assert res.error_id == 0, (t, res)
        assert res.session == plc.session
        assert res.target_mm100 == t  # the integer target reached the IK unchanged
        fk, ang = check_point(t, res.angles_deg100, res.echo_mm100, elbow_up)
        worst_fk, worst_angle = max(worst_fk, fk), max(worst_angle, ang)
    # other clients may solve at the same time on a shared PLC: at least ours were counted
    assert (plc.lut_result().solves - solves_before) & 0xFFFFFFFF >= len(targets)
    print(f"\nLutSolve elbow {'up' if elbow_up else 'down'}: {len(targets)} points, "
          f"max |FK(q) - p| {worst_fk:.4f} mm, max joint error {worst_angle:.5f} deg")


@pytest.mark.parametrize("elbow_up", [True, False])
def test_lut_batch_round_trip(plc: ArmControllerClient, elbow_up: bool) -> None:
    targets = workspace_targets(4 * plc.batch_max + 5)  # several chunks, one partial
    results = plc.lut_solve_batch(targets, elbow_down=not elbow_up)
    assert len(results) == len(targets)
    worst_fk = worst_angle = 0.0
    for t, r in zip(targets, results, strict=True):
        assert r.error_id == 0, (t, r)
        fk, ang = check_point(t, r.angles_deg100, r.echo_mm100, elbow_up)
        worst_fk, worst_angle = max(worst_fk, fk), max(worst_angle, ang)
    assert plc.status().batch_failures == 0
    print(f"\nLutSolveBatch elbow {'up' if elbow_up else 'down'}: {len(targets)} points, "
          f"max |FK(q) - p| {worst_fk:.4f} mm, max joint error {worst_angle:.5f} deg")


def test_lut_batch_counts_failures_per_point(plc: ArmControllerClient) -> None:
    good = workspace_targets(2)
    far = (40000, 0, 10000)  # 400 mm out: beyond the 270 mm reach
    axis = (0, 0, 15000)  # on the base axis
    results = plc.lut_solve_batch([good[0], far, axis, good[1]])
    assert [r.error_id for r in results] == [0, ERR_UNREACHABLE, ERR_SINGULAR, 0]
    assert results[1].angles_deg100 == (0, 0, 0)
    st = plc.status()
    assert (st.batch_count, st.batch_failures) == (4, 2)


def test_lut_solve_rejects_bad_targets(plc: ArmControllerClient) -> None:
    assert plc.lut_solve(40000, 0, 10000).error_id == ERR_UNREACHABLE
    res = plc.lut_solve(0, 0, 15000)
    assert res.error_id == ERR_SINGULAR
    assert res.angles_deg100 == (0, 0, 0) and res.echo_mm100 == (0, 0, 0)
    # what the client refuses to send, a plain Modbus client can: the PLC judges it too
    st = plc.command(CMD_LUT_SOLVE, args=(float("nan"), 100.0, 100.0))
    assert st.error_id == ERR_NOT_FINITE
    st = plc.command(CMD_LUT_SOLVE, args=(20000.0, 0.0, 0.0))  # 20 m: beyond the integer range
    assert st.error_id == ERR_UNREACHABLE


def test_lut_batch_needs_the_buffer_and_a_count(plc: ArmControllerClient) -> None:
    st = plc.command(CMD_LUT_SOLVE_BATCH, ints=(0, 1))
    assert st.error_id == ERR_NOT_BATCH_OWNER
    with plc.batch_buffer():
        for count in (0, plc.batch_max + 1):
            st = plc.command(CMD_LUT_SOLVE_BATCH, ints=(0, count))
            assert st.error_id == ERR_BAD_COUNT


def test_lut_move_xyz_moves_the_arm(plc: ArmControllerClient) -> None:
    t = (15000, 3000, 12000)
    res = plc.lut_move_xyz(*t)
    assert res.error_id == 0, res
    st = plc.status()
    # the servos follow the LUT's angles (0.01 deg steps, published as REAL deg)
    for got, want in zip(st.joints_deg, res.angles_deg100, strict=True):
        assert got == pytest.approx(want / 100.0, abs=1e-4)
    check_point(t, res.angles_deg100, res.echo_mm100, True)
    # MoveXyz (float IK) to the same point lands within the LUT's error of it
    st_float = plc.move_xyz(t[0] / 100.0, t[1] / 100.0, t[2] / 100.0)
    assert st_float.error_id == 0
    for a, b in zip(st_float.joints_deg, res.angles_deg100, strict=True):
        assert angle_diff(a, b / 100.0) <= ANGLE_BOUND_DEG + 1e-3
    # a reachable point the servos cannot take: elbow down folds past their travel
    before = plc.status().joints_deg
    res = plc.lut_move_xyz(*t, elbow_down=True)
    assert res.error_id == ERR_JOINT_LIMIT
    assert plc.status().joints_deg == before


def test_lut_move_is_busy_while_init_pwm_runs(plc_address: tuple[str, int],
                                              plc_flavor: str) -> None:
    from armbench.softplc.modbus_client import PlcClient

    host, port = plc_address
    with PlcClient(host, port) as c1, PlcClient(host, port) as c2, \
            PlcClient(host, port) as c3, ArmControllerClient(c1, flavor=plc_flavor) as a, \
            ArmControllerClient(c2, retry_busy=False, flavor=plc_flavor) as b, \
            ArmControllerClient(c3, flavor=plc_flavor) as c:
        b.hello()
        c.hello()
        # InitPwm runs for several scans (one init frame per scan); a LutMoveXyz sent once
        # it runs is answered Busy, a LutSolve (no servo) is run. Under heavy load the
        # writes may come after the end of InitPwm: try a few times.
        results: list[int] = []
        for _ in range(5):
            init = a.submit(CMD_INIT_PWM)
            while a.status().busy_mailbox != init.mailbox and a.answer(init.mailbox).ack_seq \
                    != init.seq:
                time.sleep(0.001)  # until the PLC has taken InitPwm (or already finished it)
            move = b.submit(CMD_LUT_MOVE_XYZ, args=(150.0, 30.0, 120.0))
            solve = c.submit(CMD_LUT_SOLVE, args=(150.0, 30.0, 120.0))
            results = [a.wait(init), b.wait(move), c.wait(solve)]
            if results[1] == ERR_BUSY:
                break
        assert results == [0, ERR_BUSY, 0]



def test_lut_batch_publishes_whole_hundredths_the_float_batch_does_not(
        plc: ArmControllerClient) -> None:
    """The LUT path really ran: its angles are whole 0.01 deg steps (as REALs: float32 of
    k / 100), the float IK's are not; both solve the same targets within the LUT's error
    (where SolveBatch's servo check lets a point through)."""
    targets = workspace_targets(plc.batch_max)
    mm = [(x / 100.0, y / 100.0, z / 100.0) for x, y, z in targets]

    def f32(v: float) -> float:
        return float(struct.unpack(">f", struct.pack(">f", v))[0])

    with plc.batch_buffer():
        lut = plc.solve_batch(mm, code=CMD_LUT_SOLVE_BATCH)
        flt = plc.solve_batch(mm)
    whole_lut = whole_flt = compared = 0
    for a, b in zip(lut, flt, strict=True):
        assert a.error_id == 0
        for x in a.joints_deg:
            whole_lut += x == f32(round(x * 100.0) / 100.0)
        if b.error_id != 0:
            continue  # SolveBatch also checks the servos' travel (101), the LUT batch not
        compared += 1
        for x, y in zip(a.joints_deg, b.joints_deg, strict=True):
            whole_flt += y == f32(round(y * 100.0) / 100.0)
            assert angle_diff(x, y) <= ANGLE_BOUND_DEG + 1e-3
    assert whole_lut == 3 * len(targets)
    assert compared >= 5
    assert whole_flt < compared
