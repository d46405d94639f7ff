"""A 10,000-point FK∘IK sweep over Modbus, in SolveBatch commands, split into tests that
pytest-xdist spreads over its workers (each with its own PLC: docs/parallel-runs.md).

Every point is checked against independent float64 references from the plant model
(armbench.plant.arm, numpy): the PLC's joint angles against the two-acos inverse of document
002, the numpy forward kinematics of those joints against the target, and the PLC's own FK
echo against the target. Bounds: 0.05 mm is REAL (float32) arithmetic on ~300 mm lengths with
margin, 0.01 deg the float32 IK against the float64 one away from the reach shells (the same
bounds as tests/unit/test_kinematics.py and test_controller.py).

The progress bar and the points/s line come from the armbench plugin (``record_points``);
``bench/parallel_sweep.py`` runs this file with 1 and 2 workers and prints both rates.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from motion_checks import angle_diff

from armbench.controller_client import ArmControllerClient
from armbench.plant import arm

SWEEP_POINTS = 10_000
CHUNK = 320  # points per test: 10 SolveBatch commands of 32
TOLERANCE_MM = 0.05
TOLERANCE_DEG = 0.01

# Box of targets in front of the arm, inside its reach shell by a margin (checked below).
LOW = np.array([110.0, -60.0, 80.0])
HIGH = np.array([190.0, 60.0, 160.0])


def sweep_targets(n: int = SWEEP_POINTS) -> np.ndarray:
    """n targets spread evenly over the box: the additive recurrence of the plastic number
    (Roberts' R3 sequence), deterministic and low-discrepancy."""
    phi = 1.2207440846057596  # root of x^3 = x + 1
    alpha = np.array([1.0 / phi, 1.0 / phi**2, 1.0 / phi**3])
    k = np.arange(1, n + 1)[:, None]
    return LOW + (HIGH - LOW) * np.mod(0.5 + k * alpha, 1.0)


def test_the_sweep_covers_reachable_targets_only() -> None:
    pts = sweep_targets()
    assert len(pts) == SWEEP_POINTS and len(np.unique(pts, axis=0)) == SWEEP_POINTS
    assert all(arm.is_reachable(*map(float, p), margin=5.0) for p in pts)
    # spread over the whole box, not bunched in a corner
    assert np.all(pts.min(axis=0) < LOW + 0.01 * (HIGH - LOW))
    assert np.all(pts.max(axis=0) > HIGH - 0.01 * (HIGH - LOW))


@pytest.mark.parametrize("chunk", range(math.ceil(SWEEP_POINTS / CHUNK)))
def test_fk_of_ik_sweep(plc: ArmControllerClient, record_points: Callable[..., None],
                        chunk: int) -> None:
    want = sweep_targets()[chunk * CHUNK: (chunk + 1) * CHUNK]
    results = plc.batch_roundtrip([tuple(map(float, p)) for p in want])

    assert len(results) == len(want)
    failed = [(i, r) for i, r in enumerate(results) if r.error_id != 0]
    assert not failed, f"{len(failed)} points not solved, first {failed[:3]}"
    joints = np.array([r.joints_deg for r in results])
    fk = arm.forward_batch(joints)
    echo = np.array([r.echo_mm for r in results])
    fk_err = np.linalg.norm(fk - want, axis=1)
    echo_err = np.linalg.norm(echo - want, axis=1)
    assert fk_err.max() <= TOLERANCE_MM, f"FK of the PLC's joints off by {fk_err.max():.4f} mm"
    assert echo_err.max() <= TOLERANCE_MM, f"the PLC's FK echo off by {echo_err.max():.4f} mm"
    for p, got in zip(want, joints, strict=True):
        ref = arm.inverse(*map(float, p), elbow_up=True)
        worst = max(angle_diff(g, r) for g, r in zip(got, ref, strict=True))
        assert worst <= TOLERANCE_DEG, f"joints {got} at {p}, float64 reference {ref}"
    record_points(len(want), total=SWEEP_POINTS)
