"""An independent Python model of PLCopen Motion Control Part 1 (single axis) for the
stateful test of st/AMC*.st: the state diagram, which command is accepted in which state
(ErrorIDs of the layer's one list), aborting (BufferMode Aborting), MC_Stop's Stopping rule
and the output rules of the Execute/Enable blocks. Written from the PLCopen specification and
the layer's documented choices (docs/plcopen-motion.md), not from the ST.

What a model cannot know without planning the trajectory -- when a move has arrived -- it
takes from the observed set point after the drive ran: a position move or homing is complete
when the set point is at its target at rest, Halt and Stop when at rest; a velocity move may
end in ErrorStop (JointLimit) only while moving towards a range end.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from amc_bench import (
    ABS_A,
    ABS_B,
    HALT,
    HOME,
    OVERRIDE,
    POWER,
    REL,
    RESET,
    STATUS,
    STOP,
    VEL,
)

DISABLED, STANDSTILL, HOMING, DISCRETE, CONTINUOUS, STOPPING, ERRORSTOP = range(7)
STATE_NAMES = ["Disabled", "Standstill", "Homing", "DiscreteMotion", "ContinuousMotion",
               "Stopping", "ErrorStop"]
BAD_PARAMETER, JOINT_LIMIT = 8, 10
AXIS_DISABLED, AXIS_STOPPING, AXIS_ERRORSTOP, AXIS_HOMING, NOT_STANDSTILL = 50, 51, 52, 53, 54
REST = 1e-9  # deg/s, deg/s^2: at rest; deg: at the target
MOTION_BLOCKS = (HOME, ABS_A, ABS_B, REL, VEL, HALT, STOP)


@dataclass
class Outputs:
    done: bool = False
    busy: bool = False
    active: bool = False
    aborted: bool = False
    error: bool = False
    error_id: int = 0


@dataclass
class Block:
    """One command block instance as the model sees it."""

    last_execute: bool = False
    token: int = 0                  # the command it issued last (0: none)
    issued_scan: int = -1
    out: Outputs = field(default_factory=Outputs)
    pending: str = ""               # result reached, shown at the next call: done/error/aborted
    pending_code: int = 0
    target: float = 0.0             # deg (position moves, home)
    velocity: float = 0.0           # deg/s signed (velocity moves)


@dataclass
class Observed:
    pos: float
    vel: float
    acc: float
    error_id: int


@dataclass
class AxisModel:
    lo: float
    hi: float
    state: int = DISABLED
    power: bool = False
    owner: int = 0                  # token of the current command
    owner_block: int = 0            # block number of the current command, 0: none
    owner_kind: int = 0             # block number kind: HOME/ABS_A/.../STOP
    next_token: int = 0
    reset_pending: bool = False
    stop_done: bool = False
    vel_factor: float = 1.0
    blocks: dict[int, Block] = field(default_factory=dict)
    obs: Observed = field(default_factory=lambda: Observed(0.0, 0.0, 0.0, 0))

    def __post_init__(self) -> None:
        self.blocks = {b: Block() for b in range(1, 12)}

    # -- what the specification allows ----------------------------------------------------
    def refusal(self, block: int) -> int:
        if block == STOP:
            return {DISABLED: AXIS_DISABLED, ERRORSTOP: AXIS_ERRORSTOP}.get(self.state, 0)
        code = {DISABLED: AXIS_DISABLED, STOPPING: AXIS_STOPPING, ERRORSTOP: AXIS_ERRORSTOP,
                HOMING: AXIS_HOMING}.get(self.state, 0)
        if code == 0 and block == HOME and self.state != STANDSTILL:
            code = NOT_STANDSTILL
        return code

    def _abort_owner(self) -> None:
        if self.owner_block:
            blk = self.blocks[self.owner_block]
            if blk.token == self.owner and blk.out.busy and not blk.pending:
                blk.pending = "aborted"
        self.owner_block = 0
        self.owner_kind = 0

    # -- one block call ---------------------------------------------------------------------
    def call(self, block: int, execute: bool, par: list[float], ipar: int, scan: int) -> Outputs:
        blk = self.blocks[block]
        if block == POWER:
            self.power = execute
            if execute and self.state == DISABLED:
                self.state = STANDSTILL
            elif not execute and self.state not in (DISABLED, ERRORSTOP):
                self._abort_owner()
                self.owner = -1  # no block's token
                self.state = DISABLED
            blk.out = Outputs(done=self.power and self.state != DISABLED, busy=execute)
            return blk.out
        if block == OVERRIDE:
            v, a, j = par[0], par[1], par[2]
            ok = 0.0 <= v <= 1.0 and 0.0 < a <= 1.0 and 0.0 < j <= 1.0
            if execute and ok:
                self.vel_factor = v
            blk.out = Outputs(done=execute and ok, busy=execute, error=execute and not ok,
                              error_id=BAD_PARAMETER if execute and not ok else 0)
            return blk.out
        if block == STATUS:
            blk.out = Outputs(busy=execute)
            return blk.out
        out = blk.out
        shown = out.done or out.error or out.aborted
        if not execute and shown:
            out.done = out.error = out.aborted = False
            out.error_id = 0
        edge = execute and not blk.last_execute
        blk.last_execute = execute
        if block == RESET:
            if edge:
                out.done = False
                if self.state == ERRORSTOP:
                    out.busy = True
                    self.reset_pending = True
                else:
                    out.done = True
            if out.busy and self.state != ERRORSTOP:
                out.busy = False
                out.done = True
            return out
        if edge:
            out.done = out.error = out.aborted = out.busy = out.active = False
            out.error_id = 0
            blk.pending = ""
            code = self.refusal(block)
            if code == 0:
                code = self._param_error(block, par, ipar)
            if code:
                out.error, out.error_id = True, code
            else:
                self._accept(block, blk, par, ipar, scan)
                out.busy = True
        if out.busy and blk.pending:
            out.busy = False
            if blk.pending == "done":
                out.done = True
            elif blk.pending == "error":
                out.error, out.error_id = True, blk.pending_code
            else:
                out.aborted = True
            blk.pending = ""
        elif out.busy and self.owner != blk.token:
            out.busy = False
            out.aborted = True
        out.active = out.busy and self.owner == blk.token and blk.issued_scan < scan
        return out

    def _param_error(self, block: int, par: list[float], ipar: int) -> int:
        def bad(x: float) -> bool:
            return not (0.0 < x <= 1.0e15)
        if block == HOME:
            if ipar != 0 or not abs(par[0]) <= 1.0e15:
                return BAD_PARAMETER
            return JOINT_LIMIT if not self.lo <= par[0] <= self.hi else 0
        if block in (ABS_A, ABS_B, REL):
            target = par[0] + (self.obs.pos if block == REL else 0.0)
            if any(bad(x) for x in par[1:5]) or ipar != 0 or not abs(target) <= 1.0e15:
                return BAD_PARAMETER
            return JOINT_LIMIT if not self.lo <= target <= self.hi else 0
        if block == VEL:
            if not 0.0 <= par[0] <= 1.0e15 or any(bad(x) for x in par[1:4]) \
                    or ipar not in (1, -1):
                return BAD_PARAMETER
            return 0
        if block == HALT:
            return BAD_PARAMETER if bad(par[0]) or bad(par[1]) or ipar != 0 else 0
        if block == STOP:
            return BAD_PARAMETER if bad(par[0]) or bad(par[1]) else 0
        raise AssertionError(block)

    def _accept(self, block: int, blk: Block, par: list[float], ipar: int, scan: int) -> None:
        if self.owner_block != block:
            self._abort_owner()
        self.next_token += 1
        blk.token = self.owner = self.next_token
        blk.issued_scan = scan
        self.owner_block = block
        self.owner_kind = block
        self.stop_done = False
        if block == HOME:
            blk.target = par[0]
            self.state = HOMING
        elif block in (ABS_A, ABS_B, REL):
            blk.target = par[0] + (self.obs.pos if block == REL else 0.0)
            self.state = DISCRETE
        elif block == VEL:
            blk.velocity = ipar * par[0]
            self.state = CONTINUOUS
        elif block == HALT:
            self.state = DISCRETE
        else:
            self.state = STOPPING

    # -- after the drive: what the set point says -------------------------------------------
    def drive(self, obs: Observed, max_vel: float) -> list[str]:
        """Advance by the drive's step given its observed result; returns the names of the
        transitions the model took (for the figures)."""
        self.obs = obs
        took: list[str] = []
        at_rest = abs(obs.vel) <= REST and abs(obs.acc) <= REST
        blk = self.blocks.get(self.owner_block) if self.owner_block else None
        kind = self.owner_kind
        if self.state == DISABLED:
            return took
        if obs.error_id == JOINT_LIMIT and self.state == CONTINUOUS:
            # an axis error: only a velocity move heading for a range end may raise it
            assert (obs.vel > 0.0) or (obs.vel < 0.0), "JointLimit at rest"
            if blk is not None and blk.token == self.owner:
                blk.pending, blk.pending_code = "error", JOINT_LIMIT
            self.owner_block = self.owner_kind = 0
            self.state = ERRORSTOP
            took.append("ContinuousMotion->ErrorStop")
        elif kind in (HOME, ABS_A, ABS_B, REL) and blk is not None and at_rest \
                and abs(obs.pos - blk.target) <= REST:
            blk.pending = "done" if blk.token == self.owner else ""
            took.append(f"{STATE_NAMES[self.state]}->Standstill")
            self.state = STANDSTILL
            self.owner_block = self.owner_kind = 0
        elif kind == HALT and blk is not None and at_rest:
            blk.pending = "done"
            self.state = STANDSTILL
            self.owner_block = self.owner_kind = 0
            took.append("DiscreteMotion->Standstill")
        elif kind == STOP and blk is not None:
            if at_rest and not self.stop_done:
                self.stop_done = True
                blk.pending = "done"
            if self.stop_done and not blk.last_execute:
                self.state = STANDSTILL
                self.owner_block = self.owner_kind = 0
                took.append("Stopping->Standstill")
        if self.reset_pending:
            if self.state != ERRORSTOP:
                self.reset_pending = False
            elif at_rest:
                self.reset_pending = False
                self.state = STANDSTILL if self.power else DISABLED
                took.append(f"ErrorStop->{STATE_NAMES[self.state]}")
        return took
