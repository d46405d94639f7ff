"""The PLCopen axis-group layer (st/AMCGroup*.st) from outside.

1. A hypothesis stateful test: random sequences on one group of three axes -- axes powered on
   and off, moved, driven into a range end (ErrorStop), reset; GroupEnable, GroupDisable,
   GroupReset, SetKinTransform with good and bad models and geometries, in random call
   orders -- through the bench-compiled ST (amc_group_bench.py). Every scan checks every group
   block's outputs and the group state against plcopen_group_model.py (written from PLCopen
   Part 4 and the documented choices), Busy/Done/Error exclusive, ErrorIDs from the list,
   ReadStatus (one flag, the model's state), ReadError, and ReadActualPosition: the joint
   positions the axes had, and the Cartesian position against the closed-form forward
   kinematics of seed 002's arm (float32 tolerance).
2. Directed: the axis-error rule (a velocity move into the range end stops the group, the
   group reset resets the axis too), AxisCount outside 1..6, Arm3Dof on two axes.
"""

from __future__ import annotations

import math
import os
import random
from typing import Any

import pytest

hypothesis = pytest.importorskip("hypothesis")
from amc_group_bench import (  # noqa: E402
    AXES,
    G_DISABLE,
    G_ENABLE,
    G_RESET,
    G_SETKIN,
    compile_group_bench,
)
from amc_group_stateful import GEO, MODEL_BLOCKS, GroupMachine, random_geo, random_run, settle  # noqa: E402
from hypothesis import settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.stateful import RuleBasedStateMachine, rule, run_state_machine_as_test  # noqa: E402
from plcopen_group_model import G_ERRORSTOP, G_STANDBY, GROUP_AXIS_ERROR, KIN_ARM3  # noqa: E402


