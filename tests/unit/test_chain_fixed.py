"""st/KinematicsChainFixed.st: document 003's fixed-point resolved-rate step.

References: Python's math (sine), central differences of the float64 closed-form FK
(Jacobian), numpy.linalg.pinv (the 003 line, float64) and the same algorithm in float32
(armbench.plant.redundant_chain). Figures are printed: run with -s.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from armbench.plant import redundant_chain as rc

REPO = Path(__file__).resolve().parents[2]
SOURCE = REPO / "st" / "KinematicsChainFixed.st"
GEO = rc.DEFAULT_CHAIN
GEO_UM = GEO.as_st_um()
NO_ERROR, UNREACHABLE, BAD_GEOMETRY, BAD_PARAMETER = 0, 1, 4, 8
STEP_TOO_LARGE, FIXED_SINGULAR = 38, 39
Q18 = 2.0 ** 18
Q24 = 2.0 ** 24


def _step(fb: Any, target_um: tuple[int, int, int], damping_um: int = 0,
          geometry: dict[str, int] | None = None) -> None:
    fb(TargetXUm=target_um[0], TargetYUm=target_um[1], TargetZUm=target_um[2],
       Geometry=geometry or GEO_UM, DampingUm=damping_um, Reset=False, InitJoints=[0, 0, 0, 0])


def _reset(fb: Any, joints: list[int], geometry: dict[str, int] | None = None) -> None:
    fb(TargetXUm=0, TargetYUm=0, TargetZUm=0, Geometry=geometry or GEO_UM, DampingUm=0,
       Reset=True, InitJoints=joints)


def run_line(st_module: Any, damping_um: int = 0) -> np.ndarray:
    """Joints (rad) of the ST block along the seed's line, rows 0..100."""
    points = rc.line_points()
    q0 = rc.start_configuration(points[0])
    fb = st_module.new_fb("ChainResolvedRateFixed")
    _reset(fb, rc.to_turn24(q0))
    assert fb.Valid and fb.ErrorId == NO_ERROR
    rows = [rc.from_turn24(fb.Joints)]
    for x in points[1:]:
        _step(fb, tuple(int(round(v * 1e6)) for v in x), damping_um)  # type: ignore[arg-type]
        assert fb.Valid, f"step refused: ErrorId {fb.ErrorId}"
        rows.append(rc.from_turn24(fb.Joints))
    return np.array(rows)


# ------------------------------------------------------------------ integer only
# no floating-point token: tests/unit/test_kinematics_fixed.py::test_no_floating_point_tokens
def test_no_division_operator() -> None:
    """Document 003: shifts instead of division (MOD too would be a division)."""
    text = re.sub(r"\(\*.*?\*\)", " ", SOURCE.read_text(encoding="utf-8"), flags=re.S)
    assert "/" not in text and not re.search(r"\bMOD\b", text, re.I)


# ------------------------------------------------------------------ building blocks
def test_sin_cos_turn24_against_math(st_module: Any) -> None:
    fb = st_module.new_fb("SinCosTurnFixed")
    rng = np.random.default_rng(3)
    angles = [0, 1 << 22, 1 << 23, 3 << 22, (1 << 24) - 1, -1, -(1 << 22), 1 << 26, -(1 << 30),
              *rng.integers(-(1 << 31), (1 << 31) - 1, 4000).tolist()]
    worst = 0.0
    for a in angles:
        fb(AngleT24=a)
        rad = (a % (1 << 24)) * 2 * math.pi / (1 << 24)
        worst = max(worst, abs(fb.SinQ18 / Q18 - math.sin(rad)),
                    abs(fb.CosQ18 / Q18 - math.cos(rad)))
    print(f"\nSinCosTurnFixed: worst |error| {worst:.2e} over {len(angles)} angles")
    assert worst <= 1.2e-5  # the 1024-point table's budget (file header: 1.1E-5)
    for a, s, c in ((0, 0, 262144), (1 << 22, 262144, 0), (1 << 23, 0, -262144),
                    (3 << 22, -262144, 0)):
        fb(AngleT24=a)
        assert (fb.SinQ18, fb.CosQ18) == (s, c)


@pytest.mark.parametrize("value,bits,expected", [
    (5, 1, 3), (-5, 1, -3), (4, 1, 2), (-4, 1, -2), (7, 2, 2), (-7, 2, -2), (1, 63, 0),
    (3, -4, 48), (-3, -4, -48), (1 << 61, 60, 2), (-(1 << 61), 61, -1), (123, 0, 123)])
def test_shift_rounds_half_away_from_zero(st_module: Any, value: int, bits: int,
                                          expected: int) -> None:
    assert st_module.call("ChainShiftLint", Value=value, Bits=bits) == expected


