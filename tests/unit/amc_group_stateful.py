"""The PLCopen axis-group layer (st/AMCGroup*.st) against plcopen_group_model.py, scan by
scan: one group of three axes on the bench (amc_group_bench.py) driven by block inputs, and
the checks of every group rule on every scan. Shared by tests/unit/test_amc_group_stateful.py
(CI, bounded) and bench/plcopen_group_soak.py (longer).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any

from amc_group_bench import AXES, G_DISABLE, G_ENABLE, G_NAMES, G_RESET, G_SETKIN, GBLOCKS
from plcopen_group_model import (
    ERROR_LIST,
    G_ERRORSTOP,
    G_STANDBY,
    GROUP_STATE_NAMES,
    KIN_ARM3,
    GroupModel,
)

# the group blocks plcopen_group_model.py models (the administrative ones; the moves are
# checked by the directed tests of test_amc_group_moves.py)
MODEL_BLOCKS = 4
CYCLE = 0.01
CFG: dict[str, Any] = dict(MinPosDeg=-90.0, MaxPosDeg=90.0, MaxVelDeg=120.0, MaxAccDeg=600.0,
                           MaxJerkDeg=6000.0, HomeVelDeg=60.0, HomePosDeg=0.0)
GEO = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}
FK_TOL_MM = 2.0e-3  # REAL (float32) arithmetic in ForwardKinematic_V1 at ~250 mm reach


def fk_closed_form(base: float, shoulder: float, elbow: float,
                   g: dict[str, float]) -> tuple[float, float, float]:
    """Seed 002's arm: reach and height of the planar two-link chain, turned by the base."""
    t1, t2, t3 = math.radians(base), math.radians(shoulder), math.radians(elbow - 180.0)
    reach = g["A2"] + g["A3"] * math.cos(t2) + g["A4"] * math.cos(t2 + t3)
    height = g["A1"] + g["A3"] * math.sin(t2) + g["A4"] * math.sin(t2 + t3)
    return reach * math.cos(t1), reach * math.sin(t1), height


@dataclass
class Figures:
    scans: int = 0
    calls: int = 0
    checks: int = 0
    transitions: dict[str, int] = field(default_factory=dict)

    def check(self, ok: bool, msg: str) -> None:
        self.checks += 1
        assert ok, msg


class GroupMachine:
    def __init__(self, module: Any, axis_count: int = 3) -> None:
        self.fb = module.new_fb("AMCGroupBench")
        self.model = GroupModel(axis_count=axis_count)
        self.power = [False] * AXES
        self.move = [False] * AXES
        self.move_pos = [0.0] * AXES
        self.vel = [False] * AXES
        self.vel_dir = [1] * AXES
        self.reset = [False] * AXES
        self.gexec = [False] * GBLOCKS
        self.order = list(range(1, MODEL_BLOCKS + 1))
        self.kin = 0
        self.geo = dict(GEO)
        self.fig = Figures()
        self.fb(Init=True, Cfg=CFG, AxisCount=axis_count, GOrder=self.padded(), CycleTime=CYCLE)
        self.fb.set(Init=False)
        self.model.monitor([int(s) for s in self.fb.MidState])
        self._check()

    def padded(self) -> list[int]:
        return self.order + [0] * (GBLOCKS - len(self.order))

    def scan(self, order: list[int] | None = None) -> None:
        if order is not None:
            self.order = order
        fb = self.fb
        fb(AxPower=self.power, AxMove=self.move, AxMovePos=self.move_pos, AxVel=self.vel,
           AxVelDir=self.vel_dir, AxReset=self.reset, GOrder=self.padded(), GExec=self.gexec,
           KinModel=self.kin, Geo=self.geo)
        axes = [int(s) for s in fb.MidState]
        before = self.model.state
        for b in self.order:
            want = self.model.call(b, self.gexec[b - 1], axes, self.kin, self.geo)
            self.fig.calls += 1
            got = (bool(fb.GDone[b - 1]), bool(fb.GBusy[b - 1]), bool(fb.GErr[b - 1]),
                   int(fb.GErrId[b - 1]))
            self.fig.check(got == (want.done, want.busy, want.error, want.error_id),
                           f"{G_NAMES[b - 1]} scan {self.fig.scans}: got {got}, model {want}")
            self.fig.check(got[0] + got[1] + got[2] <= 1, f"{G_NAMES[b - 1]} exclusive {got}")
            self.fig.check(got[3] in ERROR_LIST, f"ErrorID {got[3]} not in the list")
        self.model.monitor(axes)
        self.fig.scans += 1
        if self.model.state != before:
            key = f"{GROUP_STATE_NAMES[before]}->{GROUP_STATE_NAMES[self.model.state]}"
            self.fig.transitions[key] = self.fig.transitions.get(key, 0) + 1
        self._check()

    def _check(self) -> None:
        fb, m, fig = self.fb, self.model, self.fig
        state = int(fb.GOut["State"])
        fig.check(state == m.state, f"scan {fig.scans}: group state "
                  f"{GROUP_STATE_NAMES[state]}, model {GROUP_STATE_NAMES[m.state]}")
        flags = [bool(f) for f in fb.Flags]
        fig.check(sum(flags) == 1 and flags[m.state], f"ReadStatus {flags}")
        fig.check((int(fb.RdGroupErr), int(fb.RdErrAxis)) == (m.error_id, m.error_axis),
                  f"ReadError {fb.RdGroupErr} axis {fb.RdErrAxis}, model {m.error_id} "
                  f"axis {m.error_axis}")
        fig.check(m.error_axis != 0 or int(fb.RdAxisErr) == 0, "AxisErrorID without an axis")
        mid = [float(p) for p in fb.MidPos]
        joint = [float(v) for v in fb.RdJoint]
        fig.check(joint == mid + [0.0] * (6 - AXES), f"joint position {joint} != {mid}")
        cart = [float(v) for v in fb.RdCart]
        if m.kin_model == KIN_ARM3:
            want = fk_closed_form(mid[0], mid[1], mid[2], m.geo)
            fig.check(bool(fb.RdCartValid), "Cartesian not valid with Arm3Dof")
            fig.check(all(abs(c - w) <= FK_TOL_MM for c, w in zip(cart, want, strict=False)),
                      f"Cartesian {cart[:3]} vs closed form {want}")
        else:
            fig.check(not fb.RdCartValid and cart == [0.0] * 6, f"Cartesian {cart} w/o model")


