"""Property tests of ChainResolvedRateFixed (st/KinematicsChainFixed.st) and
InverseKinematik5Axis (st/Kinematics5Axis.st) over their whole input range.

ChainResolvedRateFixed: every DINT input from its whole type (extremes and the documented
limits drawn often). Property: the documented error (joints kept), or a step within the
documented error of the float64 damped least-squares step J^T (J J^T + l^2 I)^-1 dX from the
same joints (dX clamped to 0.25 m per axis), and 39 FixedSingular only where float64 too finds
J J^T + l^2 I nearly singular.

InverseKinematik5Axis: any REAL (NaN, +/-Inf, huge, tiny). Property: every output finite;
whenever the block says Valid, the float64 FK of its joints puts the tip (tip mode) or the
flange (flange mode) at the command, with the commanded pitch (angle mode) or direction
(vector mode).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from armbench.plant import redundant_chain as rc

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import event, given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

DINT_MIN, DINT_MAX = -(2**31), 2**31 - 1
CHAIN_CODES = {1, 4, 8, 38, 39}
FIVE_AXIS_CODES = {1, 2, 3, 4, 35, 36, 37}
TURN = 2**24


def dint(*edges: int) -> st.SearchStrategy[int]:
    common = [DINT_MIN, DINT_MIN + 1, -1, 0, 1, DINT_MAX - 1, DINT_MAX]
    near = [e + d for e in edges for d in (-1, 0, 1)]
    return st.one_of(st.integers(DINT_MIN, DINT_MAX), st.sampled_from(common + near),
                     st.integers(-max(edges + (1,)), max(edges + (1,))))


def length_um() -> st.SearchStrategy[int]:
    return st.one_of(dint(0, 2_000_000, -2_000_000), st.integers(1, 2_000_000))


def _geometry_ok(g: dict[str, int]) -> bool:
    inside = (abs(g["A1Um"]) <= 2_000_000 and abs(g["A2Um"]) <= 2_000_000
              and 1 <= g["A3Um"] <= 2_000_000 and 0 <= g["A4Um"] <= 2_000_000
              and 0 <= g["A5Um"] <= 2_000_000)
    return inside and abs(g["A2Um"]) + g["A3Um"] + g["A4Um"] + g["A5Um"] <= 4_000_000


SANE_GEOMETRY = st.fixed_dictionaries({
    "A1Um": st.integers(-1_000_000, 1_000_000), "A2Um": st.integers(-500_000, 500_000),
    "A3Um": st.integers(1, 1_000_000), "A4Um": st.integers(0, 1_000_000),
    "A5Um": st.integers(0, 1_000_000)})


@given(geometry=st.one_of(st.just(rc.DEFAULT_CHAIN.as_st_um()), SANE_GEOMETRY,
                          st.fixed_dictionaries({f"A{i}Um": length_um() for i in range(1, 6)})),
       joints=st.lists(dint(TURN, -TURN, TURN // 2), min_size=4, max_size=4),
       target=st.lists(st.one_of(dint(8_000_000, -8_000_000), st.integers(-2_000_000, 2_000_000),
                                 st.integers(-2_000_000, 2_000_000)), min_size=3, max_size=3),
       damping=dint(0, 1_000_000))
def test_chain_step_whole_range(st_module: Any, geometry: dict[str, int], joints: list[int],
                                target: list[int], damping: int) -> None:
    fb = st_module.new_fb("ChainResolvedRateFixed")
    good_geo = _geometry_ok(geometry)
    fb(TargetXUm=0, TargetYUm=0, TargetZUm=0, Geometry=geometry, DampingUm=0, Reset=True,
       InitJoints=joints)
    if not good_geo:
        assert fb.Error and fb.ErrorId == 4
        return
    start = list(fb.Joints)
    assert all(-(2**23) <= j < 2**23 for j in start)
    assert all((s - j) % TURN == 0 for s, j in zip(start, joints, strict=True))
    fb(TargetXUm=target[0], TargetYUm=target[1], TargetZUm=target[2], Geometry=geometry,
       DampingUm=damping, Reset=False, InitJoints=joints)
    if not 0 <= damping <= 1_000_000:
        assert fb.ErrorId == 8 and fb.Joints == start
        return
    if any(abs(t) > 8_000_000 for t in target):
        assert fb.ErrorId == 1 and fb.Joints == start
        return
    geo = rc.ChainGeometry(*(geometry[f"A{i}Um"] * 1e-6 for i in range(1, 6)))
    q = rc.from_turn24(start)
    jac = rc.jacobian(q, geo)
    lam2 = (damping * 1e-6) ** 2
    a = jac @ jac.T + lam2 * np.eye(3)
    eig = np.linalg.eigvalsh(a)
    ratio = eig[0] / eig[-1] if eig[-1] > 0 else 0.0
    event(f"chain step: ErrorId {fb.ErrorId}")
    if fb.Error:
        assert fb.ErrorId in (38, 39) and fb.Joints == start
        if fb.ErrorId == 39:
            assert ratio < 1e-3, f"refused as singular, float64 eigenvalue ratio {ratio:.2e}"
        return
    assert fb.Valid and fb.ErrorId == 0
    dx = np.clip(np.array(target) * 1e-6 - rc.forward(q, geo), -0.25, 0.25)
    ref = jac.T @ np.linalg.solve(a, dx)
    got = rc.from_turn24(fb.Joints) - q
    got = (got + math.pi) % (2 * math.pi) - math.pi
    if ratio < 1e-2 or np.abs(ref).max() > 1.0:
        event("chain step: valid, ill-conditioned (not compared)")
        return  # ill-conditioned: the float64 step itself is not a sharp reference
    event("chain step: valid, compared with float64")
    reach = abs(geo.a2) + geo.a3 + geo.a4 + geo.a5
    # FK and Jacobian errors of the table (1.1E-5 of the links, twice) through J^+ ...
    pinv_norm = 1.0 / math.sqrt(eig[0]) if eig[0] > 0 else math.inf
    tol = (4 * 1.1e-5 * reach * pinv_norm * (1 + np.abs(ref).max())
           + 1e-4 * np.abs(ref).max() + 4 * 2 * math.pi / TURN)
    assert np.abs(got - ref).max() <= tol, (got, ref, tol)


GARBAGE = st.one_of(st.floats(width=32), st.sampled_from(
    [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e-30, -1e-30, 1e30, 1e6, -1e6, 3.4e38, 1e-7]))
NAMES = ("x", "y", "z", "pitch", "roll", "dx", "dy", "dz", "tool")


@given(sane=st.fixed_dictionaries({
           "x": st.floats(-300.0, 300.0), "y": st.floats(-300.0, 300.0),
           "z": st.floats(-200.0, 400.0), "pitch": st.floats(-360.0, 360.0),
           "roll": st.floats(-360.0, 360.0), "dx": st.floats(-2.0, 2.0),
           "dy": st.floats(-2.0, 2.0), "dz": st.floats(-2.0, 2.0),
           "tool": st.sampled_from([60.0, 0.0, 25.0])}),
       spoil=st.one_of(st.none(), st.tuples(st.sampled_from(NAMES), GARBAGE)),
       in_plane=st.booleans(), tip_fixed=st.booleans(), vector=st.booleans(),
       elbow_up=st.booleans())
def test_five_axis_ik_whole_range(st_module: Any, sane: dict[str, float],
                                  spoil: tuple[str, float] | None, in_plane: bool,
                                  tip_fixed: bool, vector: bool, elbow_up: bool) -> None:
    v = dict(sane)
    if in_plane:  # a direction in the plane of the commanded point: often reachable
        c, s_ = math.cos(math.atan2(v["y"], v["x"])), math.sin(math.atan2(v["y"], v["x"]))
        v["dx"], v["dy"] = c * v["dx"], s_ * v["dx"]
    if spoil is not None:
        v[spoil[0]] = spoil[1]
    x, y, z, pitch, roll, tool = v["x"], v["y"], v["z"], v["pitch"], v["roll"], v["tool"]
    d = [v["dx"], v["dy"], v["dz"]]
    geo = {"Arm": {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}, "ToolMm": tool}
    ik = st_module.new_fb("InverseKinematik5Axis")
    ik(XMm=x, YMm=y, ZMm=z, TipFixed=tip_fixed, UseToolVector=vector, PitchDeg=pitch,
       RollDeg=roll, DirX=d[0], DirY=d[1], DirZ=d[2], ElbowUp=elbow_up, Geometry=geo)
    outs = [*ik.Angles.values(), *ik.Joints, ik.TipXMm, ik.TipYMm, ik.TipZMm, ik.FlangeXMm,
            ik.FlangeYMm, ik.FlangeZMm, ik.ToolPitchDeg]
    assert all(math.isfinite(v) for v in outs)
    event(f"5-axis IK: ErrorId {ik.ErrorId}")
    if not ik.Valid:
        assert ik.Error and ik.ErrorId in FIVE_AXIS_CODES
        assert all(v == 0.0 for v in outs)  # first call: the last valid output is zero
        return
    fk = st_module.new_fb("ForwardKinematic5Axis")
    fk(Angles=ik.Angles, Geometry=geo)
    point = np.array([fk.TipXMm, fk.TipYMm, fk.TipZMm]) if tip_fixed else \
        np.array([fk.FlangeXMm, fk.FlangeYMm, fk.FlangeZMm])
    scale = 1.0 + abs(x) + abs(y) + abs(z) + 310.0 + abs(tool)
    assert np.abs(point - np.array([x, y, z])).max() <= 2e-3 + 2e-6 * scale
    frame_x = np.array(fk.ToolAxisX)
    if vector:
        u = np.array(d, dtype=np.float64)
        u = u / np.linalg.norm(u / np.abs(u).max()) / np.abs(u).max()
        assert np.abs(frame_x - u).max() <= 2e-4
    else:
        want = (pitch + 180.0) % 360.0 - 180.0
        assert abs((fk.PitchDeg - want + 180.0) % 360.0 - 180.0) <= 2e-3
    assert abs((fk.RollDeg - roll + 180.0) % 360.0 - 180.0) <= 2e-3
