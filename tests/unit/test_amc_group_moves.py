"""The group moves of the PLCopen axis-group layer (AMC_MoveDirectAbsolute, AMC_GroupHalt,
AMC_GroupStop, run by AMC_GroupDrive through the axes' Coupled mode) from outside, on the
bench of amc_group_bench.py:

- AMC_MoveDirectAbsolute from rest takes the scans ruckig's time-synchronised trajectory of the
  three joints with the same limits takes (ruckig, same run), all joints arrive in the same
  scan, and every scan's joint velocity, acceleration and jerk stay within the axes' limits
  times the factors;
- a second move mid-way aborts the first without a jump in position or velocity;
- GroupHalt brings the group to rest, GroupStop holds it in GroupStopping and refuses moves;
- an axis switched off or taken by a single-axis command mid-move stops the group
  (GroupErrorStop, GroupAxisError) and the other axes brake to rest within their limits;
- refusals with the layer's codes.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

ruckig = pytest.importorskip("ruckig")
from amc_group_bench import (  # noqa: E402
    AXES,
    G_DIRECT,
    G_DISABLE,
    G_ENABLE,
    G_HALT,
    G_RESET,
    G_STOP,
    GBLOCKS,
    compile_group_bench,
)

CYCLE = 0.01
LIMITS = [(120.0, 600.0, 6000.0), (90.0, 400.0, 3000.0), (150.0, 800.0, 9000.0)]
ORDER = list(range(1, GBLOCKS + 1))
STANDBY, MOVING, STOPPING, ERRORSTOP = 1, 2, 4, 5


@pytest.fixture(scope="module")
def group_module(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return compile_group_bench(tmp_path_factory.mktemp("amcgroupmoves"))


class Bench:
    def __init__(self, module: Any) -> None:
        self.fb = module.new_fb("AMCGroupBench")
        cfg = dict(MinPosDeg=-90.0, MaxPosDeg=90.0, MaxVelDeg=120.0, MaxAccDeg=600.0,
                   MaxJerkDeg=6000.0, HomeVelDeg=60.0, HomePosDeg=0.0)
        self.fb(Init=True, Cfg=cfg, AxisCount=3, GOrder=ORDER, CycleTime=CYCLE)
        self.fb.set(Init=False)
        self.exec = [False] * GBLOCKS
        self.power = [True] * AXES
        self.move = [False] * AXES
        self.vel = [False] * AXES
        self.scan()
        self.edge(G_ENABLE)
        assert int(self.fb.GOut["State"]) == STANDBY

    def scan(self, **kw: Any) -> None:
        self.fb(GExec=self.exec, AxPower=self.power, AxMove=self.move, AxVel=self.vel, **kw)

    def edge(self, block: int, **kw: Any) -> None:
        self.exec[block - 1] = False
        self.scan(**kw)
        self.exec[block - 1] = True
        self.scan(**kw)

    def axes(self) -> list[dict[str, Any]]:
        return [self.fb.AxOut[k] for k in range(AXES)]


def ruckig_sync(start: list[float], target: list[float], lim: list[tuple[float, float, float]]
                ) -> Any:
    inp = ruckig.InputParameter(3)
    inp.current_position = start
    inp.target_position = target
    inp.max_velocity = [v for v, _, _ in lim]
    inp.max_acceleration = [a for _, a, _ in lim]
    inp.max_jerk = [j for _, _, j in lim]
    traj = ruckig.Trajectory(3)
    ruckig.Ruckig(3).calculate(inp, traj)
    return traj


MOVES = [([40.0, -30.0, 60.0], (1.0, 1.0, 1.0)), ([-80.0, 10.0, 5.0], (0.5, 0.8, 0.6)),
         ([0.5, 85.0, -85.0], (1.0, 0.3, 1.0)), ([12.0, 12.0, 12.0], (0.2, 1.0, 0.1))]


@pytest.mark.parametrize(("target", "factors"), MOVES)
def test_move_direct_is_synchronised_and_takes_ruckigs_time(group_module: Any,
                                                            target: list[float],
                                                            factors: tuple[float, float, float]
                                                            ) -> None:
    b = Bench(group_module)
    lim = [(120.0 * factors[0], 600.0 * factors[1], 6000.0 * factors[2])] * 3
    b.exec[G_DIRECT - 1] = False
    b.scan()
    pos = [target[0], target[1], target[2], 0.0, 0.0, 0.0]
    b.exec[G_DIRECT - 1] = True
    prev = [(0.0, 0.0, 0.0)] * 3
    arrive = [0, 0, 0]
    n = 0
    for n in range(1, 3000):
        b.scan(DirPos=pos, DirFactor=list(factors), DirBuffer=0)
        ax = b.axes()
        for k in range(3):
            p, v, a = ax[k]["SetPosDeg"], ax[k]["SetVelDeg"], ax[k]["SetAccDeg"]
            vmax, amax, jmax = lim[k]
            assert abs(v) <= vmax * (1 + 1e-9) + 1e-9, (n, k, v)
            assert abs(a) <= amax * (1 + 1e-9) + 1e-9, (n, k, a)
            assert abs(a - prev[k][2]) <= jmax * CYCLE * (1 + 1e-9) + 1e-9, (n, k)
            prev[k] = (p, v, a)
            if arrive[k] == 0 and abs(p - target[k]) <= 1e-9 and abs(v) <= 1e-9:
                arrive[k] = n
            if arrive[k]:
                assert abs(p - target[k]) <= 1e-9
        # GroupMoving until the drive reaches the target; Done shows at the next call
        assert int(b.fb.GOut["State"]) in ((MOVING, STANDBY) if min(arrive) else (MOVING,))
        if b.fb.GDone[G_DIRECT - 1]:
            break
    t = float(ruckig_sync([0.0] * 3, target, lim).duration)
    # the move runs in the group drive from the edge's scan on; Done shows one scan later
    assert (n - 2) * CYCLE < t + 1e-9 and t <= (n - 1) * CYCLE + 1e-9, (n, t)
    assert max(arrive) - min(arrive) == 0, arrive
    assert [int(a["State"]) for a in b.axes()] == [1, 1, 1]
    print(f"\nMoveDirect {target} x{factors}: {n - 1} scans, ruckig {t / CYCLE:.2f} scans, "
          f"ratio {(n - 1) * CYCLE / t:.4f}")


def test_a_second_move_aborts_the_first_without_a_jump(group_module: Any) -> None:
    b = Bench(group_module)
    b.edge(G_DIRECT, DirPos=[60.0, 60.0, 60.0, 0, 0, 0], DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
    for _ in range(20):
        b.scan()
    before = [(a["SetPosDeg"], a["SetVelDeg"]) for a in b.axes()]
    # the bench has one MoveDirect: a new edge with a new target is a new command
    b.exec[G_DIRECT - 1] = False
    b.scan(DirPos=[-20.0, 0.0, 10.0, 0, 0, 0])
    after0 = [(a["SetPosDeg"], a["SetVelDeg"]) for a in b.axes()]
    b.exec[G_DIRECT - 1] = True
    b.scan()
    after = [(a["SetPosDeg"], a["SetVelDeg"]) for a in b.axes()]
    for (p0, v0), (p1, v1), (p2, v2) in zip(before, after0, after, strict=True):
        assert abs(p2 - p1) <= 120.0 * CYCLE + 1e-9 and abs(v2 - v1) <= 600.0 * CYCLE + 1e-9
        assert v0 > 0.0 and abs(p1 - p0) <= 120.0 * CYCLE + 1e-9
    for _ in range(400):
        b.scan()
        if b.fb.GDone[G_DIRECT - 1]:
            break
    assert [round(a["SetPosDeg"], 9) for a in b.axes()] == [-20.0, 0.0, 10.0]


def test_group_halt_and_stop(group_module: Any) -> None:
    b = Bench(group_module)
    b.edge(G_DIRECT, DirPos=[80.0, -80.0, 80.0, 0, 0, 0], DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
    for _ in range(30):
        b.scan()
    b.edge(G_HALT)
    b.scan()   # MoveDirect is called before GroupHalt: it sees the abort one scan later
    assert b.fb.GAborted[G_DIRECT - 1] and b.fb.GBusy[G_HALT - 1]
    for _ in range(200):
        b.scan()
        if b.fb.GDone[G_HALT - 1]:
            break
    assert b.fb.GDone[G_HALT - 1] and int(b.fb.GOut["State"]) == STANDBY
    assert all(0.0 < abs(a["SetPosDeg"]) < 80.0 and a["SetVelDeg"] == 0.0 for a in b.axes())
    # GroupStop: GroupStopping while held, moves refused (59), Standby after release
    b.edge(G_DIRECT, DirPos=[0.0, 0.0, 0.0, 0, 0, 0])
    for _ in range(5):
        b.scan()
    b.edge(G_STOP)
    b.scan()
    assert int(b.fb.GOut["State"]) == STOPPING and b.fb.GAborted[G_DIRECT - 1]
    for _ in range(200):
        b.scan()
    assert b.fb.GDone[G_STOP - 1] and int(b.fb.GOut["State"]) == STOPPING
    b.edge(G_DIRECT)
    assert b.fb.GErr[G_DIRECT - 1] and int(b.fb.GErrId[G_DIRECT - 1]) == 59
    b.exec[G_STOP - 1] = False
    b.scan()
    b.scan()
    assert int(b.fb.GOut["State"]) == STANDBY and not b.fb.GDone[G_STOP - 1]
    assert [int(a["State"]) for a in b.axes()] == [1, 1, 1]


@pytest.mark.parametrize("how", ["power off", "single-axis move"])
def test_an_axis_leaving_mid_move_stops_the_group(group_module: Any, how: str) -> None:
    b = Bench(group_module)
    b.edge(G_DIRECT, DirPos=[80.0, -80.0, 80.0, 0, 0, 0], DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
    for _ in range(30):
        b.scan()
    if how == "power off":
        b.power[1] = False
    else:
        b.move[1] = True
    v_before = [a["SetVelDeg"] for a in b.axes()]
    b.scan(AxMovePos=[0.0, 0.0, 0.0])
    # no jump in velocity, also not on the axis a single-axis command took over
    for k, a in enumerate(b.axes()):
        if how != "power off" or k != 1:
            assert abs(a["SetVelDeg"] - v_before[k]) <= 600.0 * CYCLE + 1e-9, (k, v_before, a)
    assert int(b.fb.GOut["State"]) == ERRORSTOP
    assert (int(b.fb.RdGroupErr), int(b.fb.RdErrAxis)) == (58, 2)
    b.scan()
    assert b.fb.GErr[G_DIRECT - 1] and int(b.fb.GErrId[G_DIRECT - 1]) == 58
    prev = [(a["SetVelDeg"], a["SetAccDeg"]) for a in b.axes()]
    for _ in range(100):
        b.scan()
        for k in (0, 2):
            a = b.axes()[k]
            assert abs(a["SetAccDeg"] - prev[k][1]) <= 6000.0 * CYCLE + 1e-9
            assert -90.0 <= a["SetPosDeg"] <= 90.0
        prev = [(a["SetVelDeg"], a["SetAccDeg"]) for a in b.axes()]
    assert [int(a["State"]) for a in b.axes()][0::2] == [1, 1]
    assert all(a["SetVelDeg"] == 0.0 for a in b.axes()[0::2])
    b.move[1] = False
    b.power[1] = True
    for _ in range(100):
        b.scan()
    b.edge(G_RESET)
    b.scan()
    assert int(b.fb.GOut["State"]) == STANDBY, int(b.fb.GOut["State"])


def test_refusals(group_module: Any) -> None:
    b = Bench(group_module)
    cases: list[tuple[list[float], list[float], int, int]] = [
        ([95.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0, 10), ([0.0, 0.0, math.nan], [1.0, 1.0, 1.0], 0, 8),
        ([0.0, 0.0, 0.0], [0.0, 1.0, 1.0], 0, 8), ([0.0, 0.0, 0.0], [1.0, 1.5, 1.0], 0, 8),
        ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 1, 8)]
    for pos, fac, buf, code in cases:
        b.edge(G_DIRECT, DirPos=[*pos, 0, 0, 0], DirFactor=fac, DirBuffer=buf)
        assert b.fb.GErr[G_DIRECT - 1] and int(b.fb.GErrId[G_DIRECT - 1]) == code
        assert int(b.fb.GOut["State"]) == STANDBY
    b.edge(G_DISABLE)
    for blk in (G_DIRECT, G_HALT, G_STOP):
        b.edge(blk, DirPos=[0.0] * 6, DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
        assert b.fb.GErr[blk - 1] and int(b.fb.GErrId[blk - 1]) == 55


def test_a_move_issued_in_the_scan_an_axis_fails_ends_in_error(group_module: Any) -> None:
    """The axis blocks run before the group blocks: an axis switched off in the scan a move is
    accepted stops the group in the drive of that scan; the new move must end (Error 58), not
    stay Busy."""
    b = Bench(group_module)
    b.exec[G_DIRECT - 1] = False
    b.scan()
    b.power[0] = False
    b.exec[G_DIRECT - 1] = True
    b.scan(DirPos=[30.0, 30.0, 30.0, 0, 0, 0], DirFactor=[1.0, 1.0, 1.0], DirBuffer=0)
    assert int(b.fb.GOut["State"]) == ERRORSTOP
    b.scan()
    assert not b.fb.GBusy[G_DIRECT - 1]
    assert b.fb.GErr[G_DIRECT - 1] and int(b.fb.GErrId[G_DIRECT - 1]) == 58