def random_geo(rng: random.Random) -> dict[str, float]:
    g = {"A1": rng.uniform(50.0, 150.0), "A2": rng.uniform(0.0, 40.0),
         "A3": rng.uniform(80.0, 160.0), "A4": rng.uniform(80.0, 160.0)}
    if rng.random() < 0.2:
        g[rng.choice(["A3", "A4"])] = rng.choice([0.0, -10.0, math.nan])
    return g


def settle(m: GroupMachine, rng: random.Random) -> None:
    """Every axis powered and moved to 0 deg, to rest (Standstill); then mostly a GroupReset
    edge in GroupErrorStop, else a GroupEnable edge."""
    m.vel = [False] * AXES
    m.power = [True] * AXES
    m.move = [False] * AXES
    m.scan()
    m.move, m.move_pos = [True] * AXES, [0.0] * AXES
    for _ in range(200):
        m.scan()
    if m.model.state == G_ERRORSTOP and rng.random() < 0.8:
        m.gexec[G_RESET - 1] = False
        m.scan()
        m.gexec[G_RESET - 1] = True
    elif m.model.state != G_STANDBY:
        m.gexec[G_ENABLE - 1] = False
        m.scan()
        m.gexec[G_ENABLE - 1] = True


def random_run(m: GroupMachine, rng: random.Random, scans: int) -> None:
    """A seeded run biased to reach every transition: the group is enabled often, the axes
    mostly rest, now and then one runs into its range end or is switched off."""
    m.power = [True] * AXES
    while m.fig.scans < scans:
        r = rng.random()
        if r < 0.08:
            settle(m, rng)
        elif r < 0.25:
            b = rng.choice((G_ENABLE, G_ENABLE, G_RESET, G_RESET, G_DISABLE, G_SETKIN))
            m.gexec[b - 1] = not m.gexec[b - 1]
            if b == G_SETKIN:
                m.kin = rng.choice((0, 1, 1, 2))
                m.geo = random_geo(rng) if rng.random() < 0.3 else dict(GEO)
        elif r < 0.32:
            a = rng.randrange(AXES)
            m.vel[a], m.vel_dir[a] = not m.vel[a], rng.choice((1, -1))
        elif r < 0.40:
            a = rng.randrange(AXES)
            m.move[a], m.move_pos[a] = not m.move[a], rng.uniform(-60.0, 60.0)
        elif r < 0.44:
            a = rng.randrange(AXES)
            m.power[a] = not m.power[a] if not m.power[a] else rng.random() < 0.5
        elif r < 0.55:
            a = rng.randrange(AXES)
            m.reset[a] = not m.reset[a]
        order = list(range(1, MODEL_BLOCKS + 1))
        rng.shuffle(order)
        for k in range(rng.choice((1, 2, 5, 30))):
            m.scan(order if k == 0 else None)
