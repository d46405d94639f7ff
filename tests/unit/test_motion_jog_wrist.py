"""MotionJogWrist (st/MotionJogWrist.st): roll/pitch jog of the 5-axis arm's tool, flange-fixed
and tool-tip-fixed, with its acceleration, joint limits and unreachable orientations.

References: a float64 numpy product of elementary transforms Rz(base) Tz(A1) Tx(A2)
Ry(-shoulder) Tx(A3) Ry(180 - elbow) Tx(A4) Ry(-wrist pitch) Rx(roll) Tx(tool) (the joint
conventions of st/Kinematics5Axis.st's header, written out independently of the ST), the reach
shell |A3 - A4| .. A3 + A4 around the shoulder, the group's limits and the rate limit itself.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import (
    BAD_GEOMETRY,
    BAD_JOINT_COUNT,
    BAD_PARAMETER,
    DT,
    NOT_FINITE,
    GroupSim,
    make_group,
)

from armbench.plant import arm
from five_axis_ref import fk5, tool_pitch

G = arm.DEFAULT_GEOMETRY
TOOL_MM = 60.0
GEO5 = {"Arm": G.as_st(), "ToolMm": TOOL_MM}
SPEED, ACC = 40.0, 200.0
NAN = float("nan")
# float32 IK on a ~300 mm arm: the tip held within this (mm) while the tool turns
TIP_TOL_MM = 0.02
Q0 = [15.0, 80.0, 100.0, -20.0, 10.0]  # deg, inside +/-170 everywhere


def fk(q: list[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flange point, tool frame 4x4), float64 (tests/five_axis_ref.py)."""
    flange, tool = fk5(q, G, TOOL_MM)
    return flange[:3, 3], tool


def tip(q: list[float] | np.ndarray) -> np.ndarray:
    return fk(q)[1][:3, 3]


def start(q: list[float] = Q0, **limits: float) -> GroupSim:
    return GroupSim(make_group([float(np.float32(v)) for v in q], joints=5, **limits))


def jog(pitch: float, roll: float, enable: bool = True, tip_fixed: bool = True,
        **change: Any) -> dict[str, Any]:
    return {"Enable": enable, "PitchRate": pitch, "RollRate": roll, "MaxSpeed": SPEED,
            "Acceleration": ACC, "TipFixed": tip_fixed, "Geometry": GEO5, "CycleTime": DT,
            **change}


def rates_ok(sim: GroupSim, cols: list[int], v0: float = 0.0) -> None:
    """The driven joints' speeds stay within the group limits, all finite."""
    pos = sim.pos()
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(sim.vel()))
    steps = np.abs(np.diff(pos, axis=0))
    assert np.max(steps[:, cols]) <= 120.0 * DT * (1 + 1e-4)


