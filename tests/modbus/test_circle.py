"""The seed's task end to end: the 360-point circle of document 000, driven point by
point over Modbus (request/acknowledge), through the PCA9685 and MG996R models.

Bounds are derived, not measured: the PLC's FK echo must match the target to REAL precision
(0.05 mm), and each servo must end within the PWM quantisation of the angle the PLC commanded
— half a 12-bit count plus the servo's deadband, converted to degrees with the MG996R's
120 deg per 1000 us.
"""

from __future__ import annotations

import math

from armbench.controller_client import ArmControllerClient
from armbench.demo import circle, drive_path, start_plant
from armbench.plant import arm
from armbench.plant.pca9685 import INTERNAL_OSC_HZ
from armbench.plant.servo import ServoParams

DEG_PER_US = 120.0 / 1000.0


def test_circle_of_360_points(plc: ArmControllerClient) -> None:
    plant, prescale = start_plant(plc)
    count_us = 1e6 / (INTERNAL_OSC_HZ / (4096 * (prescale + 1))) / 4096  # one PWM count
    bound_deg = (count_us / 2 + ServoParams().deadband_width_us) * DEG_PER_US

    points = circle(360, (150.0, 0.0, 120.0), 40.0, "xy")
    run = drive_path(plc, plant, points)

    assert run.rejected == 0
    assert len(run.commanded) == 360
    assert max(run.echo_errors_mm()) <= 0.05
    worst = max(abs(a - c) for cmd, ach in zip(run.joints, run.achieved_joints, strict=True)
                for c, a in zip(cmd, ach, strict=True))
    assert worst <= bound_deg, f"servo ended {worst:.3f} deg from the command (> {bound_deg:.3f})"
    # position: each point within the joint bound pushed through the arm's Jacobian
    for cmd_joints, err in zip(run.joints, run.errors_mm(), strict=True):
        assert err <= position_bound_mm(cmd_joints, bound_deg) + 1e-3


def position_bound_mm(joints: tuple[float, float, float], bound_deg: float) -> float:
    """Sum over joints of |dp/dtheta_i| * bound: a first-order bound from the reference FK."""
    h = 1e-4
    base = arm.forward(*joints)
    total = 0.0
    for i in range(3):
        moved = list(joints)
        moved[i] += h
        d = math.dist(arm.forward(*moved)[:3], base[:3]) / h
        total += d * bound_deg
    return total
