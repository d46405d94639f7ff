"""The PLCopen single-axis layer (st/AMC*.st) against plcopen_model.py, scan by scan: one
machine (two axes, every AMC_* block per axis, drives after the blocks) driven by random
sequences of block inputs, and the checks of every PLCopen rule on every scan. Shared by
tests/unit/test_amc_axis_stateful.py (CI, bounded) and bench/plcopen_axis_soak.py (longer).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any

from amc_bench import (
    ABS_A,
    ABS_B,
    AXES,
    BLOCKS,
    HALT,
    HOME,
    NAMES,
    OVERRIDE,
    POWER,
    REL,
    RESET,
    SLOTS,
    STATUS,
    STOP,
    VEL,
)
from plcopen_model import STATE_NAMES, AxisModel, Observed, Outputs

CYCLE = 0.01
CFG: dict[str, Any] = dict(MinPosDeg=-90.0, MaxPosDeg=90.0, MaxVelDeg=120.0, MaxAccDeg=600.0,
                           MaxJerkDeg=6000.0, HomeVelDeg=60.0, HomePosDeg=0.0)
RULES = ("exclusive Busy/Done/Error/CommandAborted", "Active only while Busy",
         "outputs equal the model's", "ErrorID from the list", "axis state equals the model's",
         "ReadStatus one flag = the state", "MC_Power Status", "InVelocity only while Active",
         "set point finite and continuous")


@dataclass
class Figures:
    scans: int = 0
    calls: int = 0
    checks: dict[str, int] = field(default_factory=dict)
    transitions: dict[str, int] = field(default_factory=dict)
    results: dict[str, int] = field(default_factory=dict)

    def check(self, rule: str, ok: bool, msg: str) -> None:
        self.checks[rule] = self.checks.get(rule, 0) + 1
        assert ok, f"{rule}: {msg}"


def random_params(rng: random.Random, block: int) -> tuple[list[float], int]:
    """Mostly valid inputs of a block, sometimes one bad (NaN, 0, negative, out of range)."""
    good = rng.random() < 0.85
    p = [0.0] * 5
    ip = 0
    if block == HOME:
        p[0] = rng.uniform(-80.0, 80.0)
    elif block in (ABS_A, ABS_B):
        p[:5] = [rng.uniform(-85.0, 85.0), rng.uniform(5.0, 150.0), rng.uniform(50.0, 800.0),
                 rng.uniform(50.0, 800.0), rng.uniform(500.0, 8000.0)]
    elif block == REL:
        p[:5] = [rng.uniform(-60.0, 60.0), rng.uniform(5.0, 150.0), rng.uniform(50.0, 800.0),
                 rng.uniform(50.0, 800.0), rng.uniform(500.0, 8000.0)]
    elif block == VEL:
        p[:4] = [rng.uniform(0.0, 80.0), rng.uniform(50.0, 800.0), rng.uniform(50.0, 800.0),
                 rng.uniform(500.0, 8000.0)]
        ip = rng.choice((1, -1))
    elif block in (HALT, STOP):
        p[:2] = [rng.uniform(50.0, 800.0), rng.uniform(500.0, 8000.0)]
    elif block == OVERRIDE:
        p[:3] = [rng.choice((0.0, 1.0, rng.uniform(0.05, 1.0))), rng.uniform(0.2, 1.0),
                 rng.uniform(0.2, 1.0)]
    if not good:
        k = rng.randrange(5)
        bad = rng.choice((math.nan, 0.0, -1.0, math.inf, 200.0, -200.0))
        if block == OVERRIDE:
            p[min(k, 2)] = rng.choice((math.nan, -0.5, 1.5))
        elif block not in (POWER, RESET, STATUS):
            p[k if block in (ABS_A, ABS_B, REL) else 0] = bad
        if block in (HOME, ABS_A, ABS_B, REL, HALT) and rng.random() < 0.3:
            ip = 1  # BufferMode Buffered: not implemented, refused
        if block == VEL and rng.random() < 0.3:
            ip = 0
    return p, ip


class Machine:
    """The compiled bench and the models of its two axes."""

    def __init__(self, module: Any) -> None:
        self.fb = module.new_fb("AMCBench")
        self.models = [AxisModel(CFG["MinPosDeg"], CFG["MaxPosDeg"]) for _ in range(AXES)]
        self.exec = [False] * SLOTS
        self.par = [[0.0] * 5 for _ in range(SLOTS)]
        self.ipar = [0] * SLOTS
        self.order = list(range(1, SLOTS + 1))
        self.scan_no = 0
        self.fig = Figures()
        self.prev: list[tuple[float, float]] = [(0.0, 0.0)] * AXES
        self.last_state = [0] * AXES
        for b in (STATUS,):
            for a in range(AXES):
                self.exec[a * BLOCKS + b - 1] = True
        self.fb(Init=True, Cfg1=CFG, Cfg2=CFG, Order=self.order, Exec=self.exec, Par=self.par,
                IntPar=self.ipar, CycleTime=CYCLE)
        self.fb.set(Init=False)
        self._check_scan()

    def set_block(self, axis: int, block: int, execute: bool,
                  params: tuple[list[float], int] | None = None) -> None:
        slot = axis * BLOCKS + block - 1
        self.exec[slot] = execute
        if params is not None:
            self.par[slot], self.ipar[slot] = params

    def scan(self, order: list[int] | None = None) -> None:
        if order is not None:
            self.order = order
        self.fb(Order=self.order, Exec=self.exec, Par=self.par, IntPar=self.ipar)
        self.scan_no += 1
        self._check_scan()

    def _check_scan(self) -> None:
        fb, fig = self.fb, self.fig
        done, busy, active = fb.Done, fb.Busy, fb.Active
        aborted, err, errid, invel = fb.Aborted, fb.Err, fb.ErrId, fb.InVel
        flags = fb.Flags
        axes = [fb.Out1, fb.Out2]
        status_state: dict[int, int] = {}
        for slot in self.order:
            a, b = (slot - 1) // BLOCKS, (slot - 1) % BLOCKS + 1
            m = self.models[a]
            s = slot - 1
            want = m.call(b, self.exec[s], self.par[s], self.ipar[s], self.scan_no)
            fig.calls += 1
            name = f"{NAMES[b - 1]}{a + 1}"
            if b == STATUS:
                status_state[a] = m.state
                continue
            got = Outputs(done=bool(done[s]), busy=bool(busy[s]), active=bool(active[s]),
                          aborted=bool(aborted[s]), error=bool(err[s]), error_id=int(errid[s]))
            if b not in (POWER, OVERRIDE):
                fig.check(RULES[0], got.done + got.busy + got.error + got.aborted <= 1,
                          f"{name} scan {self.scan_no}: {got}")
                fig.check(RULES[1], not got.active or got.busy, f"{name}: {got}")
            if b in (POWER, OVERRIDE, RESET):
                got.active = want.active = False
                got.aborted = want.aborted = False
            if b == POWER:
                fig.check(RULES[6], got.done == want.done, f"{name}: Status {got.done}")
            fig.check(RULES[2], got == want,
                      f"{name} scan {self.scan_no}: ST {got} model {want} "
                      f"(model state {STATE_NAMES[m.state]})")
            fig.check(RULES[3], got.error_id in (0, 8, 10, 26, 27, 28, 29, 50, 51, 52, 53, 54),
                      f"{name}: {got.error_id}")
            if b == VEL:
                fig.check(RULES[7], not invel[s] or got.active, f"{name}: InVelocity {got}")
            for key in ("done", "error", "aborted"):
                if getattr(got, key) and not getattr(self, "_seen", {}).get((s, key)):
                    fig.results[f"{NAMES[b - 1]} {key}"] = \
                        fig.results.get(f"{NAMES[b - 1]} {key}", 0) + 1
        for a in range(AXES):
            ax = axes[a]
            m = self.models[a]
            pos, vel, acc = ax["SetPosDeg"], ax["SetVelDeg"], ax["SetAccDeg"]
            fig.check(RULES[8], all(math.isfinite(x) for x in (pos, vel, acc)),
                      f"axis {a + 1}: {pos} {vel} {acc}")
            p0, v0 = self.prev[a]
            fig.check(RULES[8], abs(pos - p0) <= CFG["MaxVelDeg"] * CYCLE * 1.000001 + 1e-9,
                      f"axis {a + 1}: step {pos - p0}")
            # MC_Power off drops the set velocity to 0 on purpose (the servo goes limp)
            fig.check(RULES[8], m.state == 0 or abs(vel - v0) <= CFG["MaxAccDeg"] * CYCLE
                      * 1.000001 + 1e-9,
                      f"axis {a + 1} scan {self.scan_no}: velocity step {vel - v0}, state "
                      f"{STATE_NAMES[int(ax['State'])]}")
            self.prev[a] = (pos, vel)
            m.drive(Observed(pos, vel, acc, int(ax["AxisErrorId"])), CFG["MaxVelDeg"])
            state = int(ax["State"])
            if state != self.last_state[a]:
                t = f"{STATE_NAMES[self.last_state[a]]}->{STATE_NAMES[state]}"
                fig.transitions[t] = fig.transitions.get(t, 0) + 1
                self.last_state[a] = state
            fig.check(RULES[4], int(ax["State"]) == m.state,
                      f"axis {a + 1} scan {self.scan_no}: ST {STATE_NAMES[int(ax['State'])]} "
                      f"model {STATE_NAMES[m.state]}")
            if a in status_state:
                row = flags[a]
                fig.check(RULES[5], sum(bool(x) for x in row) == 1
                          and bool(row[status_state[a]]),
                          f"axis {a + 1}: flags {row}, state {STATE_NAMES[status_state[a]]}")
        fig.scans += 1


def random_run(machine: Machine, rng: random.Random, scans: int) -> None:
    """Random block inputs for `scans` scans: edges, aborts, two commands in one scan, inputs
    changed while Busy, power cycles, resets, random call orders."""
    for a in range(AXES):
        machine.set_block(a, POWER, True)
    done = 0
    while done < scans:
        for _ in range(rng.choice((0, 1, 1, 2, 3))):
            a = rng.randrange(AXES)
            b = rng.choice((POWER, RESET, RESET, HOME, HOME, ABS_A, ABS_B, ABS_A, REL, VEL, VEL,
                            VEL, HALT, STOP, OVERRIDE, ABS_B))
            slot = a * BLOCKS + b - 1
            if b == POWER:
                machine.set_block(a, b, rng.random() < 0.8)
            elif b == STOP and machine.exec[slot]:
                machine.set_block(a, b, False)
            else:
                machine.set_block(a, b, not machine.exec[slot], random_params(rng, b))
        if rng.random() < 0.3:
            order = list(range(1, SLOTS + 1))
            rng.shuffle(order)
            machine.scan(order)
        else:
            machine.scan()
        done += 1
        for _ in range(rng.choice((0, 0, 2, 10, 40, 150))):
            if done >= scans:
                break
            machine.scan()
            done += 1


def report(fig: Figures) -> str:
    lines = [f"scans {fig.scans}, block calls checked {fig.calls}, "
             f"rule checks {sum(fig.checks.values())}"]
    lines += [f"  {n:>8}  {r}" for r, n in sorted(fig.checks.items())]
    lines.append("state changes between scans: " + ", ".join(f"{k} {v}" for k, v in
                                                sorted(fig.transitions.items())))
    lines.append("block-scans showing a result: "
                 + ", ".join(f"{k} {v}" for k, v in sorted(fig.results.items())))
    return "\n".join(lines)
