"""MotionJog (st/MotionJog.st) with a jerk limit (Jerk > 0): the tool's Cartesian velocity
follows MotionJerkPlanner's velocity interface.

Reference: Ruckig's own online update (PyPI `ruckig`, Ruckig.update with the velocity
interface, phase synchronisation, the output passed back as the next input) on the same
wanted velocities, scan by scan: away from the workspace's and the joints' limits the jog's
Cartesian setpoints are Ruckig's (float32 tolerance of the REAL setpoint). Also: the jerk-
limited braking for the workspace boundary stops inside it and stays latched (no chatter);
per axis the acceleration stays within Acceleration and changes by at most Jerk * dt per
scan; bad Jerk values are refused at the Enable edge and change nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from motion_support import BAD_PARAMETER, DT, GroupSim, make_group

from armbench.plant import arm

ruckig = pytest.importorskip("ruckig")

GEO = arm.DEFAULT_GEOMETRY.as_st()
P_START = (180.0, -40.0, 150.0)
SPEED, ACC, JERK = 60.0, 300.0, 2500.0


def f32(x: float) -> float:
    return float(np.float32(x))


def start(point: tuple[float, float, float] = P_START, **limits: Any) -> GroupSim:
    q0 = [f32(q) for q in arm.inverse(*point)]
    return GroupSim(make_group(q0, **limits))


def jog_inputs(command: tuple[float, float, float], enable: bool = True,
               **change: Any) -> dict[str, Any]:
    return {"Enable": enable, "Command": list(command), "MaxSpeed": SPEED,
            "Acceleration": ACC, "Jerk": JERK, "ElbowUp": True, "Geometry": GEO,
            "CycleTime": DT, **change}


class RuckigJog:
    """Ruckig.update, velocity interface, phase synchronisation, 3 axes."""

    def __init__(self, p0: list[float]) -> None:
        self.otg = ruckig.Ruckig(3, DT)
        self.inp = ruckig.InputParameter(3)
        self.out = ruckig.OutputParameter(3)
        inp = self.inp
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.synchronization = ruckig.Synchronization.Phase
        inp.current_position = p0
        inp.current_velocity = [0.0] * 3
        inp.current_acceleration = [0.0] * 3
        inp.max_velocity = [1.0e3] * 3  # the velocity interface does not use it
        inp.max_acceleration = [f32(ACC)] * 3
        inp.max_jerk = [f32(JERK)] * 3

    def step(self, want: list[float]) -> list[float]:
        self.inp.target_velocity = want
        self.otg.update(self.inp, self.out)
        self.out.pass_to_input(self.inp)
        return list(self.out.new_position)


def want_of(stick: tuple[float, float, float]) -> list[float]:
    """The block's wanted velocity, in its REAL arithmetic (sticks of length <= 1: no
    rescaling to MaxSpeed)."""
    return [float(np.float32(c) * np.float32(SPEED)) for c in stick]


def test_jerk_jog_equals_ruckig_update(st_module: Any) -> None:
    sim = start(lower=-360.0, upper=360.0, max_vel=500.0)
    fb = st_module.new_fb("MotionJog")
    script = [((0.6, 0.3, 0.0), 40), ((-0.8, 0.0, 0.4), 70), ((0.0, -0.5, -0.5), 50),
              ((0.0, 0.0, 0.0), 60)]
    ref: RuckigJog | None = None
    worst = 0.0
    for stick, scans in script:
        for _ in range(scans):
            sim.scan(fb, **jog_inputs(stick))
            assert fb.Busy and not fb.Error and not fb.AtLimit
            got = sim.cartesian[-1]
            if ref is None:
                # the block's start point: its first setpoint less its first step from rest,
                # which is Ruckig's first step too: take Ruckig's step from a probe
                probe = RuckigJog([0.0, 0.0, 0.0])
                first = probe.step(want_of(stick))
                ref = RuckigJog([g - f for g, f in zip(got, first, strict=True)])
            exp = ref.step(want_of(stick))
            for j in range(3):
                err = abs(got[j] - exp[j])
                worst = max(worst, err)
                assert err <= 4 * float(np.spacing(np.float32(abs(exp[j]) + 1.0))), \
                    (len(sim.cartesian), j, got[j], exp[j])
    print(f"jerk-limited jog vs Ruckig.update: worst |setpoint - Ruckig's| {worst:.2e} mm")
    pts = np.array(sim.cartesian, dtype=np.float64)
    acc = np.diff(pts, 2, axis=0) / DT ** 2
    noise = 8 * float(np.spacing(np.float32(np.max(np.abs(pts))))) / DT ** 2
    assert np.max(np.abs(acc)) <= ACC * 1.001 + noise
    assert np.max(np.abs(np.diff(acc, axis=0))) <= JERK * DT * 1.001 + 2 * noise


def test_jerk_jog_stops_inside_the_workspace_boundary(st_module: Any) -> None:
    sim = start(lower=-360.0, upper=360.0, max_vel=500.0)
    fb = st_module.new_fb("MotionJog")
    at_limit = []
    for _ in range(500):
        sim.scan(fb, **jog_inputs((1.0, 0.0, 0.0)))
        at_limit.append(bool(fb.AtLimit))
    assert fb.Busy and fb.AtLimit and not fb.Error
    first = at_limit.index(True)
    assert all(at_limit[first:])  # latched: no brake - accelerate - brake chatter
    pts = np.array(sim.cartesian)
    low, high = arm.reach_limits()
    reach = [arm.shoulder_distance(*p) for p in pts]
    assert max(reach) <= high + 1e-3 and reach[-1] > high - 10.0
    assert np.linalg.norm(pts[-1] - pts[-2]) < 1e-6  # at rest
    acc = np.diff(pts.astype(np.float64), 2, axis=0) / DT ** 2
    noise = 8 * float(np.spacing(np.float32(np.max(np.abs(pts))))) / DT ** 2
    assert np.max(np.abs(np.diff(acc, axis=0))) <= JERK * DT * 1.001 + 2 * noise
    # a new command releases the latch: back away
    for _ in range(40):
        sim.scan(fb, **jog_inputs((-1.0, 0.0, 0.0)))
    assert not fb.AtLimit and sim.cartesian[-1][0] < pts[-1][0]


def test_jerk_jog_enable_false_brakes_jerk_limited_then_done(st_module: Any) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJog")
    for _ in range(60):
        sim.scan(fb, **jog_inputs((0.0, 1.0, 0.0)))
    scans = 0
    while fb.Busy:
        sim.scan(fb, **jog_inputs((0.0, 1.0, 0.0), enable=False))
        scans += 1
        assert scans < 200
    assert fb.Done and sim.group["Owner"] == 0 and sim.group["Velocity"][:3] == [0.0] * 3
    # braking from 60 mm/s at 300 mm/s^2 and 2500 mm/s^3: 60/300 + 300/2500 = 0.32 s, in
    # scans of the block's REAL cycle time
    assert scans == math.ceil((SPEED / ACC + ACC / JERK) / f32(DT))


@pytest.mark.parametrize("change", [{"Jerk": math.nan}, {"Jerk": -1.0}, {"Jerk": 1.0e16},
                                    {"Jerk": math.inf}, {"MaxSpeed": 1.0e20},
                                    {"Acceleration": 1.0e16}])
def test_jerk_jog_bad_parameters_are_refused(st_module: Any, change: dict[str, Any]) -> None:
    sim = start()
    fb = st_module.new_fb("MotionJog")
    sim.assert_rejected(fb, BAD_PARAMETER, **jog_inputs((1.0, 0.0, 0.0), **change))