def test_bit_length(st_module: Any) -> None:
    for v in [0, -5, 1, 2, 3, 255, 256, (1 << 40) - 1, 1 << 40, (1 << 62) + 12345, (1 << 63) - 1]:
        assert st_module.call("ChainBitLength", Value=v) == (v.bit_length() if v > 0 else 0)


def test_forward_and_jacobian_against_float64(st_module: Any) -> None:
    fb = st_module.new_fb("ChainForwardFixed")
    rng = np.random.default_rng(11)
    worst_pos = worst_jac = 0.0
    for _ in range(400):
        q = rng.uniform(-math.pi, math.pi, 4)
        fb(Joints=rc.to_turn24(q), Geometry=GEO_UM)
        assert not fb.Error
        qq = rc.from_turn24(rc.to_turn24(q))  # the angle the block got
        ref = rc.forward(qq)
        got = np.array([fb.XUm, fb.YUm, fb.ZUm]) * 1e-6
        worst_pos = max(worst_pos, float(np.abs(got - ref).max()))
        assert np.allclose(np.array(fb.PosQ24) / Q24, got, atol=1e-6)
        # Jacobian against central differences of the float64 FK (not the analytic form)
        h = 1e-6
        num = np.array([(rc.forward(qq + h * e) - rc.forward(qq - h * e)) / (2 * h)
                        for e in np.eye(4)]).T
        jac = np.array([fb.JacobianX, fb.JacobianY, fb.JacobianZ])  # rows X, Y, Z
        worst_jac = max(worst_jac, float(np.abs(jac / Q24 - num).max()))
    print(f"\nChainForwardFixed: worst |FK error| {worst_pos * 1e6:.1f} um, "
          f"worst |J error| {worst_jac:.2e} m/rad")
    # budget: 1.1E-5 of each link's length per sine/cosine (1.7 m of links, 2 terms) + 0.5 um
    assert worst_pos <= 2 * 1.1e-5 * (GEO.a3 + GEO.a4 + GEO.a5) + 0.5e-6
    assert worst_jac <= 2 * 1.1e-5 * (abs(GEO.a2) + GEO.a3 + GEO.a4 + GEO.a5) + 1e-6


# ------------------------------------------------------------------ the 003 line
def test_003_line_against_numpy_pinv_and_float32(st_module: Any) -> None:
    points = rc.line_points()
    q0 = rc.start_configuration(points[0])
    q_fixed = run_line(st_module)
    q64 = rc.track_pinv64(points, rc.from_turn24(rc.to_turn24(q0)))
    q32 = rc.track_float32(points, rc.from_turn24(rc.to_turn24(q0)))
    err_fixed = rc.path_errors(q_fixed, points)
    err64 = rc.path_errors(q64, points)
    err32 = rc.path_errors(q32, points)
    dev_fixed = np.array([np.linalg.norm(rc.forward(a) - rc.forward(b))
                          for a, b in zip(q_fixed[1:], q64[1:], strict=True)])
    dev32 = np.array([np.linalg.norm(rc.forward(a) - rc.forward(b))
                      for a, b in zip(q32[1:], q64[1:], strict=True)])
    jdev_fixed = float(np.degrees(np.abs(q_fixed - q64)).max())
    jdev32 = float(np.degrees(np.abs(q32 - q64)).max())
    print(f"\n003 line, 100 intervals, chain {GEO}:"
          f"\n  path error |FK(q_k) - X_k|  float64 pinv max {err64.max() * 1e6:.2f} um "
          f"(the one-step lag of resolved rate), float32 max {err32.max() * 1e6:.2f} um, "
          f"fixed max {err_fixed.max() * 1e6:.2f} um "
          f"(rms {np.sqrt((err_fixed ** 2).mean()) * 1e6:.2f})"
          f"\n  |FK(q) - FK(q_float64)|  fixed max {dev_fixed.max() * 1e6:.2f} um, "
          f"float32 max {dev32.max() * 1e6:.2f} um"
          f"\n  joints vs float64: fixed max {jdev_fixed:.5f} deg, float32 max {jdev32:.5f} deg")
    # float64 resolved rate lags by the linearisation error of one step
    assert err64.max() < 15e-6
    # the fixed point adds at most the FK budget of its sine table (file header: 37 um)
    assert dev_fixed.max() < 2 * 1.1e-5 * (GEO.a3 + GEO.a4 + GEO.a5)
    assert err_fixed.max() < err64.max() + 2 * 1.1e-5 * (GEO.a3 + GEO.a4 + GEO.a5)
    assert jdev_fixed < 0.01
    assert dev32.max() < 5e-6
    # the end point is the seed's end point (within the same budget)
    assert np.linalg.norm(rc.forward(q_fixed[-1]) - points[-1]) < err64.max() + 40e-6


