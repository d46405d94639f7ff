"""AMC_MoveLinearAbsolute (st/AMCGroupMove.st, run by AMC_GroupDrive) against closed-form
geometry: every scan's tool point -- the forward kinematics of the three joints' set points,
computed here in double precision from the closed form of seed 002's arm -- lies within
0.01 mm of the ideal segment from the start to the target, the tool moves forward along it,
the path velocity and acceleration (finite differences of those points) stay within the
limits, the duration equals ruckig's for the path length with the same limits, and a line
that leaves the workspace is refused at the Execute edge with the code of the first point
that fails.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

ruckig = pytest.importorskip("ruckig")
from amc_group_bench import (  # noqa: E402
    G_DIRECT,
    G_ENABLE,
    G_LINEAR,
    G_SETKIN,
    GBLOCKS,
    compile_group_bench,
)

CYCLE = 0.01
GEO = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}
ORDER = list(range(1, GBLOCKS + 1))
DEVIATION_MM = 0.01


def fk(q: list[float]) -> np.ndarray:
    t1, t2, t3 = math.radians(q[0]), math.radians(q[1]), math.radians(q[2] - 180.0)
    reach = GEO["A2"] + GEO["A3"] * math.cos(t2) + GEO["A4"] * math.cos(t2 + t3)
    height = GEO["A1"] + GEO["A3"] * math.sin(t2) + GEO["A4"] * math.sin(t2 + t3)
    return np.array([reach * math.cos(t1), reach * math.sin(t1), height])


@pytest.fixture(scope="module")
def group_module(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return compile_group_bench(tmp_path_factory.mktemp("amcgrouplin"))


class Bench:
    def __init__(self, module: Any, q0: list[float], span: float = 90.0) -> None:
        self.fb = module.new_fb("AMCGroupBench")
        cfg = dict(MinPosDeg=-span, MaxPosDeg=span, MaxVelDeg=120.0, MaxAccDeg=600.0,
                   MaxJerkDeg=6000.0, HomeVelDeg=60.0, HomePosDeg=0.0)
        self.fb(Init=True, Cfg=cfg, AxisCount=3, GOrder=ORDER, CycleTime=CYCLE, KinModel=1,
                Geo=GEO)
        self.fb.set(Init=False)
        self.exec = [False] * GBLOCKS
        self.fb(GExec=self.exec, AxPower=[True] * 3)
        self.edge(G_SETKIN)
        self.edge(G_ENABLE)
        self.edge(G_DIRECT, DirPos=[*q0, 0.0, 0.0, 0.0], DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
        for _ in range(500):
            self.scan()
            if self.fb.GDone[G_DIRECT - 1]:
                break
        assert int(self.fb.GOut["State"]) == 1

    def scan(self, **kw: Any) -> None:
        self.fb(GExec=self.exec, **kw)

    def edge(self, block: int, **kw: Any) -> None:
        self.exec[block - 1] = False
        self.scan(**kw)
        self.exec[block - 1] = True
        self.scan(**kw)

    def joints(self) -> list[float]:
        return [float(self.fb.AxOut[k]["SetPosDeg"]) for k in range(3)]


LINES = [([0.0, 60.0, 80.0], [30.0, 40.0, 70.0], (100.0, 500.0, 5000.0)),
         ([-40.0, 30.0, 85.0], [45.0, 50.0, 60.0], (200.0, 1000.0, 20000.0)),
         ([10.0, 70.0, 50.0], [10.0, 20.0, 85.0], (50.0, 200.0, 1000.0))]


@pytest.mark.parametrize(("q0", "q1", "lim"), LINES)
def test_line_deviation_speed_and_duration(group_module: Any, q0: list[float], q1: list[float],
                                           lim: tuple[float, float, float]) -> None:
    b = Bench(group_module, q0)
    start, end = fk(b.joints()), fk(q1)
    length = float(np.linalg.norm(end - start))
    u = (end - start) / length
    b.exec[G_LINEAR - 1] = False
    b.scan()
    b.exec[G_LINEAR - 1] = True
    pts = [start]
    worst = 0.0
    n = 0
    while n < 5000:
        n += 1
        b.scan(LinPos=[*end.tolist(), 0.0, 0.0, 0.0], LinLim=list(lim), DirBuffer=0)
        assert not b.fb.GErr[G_LINEAR - 1], int(b.fb.GErrId[G_LINEAR - 1])
        p = fk(b.joints())
        s = float(np.dot(p - start, u))
        dev = float(np.linalg.norm(p - start - s * u))
        worst = max(worst, dev, -s, s - length)
        pts.append(p)
        if b.fb.GDone[G_LINEAR - 1]:
            break
    assert b.fb.GDone[G_LINEAR - 1]
    assert worst <= DEVIATION_MM, worst
    assert float(np.linalg.norm(pts[-1] - end)) <= DEVIATION_MM
    arr = np.array(pts)
    along = (arr - start) @ u
    vel = np.diff(along) / CYCLE
    acc = np.diff(vel) / CYCLE
    # float32 IK: the points carry ~1e-4 mm of noise, i.e. 1 mm/s^2 in a second difference
    assert vel.min() >= -0.05 and vel.max() <= lim[0] * (1 + 1e-6) + 0.05, (vel.min(), vel.max())
    assert np.abs(acc).max() <= lim[1] + 20.0, np.abs(acc).max()
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [length]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [lim[0]], [lim[1]], [lim[2]]
    traj = ruckig.Trajectory(1)
    ruckig.Ruckig(1).calculate(inp, traj)
    t = float(traj.duration)
    assert (n - 2) * CYCLE < t + 1e-9 and t <= (n - 1) * CYCLE + 1e-9, (n, t)
    assert int(b.fb.GOut["State"]) == 1 and [int(a["State"]) for a in b.fb.AxOut[:3]] == [1] * 3
    print(f"\nline {length:.1f} mm: {n} scans, worst deviation {worst:.2e} mm, "
          f"peak path velocity {vel.max():.2f} mm/s, ratio to ruckig {(n - 1) * CYCLE / t:.4f}")


@pytest.mark.parametrize(("q0", "target", "span", "code"),
                         [([0.0, 60.0, 80.0], None, 180.0, 2),     # through the base axis
                          ([0.0, 60.0, 80.0], "near", 180.0, 2),   # 2.5 mm past it
                          ([0.0, 60.0, 80.0], [400.0, 0.0, 150.0], 180.0, 1),   # out of reach
                          ([0.0, 60.0, 80.0], [-150.0, 0.0, 150.0], 90.0, 10),  # base range
                          ([0.0, 30.0, 60.0], [60.0, 0.0, 300.0], 90.0, 10)])
def test_a_line_leaving_the_workspace_is_refused(group_module: Any, q0: list[float],
                                                 target: list[float] | str | None, span: float,
                                                 code: int) -> None:
    b = Bench(group_module, q0, span)
    start = fk(b.joints())
    if target is None:
        end = [-start[0], -start[1], start[2]]
    elif target == "near":   # the base would turn half round within a few mm
        end = [-start[0], -start[1] + 5.0, start[2]]
    else:
        assert isinstance(target, list)
        end = target
    b.edge(G_LINEAR, LinPos=[*end, 0.0, 0.0, 0.0], LinLim=[100.0, 500.0, 5000.0], DirBuffer=0)
    assert b.fb.GErr[G_LINEAR - 1] and int(b.fb.GErrId[G_LINEAR - 1]) == code
    assert int(b.fb.GOut["State"]) == 1 and b.joints() == pytest.approx(q0, abs=1e-9)