def test_tip_fixed_pitch_jog_keeps_the_tip_and_turns_the_tool(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJogWrist")
    t0, p0 = tip(sim.start), tool_pitch(sim.start)
    for _ in range(100):  # 1 s at +25 deg/s (ramp 0.125 s)
        sim.scan(fb, **jog(25.0, 0.0))
    assert fb.Busy and not fb.Error and not fb.AtLimit
    pos = sim.pos()
    drift = max(float(np.linalg.norm(tip(q) - t0)) for q in pos)
    print(f"\nMotionJogWrist tip-fixed, 25 deg/s for 1 s: worst tip drift {drift * 1e3:.2f} um")
    assert drift < TIP_TOL_MM, drift
    pitches = np.array([tool_pitch(q) for q in pos])
    # steady state: the tool pitch (reference FK) turns at the commanded rate
    rate = np.diff(pitches[20:]) / DT
    assert np.allclose(rate, 25.0, atol=0.05), rate
    # the ramp: 0 -> 25 deg/s at 200 deg/s^2 gives 25 - 25^2/(2*200) deg less than 1 s at speed
    expected = 25.0 * 1.0 - 25.0 ** 2 / (2 * ACC)
    assert pitches[-1] - p0 == pytest.approx(expected, abs=0.3)
    assert fb.ToolPitchDeg == pytest.approx(pitches[-1], abs=0.01)
    # the flange swung round the tip: chord 2 L sin(dp / 2) of the tool length L; no roll
    chord = float(np.linalg.norm(fk(pos[-1])[0] - fk(sim.start)[0]))
    assert chord == pytest.approx(2 * TOOL_MM * math.sin(math.radians(pitches[-1] - p0) / 2),
                                  abs=0.02)
    assert pos[-1][4] == pytest.approx(Q0[4], abs=1e-4)
    rates_ok(sim, [0, 1, 2, 3, 4])


def test_roll_jog_moves_only_the_roll_joint(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJogWrist")
    t0 = tip(sim.start)
    for _ in range(60):
        sim.scan(fb, **jog(0.0, -30.0))
    pos = sim.pos()
    assert np.abs(pos[:, :4] - np.array(sim.start[:4])).max() < 1e-3
    assert np.diff(pos[-10:, 4]) / DT == pytest.approx(-30.0, abs=0.05)
    assert max(float(np.linalg.norm(tip(q) - t0)) for q in pos) < TIP_TOL_MM


def test_flange_fixed_moves_only_the_wrist(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJogWrist")
    f0 = fk(sim.start)[0]
    for _ in range(80):
        sim.scan(fb, **jog(-20.0, 15.0, tip_fixed=False))
    pos = sim.pos()
    assert np.all(pos[:, :3] == np.array(sim.start[:3]))  # the arm stands: bit for bit
    assert max(float(np.linalg.norm(fk(q)[0] - f0)) for q in pos) < 1e-9
    assert np.diff(pos[-10:, 3]) / DT == pytest.approx(-20.0, abs=0.05)
    assert np.diff(pos[-10:, 4]) / DT == pytest.approx(15.0, abs=0.05)
    # the tool pitch turns at the wrist's rate (reference FK)
    p = [tool_pitch(q) for q in pos[-10:]]
    assert np.diff(p) / DT == pytest.approx(-20.0, abs=0.05)


def test_release_brakes_within_the_stopping_distance(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJogWrist")
    for _ in range(60):
        sim.scan(fb, **jog(30.0, 20.0))
    p_release = tool_pitch(sim.positions[-1])
    r_release = sim.positions[-1][4]
    v = math.hypot(30.0, 20.0)
    scans = 0
    while fb.Busy:
        sim.scan(fb, **jog(30.0, 20.0, enable=False))
        scans += 1
        assert scans < 200
    assert fb.Done and not fb.Error and sim.group["Owner"] == 0
    # braking along the rate vector at ACC: v^2 / (2 ACC) along it, in v / ACC (+1 scan)
    moved = math.hypot(tool_pitch(sim.positions[-1]) - p_release,
                       sim.positions[-1][4] - r_release)
    assert moved <= v * v / (2 * ACC) + v * DT + 1e-3
    assert scans <= math.ceil(v / (ACC * DT)) + 2
    assert all(abs(x) < 1e-9 for x in sim.group["Velocity"][:5])


def test_flange_fixed_stops_before_the_wrist_limit(st_module: Any) -> None:
    sim = start(lower=-170.0, upper=170.0)
    sim.group["Limits"]["UpperDeg"][3] = 30.0
    fb = st_module.new_fb("MotionJogWrist")
    at_limit = []
    for _ in range(300):
        sim.scan(fb, **jog(SPEED, 0.0, tip_fixed=False))
        at_limit.append(bool(fb.AtLimit))
    pos = sim.pos()
    assert fb.Busy and fb.AtLimit and not fb.Error
    assert pos[:, 3].max() <= 30.0 + 1e-4
    assert pos[-1, 3] > 30.0 - 1.0  # it got close, and rests there
    assert pos[-1, 3] == pos[-2, 3]
    first = at_limit.index(True)
    assert all(at_limit[first:])
    speed = np.abs(np.diff(pos[:, 3])) / DT
    assert np.all(np.diff(speed[first:]) <= 1e-3)  # once braking: never faster again
    wrist = np.concatenate([[sim.start[3]], pos[:, 3]])
    acc = np.abs(np.diff(np.concatenate([[0.0], np.diff(wrist) / DT]))) / DT
    assert acc.max() <= ACC * (1 + 1e-3) + 1e-2
    # a changed command (back off) releases it
    for _ in range(20):
        sim.scan(fb, **jog(-SPEED, 0.0, tip_fixed=False))
    assert not fb.AtLimit and sim.positions[-1][3] < 29.0


def test_tip_fixed_brakes_where_the_orientation_becomes_unreachable(st_module: Any) -> None:
    # the tip near the outer reach: pitching the tool up pulls the flange out of the shell
    q = [0.0, 40.0, 160.0, 10.0, 0.0]
    sim = start(q)
    fb = st_module.new_fb("MotionJogWrist")
    t0 = tip(sim.start)
    for _ in range(600):
        sim.scan(fb, **jog(-SPEED, 0.0))
    assert fb.Busy and fb.AtLimit and not fb.Error
    pos = sim.pos()
    low, high = G.a3 - G.a4, G.a3 + G.a4
    for qq in pos:
        f = fk(qq)[0]
        d = math.hypot(math.hypot(f[0], f[1]) - G.a2, f[2] - G.a1)
        assert abs(low) - 1e-3 <= d <= high + 1e-3
    drift = max(float(np.linalg.norm(tip(qq) - t0)) for qq in pos)
    print(f"\nMotionJogWrist at the reach shell: rests at tool pitch "
          f"{tool_pitch(pos[-1]):.2f} deg, tip drift {drift * 1e3:.2f} um")
    assert drift < TIP_TOL_MM
    assert np.all(pos[-1] == pos[-2])  # at rest, at the last reachable pose
    rates_ok(sim, [0, 1, 2, 3, 4])


def test_bad_rates_never_reach_the_group(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJogWrist")
    for _ in range(20):
        sim.scan(fb, **jog(10.0, 0.0))
    sim.scan(fb, **jog(NAN, 5.0))
    assert fb.Busy and fb.Error and fb.ErrorId == NOT_FINITE
    for _ in range(50):
        sim.scan(fb, **jog(1.0e30, -1.0e30))  # clamped to MaxSpeed
    assert not fb.Error
    assert np.all(np.isfinite(sim.pos()))
    v = np.diff(sim.pos(), axis=0) / DT
    assert np.abs(v[:, 4]).max() <= SPEED * (1 + 1e-4)
    rates_ok(sim, [0, 1, 2, 3, 4])


@pytest.mark.parametrize("change, code", [
    ({"MaxSpeed": 0.0}, BAD_PARAMETER),
    ({"MaxSpeed": NAN}, BAD_PARAMETER),
    ({"MaxSpeed": 1.0e30}, BAD_PARAMETER),
    ({"Acceleration": -1.0}, BAD_PARAMETER),
    ({"CycleTime": 0.0}, BAD_PARAMETER),
    ({"Geometry": {"Arm": G.as_st(), "ToolMm": -1.0}}, BAD_GEOMETRY),
])
def test_bad_parameters_change_nothing(st_module: Any, change: dict[str, Any],
                                       code: int) -> None:
    sim = start()
    sim.assert_rejected(st_module.new_fb("MotionJogWrist"), code, **jog(10.0, 0.0, **change))


def test_a_three_joint_group_is_rejected(st_module: Any) -> None:
    sim = GroupSim(make_group(Q0[:3], joints=3))
    sim.assert_rejected(st_module.new_fb("MotionJogWrist"), BAD_JOINT_COUNT, **jog(10.0, 0.0))