def test_damped_step_stays_finite_at_a_singularity(st_module: Any) -> None:
    """Stretched arm (all pitches 0): J J^T is singular; damping gives a bounded step."""
    fb = st_module.new_fb("ChainResolvedRateFixed")
    _reset(fb, [0, 0, 0, 0])
    _step(fb, (1_500_000, 0, 500_000))
    assert fb.Error and fb.ErrorId == FIXED_SINGULAR and fb.Joints == [0, 0, 0, 0]
    _step(fb, (1_500_000, 0, 500_000), damping_um=50_000)
    assert fb.Valid and fb.ErrorId == NO_ERROR
    q = rc.from_turn24(fb.Joints)
    # float64 damped least squares from the same joints: J^T (J J^T + l^2 I)^-1 dX
    jac = rc.jacobian(np.zeros(4))
    dx = np.array([1.5, 0.0, 0.5]) - rc.forward(np.zeros(4))
    ref = jac.T @ np.linalg.solve(jac @ jac.T + 0.05 ** 2 * np.eye(3), dx)
    assert np.abs(q - ref).max() < 1e-5


def test_step_too_large_is_refused(st_module: Any) -> None:
    fb = st_module.new_fb("ChainResolvedRateFixed")
    start = [0, 0, round(1.0 / 360 * 2 ** 24), 0]  # elbow bent by 1 deg: nearly singular
    _reset(fb, start)
    _step(fb, (1_500_000, 0, 500_000))
    assert fb.Error and fb.ErrorId == STEP_TOO_LARGE and fb.Joints == start


@pytest.mark.parametrize("change,code", [
    ({"A3Um": 0}, BAD_GEOMETRY), ({"A4Um": -1}, BAD_GEOMETRY),
    ({"A1Um": 2_000_001}, BAD_GEOMETRY), ({"A2Um": -2_147_483_648}, BAD_GEOMETRY),
    ({"A3Um": 2_000_000, "A4Um": 2_000_000}, BAD_GEOMETRY)])
def test_bad_geometry_keeps_the_joints(st_module: Any, change: dict[str, int], code: int) -> None:
    fb = st_module.new_fb("ChainResolvedRateFixed")
    start = rc.to_turn24(rc.start_configuration(rc.line_points()[0]))
    _reset(fb, start)
    _step(fb, (600_000, -850_000, 500_000), geometry={**GEO_UM, **change})
    assert fb.Error and not fb.Valid and fb.ErrorId == code and fb.Joints == start
    fk = st_module.new_fb("ChainForwardFixed")
    fk(Joints=start, Geometry={**GEO_UM, **change})
    assert fk.Error and fk.ErrorId == code


@pytest.mark.parametrize("target,damping,code", [
    ((8_000_001, 0, 0), 0, UNREACHABLE), ((0, -2_147_483_648, 0), 0, UNREACHABLE),
    ((600_000, -850_000, 500_000), -1, BAD_PARAMETER),
    ((600_000, -850_000, 500_000), 1_000_001, BAD_PARAMETER)])
def test_bad_input_keeps_the_joints(st_module: Any, target: tuple[int, int, int], damping: int,
                                    code: int) -> None:
    fb = st_module.new_fb("ChainResolvedRateFixed")
    start = rc.to_turn24(rc.start_configuration(rc.line_points()[0]))
    _reset(fb, start)
    _step(fb, target, damping_um=damping)
    assert fb.Error and fb.ErrorId == code and fb.Joints == start
    _step(fb, (530_000, -820_000, 480_000))  # a good step afterwards works again
    assert fb.Valid and fb.ErrorId == NO_ERROR


def test_far_target_is_clamped_not_wrapped(st_module: Any) -> None:
    """A target 7 m away: dX is clamped to 0.25 m per axis (numpy pinv of the clamped dX)."""
    fb = st_module.new_fb("ChainResolvedRateFixed")
    start = rc.to_turn24(rc.start_configuration(rc.line_points()[0]))
    _reset(fb, start)
    _step(fb, (7_000_000, -7_000_000, 7_000_000))
    assert fb.Valid and fb.ErrorId == NO_ERROR
    q = rc.from_turn24(start)
    clamped = np.clip(np.array([7.0, -7.0, 7.0]) - rc.forward(q), -0.25, 0.25)
    ref = np.linalg.pinv(rc.jacobian(q)) @ clamped
    assert np.degrees(np.abs(rc.from_turn24(fb.Joints) - q - ref)).max() < 1e-3
