"""An independent Python model of the PLCopen Motion Control Part 4 group state diagram as the
axis-group layer (st/AMCGroup*.st) implements it so far: GroupEnable, GroupDisable, GroupReset,
SetKinTransform and the rule that an axis error (or an axis switched off) stops the group.
Written from PLCopen Part 4 and the layer's documented choices (docs/plcopen-motion.md), not
from the ST. The axes are not modelled here (plcopen_model.py does that): the model takes the
axis states the group blocks saw as its input.
"""

from __future__ import annotations

from dataclasses import dataclass, field

G_DISABLED, G_STANDBY, G_MOVING, G_HOMING, G_STOPPING, G_ERRORSTOP = range(6)
GROUP_STATE_NAMES = ["GroupDisabled", "GroupStandby", "GroupMoving", "GroupHoming",
                     "GroupStopping", "GroupErrorStop"]
AX_DISABLED, AX_STANDSTILL, AX_ERRORSTOP = 0, 1, 6
BAD_GEOMETRY, BAD_PARAMETER = 4, 8
GROUP_DISABLED, GROUP_ERRORSTOP, AXIS_NOT_READY, GROUP_AXIS_ERROR, GROUP_NOT_STANDBY = (
    55, 56, 57, 58, 59)
ENABLE, DISABLE, RESET, SETKIN = 1, 2, 3, 4
KIN_NONE, KIN_ARM3 = 0, 1
ERROR_LIST = {0, BAD_GEOMETRY, BAD_PARAMETER, GROUP_DISABLED, GROUP_ERRORSTOP, AXIS_NOT_READY,
              GROUP_AXIS_ERROR, GROUP_NOT_STANDBY}


@dataclass
class GOutputs:
    done: bool = False
    busy: bool = False
    error: bool = False
    error_id: int = 0


@dataclass
class GBlock:
    last_execute: bool = False
    out: GOutputs = field(default_factory=GOutputs)


def geometry_ok(g: dict[str, float]) -> bool:
    """ArmGeometryCheck's documented rule: a3 > 0, a4 > 0, all finite within 1e6 mm."""
    vals = [g["A1"], g["A2"], g["A3"], g["A4"]]
    return all(abs(v) <= 1.0e6 for v in vals) and g["A3"] > 0.0 and g["A4"] > 0.0


@dataclass
class GroupModel:
    axis_count: int = 3
    state: int = G_DISABLED
    error_id: int = 0
    error_axis: int = 0
    reset_req: bool = False
    kin_model: int = KIN_NONE
    geo: dict[str, float] = field(default_factory=dict)
    blocks: dict[int, GBlock] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.blocks = {b: GBlock() for b in (ENABLE, DISABLE, RESET, SETKIN)}

    def enabled(self) -> bool:
        return self.state in (G_STANDBY, G_MOVING, G_HOMING, G_STOPPING)

    def call(self, block: int, execute: bool, axes: list[int], kin: int,
             geo: dict[str, float]) -> GOutputs:
        """One call of a group block; axes = the axis states it sees."""
        blk = self.blocks[block]
        out = blk.out
        if not execute and (out.done or out.error):
            out.done = out.error = False
            out.error_id = 0
        edge = execute and not blk.last_execute
        blk.last_execute = execute
        if block == RESET:
            if edge:
                out.done = False
                if self.state == G_ERRORSTOP:
                    out.busy = True
                    self.reset_req = True
                else:
                    out.done = True
            if out.busy and self.state != G_ERRORSTOP:
                out.busy, out.done = False, True
            return GOutputs(out.done, out.busy, out.error, out.error_id)
        if not edge:
            return GOutputs(out.done, out.busy, out.error, out.error_id)
        out.done = out.error = False
        out.error_id = 0
        code = 0
        if block == ENABLE:
            if self.state == G_ERRORSTOP:
                code = GROUP_ERRORSTOP
            elif self.state == G_DISABLED:
                if not 1 <= self.axis_count <= 6:
                    code = BAD_PARAMETER
                elif any(s != AX_STANDSTILL for s in axes[:self.axis_count]):
                    code = AXIS_NOT_READY
                else:
                    self.state, self.error_id, self.error_axis = G_STANDBY, 0, 0
        elif block == DISABLE:
            self.state, self.error_id, self.error_axis = G_DISABLED, 0, 0
            self.reset_req = False
        elif block == SETKIN:
            if self.state == G_ERRORSTOP:
                code = GROUP_ERRORSTOP
            elif self.state not in (G_DISABLED, G_STANDBY):
                code = GROUP_NOT_STANDBY
            elif kin == KIN_ARM3:
                if self.axis_count != 3:
                    code = BAD_PARAMETER
                elif not geometry_ok(geo):
                    code = BAD_GEOMETRY
            elif kin != KIN_NONE:
                code = BAD_PARAMETER
            if code == 0:
                self.kin_model, self.geo = kin, dict(geo)
        out.error, out.error_id, out.done = code != 0, code, code == 0
        return GOutputs(out.done, out.busy, out.error, out.error_id)

    def monitor(self, axes: list[int]) -> None:
        """The per-scan rules, given the axis states the monitor sees."""
        mine = axes[:self.axis_count] if 1 <= self.axis_count <= 6 else []
        if self.reset_req:
            if self.state != G_ERRORSTOP:
                self.reset_req = False
            elif AX_ERRORSTOP not in mine:
                self.reset_req = False
                self.error_id = self.error_axis = 0
                ok = bool(mine) and all(s == AX_STANDSTILL for s in mine)
                self.state = G_STANDBY if ok else G_DISABLED
        bad = [k + 1 for k, s in enumerate(mine) if s in (AX_ERRORSTOP, AX_DISABLED)]
        if self.enabled() and bad:
            self.state, self.error_id, self.error_axis = G_ERRORSTOP, GROUP_AXIS_ERROR, bad[0]
