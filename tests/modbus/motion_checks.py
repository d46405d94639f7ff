"""Checks shared by the motion suites (tests/modbus/test_motion_*.py): the slew guarantee
of the output stage over a recorded path, restated from the contract (MOTION-CONTRACT.md,
st/ServoSlew.st's header) and checked on the PLC's own samples, never on our model of it;
and the joint-angle distance the IK suites (test_lut.py, test_sweep.py) compare with."""

from __future__ import annotations

from armbench.controller_client import MotionRecording
from armbench.plant import arm

DT = 0.01  # s, the controller's TASK interval (ScanPeriodS in Controller.st)
# float32 angles near 100 deg are 8e-6 deg apart; a few of them per step
TOL_DEG = 1e-4


def angle_diff(a: float, b: float) -> float:
    """|a - b| in deg, the short way round the circle (0..180)."""
    return abs(arm.wrap180(a - b))


def worst_slew(rec: MotionRecording) -> tuple[float, float]:
    """Largest per-scan step and largest per-scan step change of the servo outputs, each as
    a fraction of what the limits in force allow (<= 1 when the guarantee holds). Only
    samples of neighbouring scans count: a missed scan is never interpolated."""
    step_ratio = acc_ratio = 0.0
    for a, b, c in rec.triples():
        for j in range(3):
            s1 = b.out_deg[j] - a.out_deg[j]
            s2 = c.out_deg[j] - b.out_deg[j]
            vmax, amax = c.limit_vel[j], c.limit_acc[j]
            # a lowered speed limit is reached by braking (ServoSlew.st)
            cap = max(vmax * DT, abs(s1) - amax * DT * DT)
            step_ratio = max(step_ratio, (abs(s2) - TOL_DEG) / cap)
            acc_ratio = max(acc_ratio, (abs(s2 - s1) - 2 * TOL_DEG) / (amax * DT * DT))
    return step_ratio, acc_ratio


def check_slew_limited(rec: MotionRecording) -> int:
    """Asserts the guarantee on every triple of neighbouring scans the recording holds;
    returns how many there were (a loaded machine lets the recorder sample fewer)."""
    step, acc = worst_slew(rec)
    assert step <= 1.0, f"a servo stepped {step:.3f} x its speed limit in one scan"
    assert acc <= 1.0, f"a servo's speed changed {acc:.3f} x its acceleration limit in a scan"
    return sum(1 for _ in rec.triples())


def assert_slew_limited(rec: MotionRecording, min_triples: int = 10) -> None:
    n = check_slew_limited(rec)
    assert n >= min_triples, f"only {n} triples of neighbouring scans recorded"