@pytest.fixture(scope="module")
def group_module(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return compile_group_bench(tmp_path_factory.mktemp("amcgroup"))


def test_random_sequences_follow_the_group_model(group_module: Any) -> None:
    runs: list[GroupMachine] = []

    class PlcopenGroup(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            self.m = GroupMachine(group_module)
            runs.append(self.m)
            self.m.power = [True] * AXES

        @rule(axis=st.integers(0, AXES - 1), what=st.integers(0, 3),
              seed=st.integers(0, 2**32 - 1))
        def axis_block(self, axis: int, what: int, seed: int) -> None:
            rng = random.Random(seed)
            m = self.m
            if what == 0:
                m.power[axis] = rng.random() < 0.7
            elif what == 1:
                m.move[axis] = not m.move[axis]
                m.move_pos[axis] = rng.uniform(-85.0, 85.0)
            elif what == 2:
                m.vel[axis] = not m.vel[axis]
                m.vel_dir[axis] = rng.choice((1, -1))
            else:
                m.reset[axis] = not m.reset[axis]

        @rule(block=st.integers(1, MODEL_BLOCKS), seed=st.integers(0, 2**32 - 1))
        def group_block(self, block: int, seed: int) -> None:
            rng = random.Random(seed)
            m = self.m
            m.gexec[block - 1] = not m.gexec[block - 1]
            if block == G_SETKIN:
                m.kin = rng.choice((0, 1, 1, 1, 2, -1))
                m.geo = random_geo(rng) if rng.random() < 0.5 else dict(GEO)

        @rule(seed=st.integers(0, 2**32 - 1))
        def settle_axes(self, seed: int) -> None:
            settle(self.m, random.Random(seed))

        @rule(scans=st.sampled_from([1, 1, 2, 5, 20, 80]), shuffle=st.integers(0, 2**32 - 1))
        def run(self, scans: int, shuffle: int) -> None:
            order = list(range(1, MODEL_BLOCKS + 1))
            if shuffle % 2 == 0:
                random.Random(shuffle).shuffle(order)
            for k in range(scans):
                self.m.scan(order if k == 0 else None)

    run_state_machine_as_test(PlcopenGroup, settings=settings(
        max_examples=int(os.environ.get("AMC_GROUP_STATEFUL_EXAMPLES", "10")),
        stateful_step_count=40, deadline=None, derandomize=True, database=None))
    scans = sum(r.fig.scans for r in runs)
    calls = sum(r.fig.calls for r in runs)
    checks = sum(r.fig.checks for r in runs)
    seen: dict[str, int] = {}
    for r in runs:
        for k, v in r.fig.transitions.items():
            seen[k] = seen.get(k, 0) + v
    print(f"\ngroup stateful: {len(runs)} runs, {scans} scans, {calls} group block calls, "
          f"{checks} checks; transitions {seen}")
    assert scans > 500
    assert seen.get("GroupStandby->GroupErrorStop", 0) > 0, seen


def test_long_random_run_visits_the_group_diagram(group_module: Any) -> None:
    seen: dict[str, int] = {}
    scans = calls = checks = 0
    for seed in range(6):
        m = GroupMachine(group_module)
        random_run(m, random.Random(seed), 1500)
        scans, calls, checks = scans + m.fig.scans, calls + m.fig.calls, checks + m.fig.checks
        for k, v in m.fig.transitions.items():
            seen[k] = seen.get(k, 0) + v
    print(f"\ngroup random runs: {scans} scans, {calls} group block calls, {checks} checks; "
          f"transitions {seen}")
    for t in ("GroupDisabled->GroupStandby", "GroupStandby->GroupErrorStop",
              "GroupErrorStop->GroupStandby", "GroupErrorStop->GroupDisabled",
              "GroupStandby->GroupDisabled"):
        assert seen.get(t, 0) > 0, (t, seen)


def test_axis_error_stops_the_group_and_group_reset_recovers(group_module: Any) -> None:
    m = GroupMachine(group_module)
    m.power = [True] * AXES
    m.scan()
    m.kin, m.gexec[G_SETKIN - 1] = KIN_ARM3, True
    m.gexec[G_ENABLE - 1] = True
    m.scan()
    assert m.model.state == G_STANDBY and m.fb.GDone[G_ENABLE - 1] and m.fb.GDone[G_SETKIN - 1]
    m.vel[1], m.vel_dir[1] = True, 1
    for _ in range(400):
        m.scan()
        if m.model.state == G_ERRORSTOP:
            break
    assert int(m.fb.GOut["State"]) == G_ERRORSTOP
    assert (int(m.fb.RdGroupErr), int(m.fb.RdErrAxis), int(m.fb.RdAxisErr)) == (
        GROUP_AXIS_ERROR, 2, 10)
    m.vel[1] = False
    m.gexec[G_ENABLE - 1] = False
    m.scan()
    m.gexec[G_ENABLE - 1] = True   # refused in GroupErrorStop
    m.gexec[G_RESET - 1] = True
    for _ in range(300):
        m.scan()
        if m.fb.GDone[G_RESET - 1]:
            break
    assert m.fb.GErr[G_ENABLE - 1] and int(m.fb.GErrId[G_ENABLE - 1]) == 56
    assert int(m.fb.GOut["State"]) == G_STANDBY and m.fb.GDone[G_RESET - 1]
    assert int(m.fb.AxOut[1]["State"]) == 1 and int(m.fb.AxOut[1]["AxisErrorId"]) == 0
    m.gexec[G_DISABLE - 1] = True
    m.scan()
    assert int(m.fb.GOut["State"]) == 0
    print(f"\naxis-error rule: {m.fig.scans} scans, {m.fig.checks} checks")


@pytest.mark.parametrize("count", [0, 7, -1])
def test_axis_count_outside_the_range_is_refused(group_module: Any, count: int) -> None:
    m = GroupMachine(group_module, axis_count=count)
    m.power = [True] * AXES
    m.scan()
    m.gexec[G_ENABLE - 1] = True
    m.scan()
    assert m.fb.GErr[G_ENABLE - 1] and int(m.fb.GErrId[G_ENABLE - 1]) == 8
    assert int(m.fb.GOut["State"]) == 0


def test_arm3dof_needs_three_axes(group_module: Any) -> None:
    m = GroupMachine(group_module, axis_count=2)
    m.kin, m.gexec[G_SETKIN - 1] = KIN_ARM3, True
    m.scan()
    assert m.fb.GErr[G_SETKIN - 1] and int(m.fb.GErrId[G_SETKIN - 1]) == 8
    assert int(m.fb.GOut["KinModel"]) == 0


@pytest.mark.parametrize(("kin", "change", "code"),
                         [(KIN_ARM3, {"A3": 0.0}, 4), (KIN_ARM3, {"A4": -5.0}, 4),
                          (KIN_ARM3, {"A1": math.nan}, 4), (2, {}, 8), (-1, {}, 8)])
def test_set_kin_transform_refuses_bad_models(group_module: Any, kin: int,
                                              change: dict[str, float], code: int) -> None:
    m = GroupMachine(group_module)
    m.kin, m.geo, m.gexec[G_SETKIN - 1] = kin, {**GEO, **change}, True
    m.scan()
    assert m.fb.GErr[G_SETKIN - 1] and int(m.fb.GErrId[G_SETKIN - 1]) == code
    assert int(m.fb.GOut["KinModel"]) == 0 and not m.fb.RdCartValid
