"""st/Kinematics5Axis.st: the 5-axis arm (base, shoulder, elbow, wrist pitch, wrist roll).

Independent references, built here: a Robotics Toolbox DHRobot of the arm (standard DH,
fkine) and a numpy product of elementary transforms Rz, Ry, Rx and translations. Round trips
FK(IK(p)) on >= 10,000 poses in each of document 004's modes (tip fixed, flange fixed) and
with each orientation input (pitch/roll angles, tool direction vector).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import five_axis_ref
from armbench.plant.arm import ArmGeometry

A1, A2, A3, A4, TOOL = 100.0, 20.0, 120.0, 130.0, 60.0
GEO = {"Arm": {"A1": A1, "A2": A2, "A3": A3, "A4": A4}, "ToolMm": TOOL}
LENGTHS = ArmGeometry(A1, A2, A3, A4)
N_ROUND_TRIP = 10_000
NO_ERROR, UNREACHABLE, SINGULAR, NOT_FINITE, BAD_GEOMETRY = 0, 1, 2, 3, 4
TOOL_OUT_OF_PLANE, TOOL_VECTOR_ZERO, FLANGE_UNREACHABLE = 35, 36, 37
POS_TOL_MM = 2e-3   # float32 REAL at a 300 mm reach: a few ulp through the trig
ANGLE_TOL_DEG = 2e-3


# ------------------------------------------------------------------ references
def fk_elementary(q_deg: np.ndarray) -> np.ndarray:
    """Tool poses (N, 4, 4) of the shared reference (tests/five_axis_ref.py) on this file's
    geometry; columns of the rotation = tool x, y, z."""
    return five_axis_ref.fk_elementary(q_deg, LENGTHS, TOOL)


@pytest.fixture(scope="module")
def dh_robot() -> Any:
    rtb = pytest.importorskip("roboticstoolbox")
    sm = pytest.importorskip("spatialmath")
    robot = rtb.DHRobot([
        rtb.RevoluteDH(d=A1, a=A2, alpha=math.pi / 2),
        rtb.RevoluteDH(a=A3),
        rtb.RevoluteDH(a=A4, offset=-math.pi),          # Elbow = 180 deg: straight arm
        rtb.RevoluteDH(alpha=math.pi / 2, offset=math.pi / 2),
        rtb.RevoluteDH(d=TOOL)], name="five-axis")
    # DH puts the approach on z; the library's tool frame has it on x: (x, y, z) = (z, -y, x)
    robot.tool = sm.SE3.Rt(np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]),
                           [0.0, 0.0, 0.0])
    return robot


def sample_joints(rng: np.random.Generator, n: int, tip_radial: bool) -> np.ndarray:
    """Elbow-up joints away from the reach shells and the base axis (deg)."""
    out: list[np.ndarray] = []
    while sum(len(o) for o in out) < n:
        q = np.column_stack([rng.uniform(-179, 179, n), rng.uniform(-80, 170, n),
                             rng.uniform(8, 172, n), rng.uniform(-150, 150, n),
                             rng.uniform(-179, 179, n)])
        t = fk_elementary(q)
        flange = t[:, :3, 3] - TOOL * t[:, :3, 0]
        heading = np.column_stack([np.cos(np.radians(q[:, 0])), np.sin(np.radians(q[:, 0]))])
        keep = np.einsum("ij,ij->i", flange[:, :2], heading) > 5.0
        if tip_radial:
            keep &= np.einsum("ij,ij->i", t[:, :2, 3], heading) > 5.0
        out.append(q[keep])
    return np.concatenate(out)[:n]


def wrap(d: np.ndarray) -> np.ndarray:
    return np.abs((np.asarray(d) + 180.0) % 360.0 - 180.0)


def _ik(fb: Any, **kw: Any) -> None:
    args = {"XMm": 0.0, "YMm": 0.0, "ZMm": 0.0, "TipFixed": True, "UseToolVector": False,
            "PitchDeg": 0.0, "RollDeg": 0.0, "DirX": 0.0, "DirY": 0.0, "DirZ": 0.0,
            "ElbowUp": True, "Geometry": GEO}
    args.update(kw)
    fb(**args)


def _joints(fb: Any) -> np.ndarray:
    a = fb.Angles
    return np.array([a["Base"], a["Shoulder"], a["Elbow"], a["GripperUpDown"],
                     a["GripperRotate"]])


def _outputs_finite(fb: Any) -> bool:
    vals = [*fb.Angles.values(), *fb.Joints, fb.TipXMm, fb.TipYMm, fb.TipZMm, fb.FlangeXMm,
            fb.FlangeYMm, fb.FlangeZMm, fb.ToolPitchDeg]
    return all(math.isfinite(v) for v in vals)


# ------------------------------------------------------------------ forward kinematics
def test_fk_against_dh_robot_and_elementary_rotations(st_module: Any, dh_robot: Any) -> None:
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(-180, 180, 2000), rng.uniform(-180, 180, 2000),
                         rng.uniform(0, 360, 2000), rng.uniform(-180, 180, 2000),
                         rng.uniform(-180, 180, 2000)])
    ref = fk_elementary(q)
    fk = st_module.new_fb("ForwardKinematic5Axis")
    worst_pos = worst_rot = worst_dh = 0.0
    for k in range(len(q)):
        dh = dh_robot.fkine(np.radians(q[k])).A
        worst_dh = max(worst_dh, float(np.abs(dh - ref[k]).max()))
        b, s, e, w, r = (float(v) for v in q[k])
        fk(Angles={"Base": b, "Shoulder": s, "Elbow": e, "GripperUpDown": w,
                   "GripperRotate": r}, Geometry=GEO)
        assert not fk.Error
        tip = np.array([fk.TipXMm, fk.TipYMm, fk.TipZMm])
        flange = np.array([fk.FlangeXMm, fk.FlangeYMm, fk.FlangeZMm])
        frame = np.column_stack([fk.ToolAxisX, fk.ToolAxisY, fk.ToolAxisZ])
        worst_pos = max(worst_pos, float(np.abs(tip - dh[:3, 3]).max()),
                        float(np.abs(flange - (dh[:3, 3] - TOOL * dh[:3, 0])).max()))
        worst_rot = max(worst_rot, float(np.abs(frame - dh[:3, :3]).max()))
    print(f"\nForwardKinematic5Axis vs DHRobot.fkine: tip {worst_pos:.2e} mm, frame "
          f"{worst_rot:.2e}; DHRobot vs elementary rotations {worst_dh:.1e}")
    assert worst_dh < 1e-9  # the two references agree
    assert worst_pos < 1e-3 and worst_rot < 1e-5


def test_fk_pitch_and_roll_outputs(st_module: Any) -> None:
    fk = st_module.new_fb("ForwardKinematic5Axis")
    fk(Angles={"Base": 30.0, "Shoulder": 40.0, "Elbow": 100.0, "GripperUpDown": -20.0,
               "GripperRotate": 200.0}, Geometry=GEO)
    assert fk.PitchDeg == pytest.approx(-60.0, abs=1e-4)   # 40 + 100 - 180 - 20
    assert fk.RollDeg == pytest.approx(-160.0, abs=1e-4)   # 200 folded into (-180, 180]


# ------------------------------------------------------------------ round trips
@pytest.mark.parametrize("tip_fixed", [True, False], ids=["tip-fixed", "flange-fixed"])
@pytest.mark.parametrize("use_vector", [False, True], ids=["pitch-roll", "tool-vector"])
def test_round_trip(st_module: Any, tip_fixed: bool, use_vector: bool) -> None:
    rng = np.random.default_rng(17 + 2 * tip_fixed + use_vector)
    q = sample_joints(rng, N_ROUND_TRIP, tip_radial=tip_fixed and not use_vector)
    poses = fk_elementary(q)
    ik = st_module.new_fb("InverseKinematik5Axis")
    got = np.zeros_like(q)
    for k in range(len(q)):
        t = poses[k]
        point = t[:3, 3] if tip_fixed else t[:3, 3] - TOOL * t[:3, 0]
        pitch = q[k, 1] + q[k, 2] - 180.0 + q[k, 3]
        # a direction of any length: the block normalises it
        direction = t[:3, 0] * rng.uniform(0.01, 100.0)
        _ik(ik, XMm=float(point[0]), YMm=float(point[1]), ZMm=float(point[2]),
            TipFixed=tip_fixed, UseToolVector=use_vector,
            PitchDeg=float((pitch + 180.0) % 360.0 - 180.0), RollDeg=float(q[k, 4]),
            DirX=float(direction[0]), DirY=float(direction[1]), DirZ=float(direction[2]))
        assert ik.Valid, f"pose {k} {q[k]}: ErrorId {ik.ErrorId}"
        got[k] = _joints(ik)
    back = fk_elementary(got)
    pos_err = np.abs(back[:, :3, 3] - poses[:, :3, 3]).max(axis=1)
    flange_err = np.abs((back[:, :3, 3] - TOOL * back[:, :3, 0])
                        - (poses[:, :3, 3] - TOOL * poses[:, :3, 0])).max(axis=1)
    rot_err = np.abs(back[:, :3, :3] - poses[:, :3, :3]).max(axis=(1, 2))
    joint_err = wrap(got - q).max(axis=1)
    print(f"\nround trip ({'tip' if tip_fixed else 'flange'} fixed, "
          f"{'vector' if use_vector else 'pitch/roll'}), {len(q)} poses: tip "
          f"{pos_err.max():.2e} mm, flange {flange_err.max():.2e} mm, frame "
          f"{rot_err.max():.2e}, joints {joint_err.max():.2e} deg")
    assert len(q) >= 10_000
    assert pos_err.max() < POS_TOL_MM and flange_err.max() < POS_TOL_MM
    assert rot_err.max() < 2e-5
    assert joint_err.max() < ANGLE_TOL_DEG  # elbow up: the sampled joints come back


# ------------------------------------------------------------------ document 004's two modes
def test_tip_stays_put_while_the_orientation_changes(st_module: Any) -> None:
    ik = st_module.new_fb("InverseKinematik5Axis")
    fk = st_module.new_fb("ForwardKinematic5Axis")
    tip = (150.0, 60.0, 90.0)
    for pitch in np.linspace(-80.0, 60.0, 29):
        for roll in (-120.0, 0.0, 45.0):
            _ik(ik, XMm=tip[0], YMm=tip[1], ZMm=tip[2], TipFixed=True, PitchDeg=float(pitch),
                RollDeg=roll)
            assert ik.Valid, (pitch, ik.ErrorId)
            fk(Angles=ik.Angles, Geometry=GEO)
            assert np.allclose([fk.TipXMm, fk.TipYMm, fk.TipZMm], tip, atol=POS_TOL_MM)
            base = math.atan2(tip[1], tip[0])
            want = (fk_elementary(np.array([[math.degrees(base), 0.0, 180.0, pitch, roll]]))[0]
                    [:3, :3])  # orientation = Rz(base) Ry(-pitch) Rx(roll)
            frame = np.column_stack([fk.ToolAxisX, fk.ToolAxisY, fk.ToolAxisZ])
            assert np.abs(frame - want).max() < 1e-5
            assert fk.PitchDeg == pytest.approx(pitch, abs=ANGLE_TOL_DEG)
            assert fk.RollDeg == pytest.approx(roll, abs=ANGLE_TOL_DEG)


def test_flange_stays_put_while_the_orientation_changes(st_module: Any) -> None:
    ik = st_module.new_fb("InverseKinematik5Axis")
    fk = st_module.new_fb("ForwardKinematic5Axis")
    flange = np.array([120.0, -90.0, 140.0])
    heading = np.array([flange[0], flange[1], 0.0]) / math.hypot(flange[0], flange[1])
    for pitch in np.linspace(-170.0, 170.0, 35):
        direction = math.cos(math.radians(pitch)) * heading + np.array(
            [0.0, 0.0, math.sin(math.radians(pitch))])
        _ik(ik, XMm=flange[0], YMm=flange[1], ZMm=flange[2], TipFixed=False,
            UseToolVector=True, DirX=direction[0] * 3, DirY=direction[1] * 3,
            DirZ=direction[2] * 3, RollDeg=10.0)
        assert ik.Valid, (pitch, ik.ErrorId)
        fk(Angles=ik.Angles, Geometry=GEO)
        assert np.allclose([fk.FlangeXMm, fk.FlangeYMm, fk.FlangeZMm], flange, atol=POS_TOL_MM)
        # the tip circles the flange at the tool length, along the commanded direction
        tip = np.array([fk.TipXMm, fk.TipYMm, fk.TipZMm])
        assert np.allclose(tip, flange + TOOL * direction, atol=POS_TOL_MM)
        assert np.abs(np.array(fk.ToolAxisX) - direction).max() < 1e-5
        assert ik.ToolPitchDeg == pytest.approx(pitch, abs=ANGLE_TOL_DEG)


# ------------------------------------------------------------------ bad input
GOOD = {"XMm": 150.0, "YMm": 60.0, "ZMm": 90.0, "PitchDeg": -30.0, "RollDeg": 20.0}


@pytest.mark.parametrize("change,code", [
    ({"XMm": math.nan}, NOT_FINITE), ({"ZMm": math.inf}, NOT_FINITE),
    ({"PitchDeg": math.nan}, NOT_FINITE), ({"RollDeg": -math.inf}, NOT_FINITE),
    ({"UseToolVector": True, "DirY": math.nan}, NOT_FINITE),
    ({"UseToolVector": True, "DirX": 0.0, "DirY": 0.0, "DirZ": 0.0}, TOOL_VECTOR_ZERO),
    ({"UseToolVector": True, "DirX": 1e-7, "DirY": 0.0, "DirZ": 0.0}, TOOL_VECTOR_ZERO),
    ({"UseToolVector": True, "DirX": 0.0, "DirY": 1.0, "DirZ": 0.0}, TOOL_OUT_OF_PLANE),
    ({"UseToolVector": True, "DirX": 1.0, "DirY": 0.0, "DirZ": -1.0}, TOOL_OUT_OF_PLANE),
    ({"XMm": 300.0, "YMm": 0.0, "ZMm": 100.0, "PitchDeg": 90.0}, FLANGE_UNREACHABLE),
    ({"XMm": 300.0, "YMm": 0.0, "ZMm": 100.0, "TipFixed": False}, UNREACHABLE),
    ({"XMm": 1e7}, UNREACHABLE), ({"PitchDeg": 400.0}, UNREACHABLE),
    ({"XMm": 0.0, "YMm": 0.0}, SINGULAR),
    ({"XMm": 0.0, "YMm": 0.0, "UseToolVector": True, "DirZ": 1.0, "TipFixed": False}, SINGULAR),
    ({"Geometry": {**GEO, "ToolMm": -1.0}}, BAD_GEOMETRY),
    ({"Geometry": {**GEO, "ToolMm": math.nan}}, BAD_GEOMETRY),
    ({"Geometry": {"Arm": {**GEO["Arm"], "A3": 0.0}, "ToolMm": TOOL}}, BAD_GEOMETRY),
])
def test_bad_input_gives_an_error_and_keeps_the_last_solution(
        st_module: Any, change: dict[str, Any], code: int) -> None:
    ik = st_module.new_fb("InverseKinematik5Axis")
    _ik(ik, **GOOD)
    assert ik.Valid
    before = _joints(ik)
    _ik(ik, **{**GOOD, **change})
    assert ik.Error and not ik.Valid and ik.ErrorId == code
    assert np.array_equal(_joints(ik), before)
    assert _outputs_finite(ik)


def test_out_of_plane_tolerance(st_module: Any) -> None:
    """A direction 0.003 deg out of the plane passes (1.0E-4), 0.01 deg does not."""
    ik = st_module.new_fb("InverseKinematik5Axis")
    for tilt_deg, ok in ((0.003, True), (0.01, False)):
        t = math.radians(tilt_deg)
        # flange on +X (tool straight down from a tip on +X): the plane normal is +Y
        _ik(ik, XMm=180.0, YMm=0.0, ZMm=60.0, TipFixed=True, UseToolVector=True,
            DirX=0.0, DirY=math.sin(t), DirZ=-math.cos(t))
        assert ik.Valid is ok, (tilt_deg, ik.ErrorId)
        if not ok:
            assert ik.ErrorId == TOOL_OUT_OF_PLANE


def test_fk_bad_input(st_module: Any) -> None:
    fk = st_module.new_fb("ForwardKinematic5Axis")
    angles = {"Base": 10.0, "Shoulder": 30.0, "Elbow": 90.0, "GripperUpDown": 0.0,
              "GripperRotate": 0.0}
    fk(Angles=angles, Geometry=GEO)
    tip = (fk.TipXMm, fk.TipYMm, fk.TipZMm)
    for bad, code in (({**angles, "Elbow": math.nan}, NOT_FINITE),
                      ({**angles, "GripperRotate": math.inf}, NOT_FINITE)):
        fk(Angles=bad, Geometry=GEO)
        assert fk.Error and fk.ErrorId == code and (fk.TipXMm, fk.TipYMm, fk.TipZMm) == tip
    fk(Angles=angles, Geometry={**GEO, "ToolMm": math.nan})
    assert fk.ErrorId == BAD_GEOMETRY and (fk.TipXMm, fk.TipYMm, fk.TipZMm) == tip
