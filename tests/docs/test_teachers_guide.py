"""The teacher's guide's model ST solutions run in the soft PLC and give the right answers.

docs/teachers-guide.md is also a code page of test_teaching_docs.py (its Python keys run, its
ST blocks are checked one by one). Here the blocks tagged ``lab2-solution`` are put into one
file, as the guide tells the teacher to, checked with the library, served by a real-time soft
PLC with its Modbus server, and driven over Modbus; the angles are compared with the float64
reference IK of the 3-DOF arm reduced to two links (a1 = a2 = 0), which is not ST code.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_teaching_docs import DOCS, blocks

from armbench.harness.program import PlcProgram, PlcVariables, serve_program
from armbench.plant import arm

GUIDE = DOCS / "teachers-guide.md"
L1, L2 = 120.0, 130.0
PLANAR = arm.ArmGeometry(a1=0.0, a2=0.0, a3=L1, a4=L2)


def _solution_source() -> str:
    parts = [b.text for b in blocks(GUIDE) if b.info[:1] == ["st"] and "lab2-solution" in b.info]
    assert len(parts) >= 2, "the guide lost its Lab 2 model solution blocks"
    return "\n".join(parts)


@pytest.fixture(scope="module")
def planar(tmp_path_factory: pytest.TempPathFactory) -> Iterator[PlcVariables]:
    src = tmp_path_factory.mktemp("lab2") / "lab2.st"
    src.write_text(_solution_source(), encoding="utf-8")
    program = PlcProgram.load([src])  # raises CompileFailed with the diagnostics
    with serve_program(program) as plc, plc.connect() as v:
        yield v


def _solve(v: PlcVariables, x: float, z: float, elbow_up: bool) -> dict[str, float | bool]:
    v.write({"L1": L1, "L2": L2, "X": x, "Z": z, "ElbowUp": elbow_up})
    v.wait_scans(2)
    return {name: v[name] for name in ("Theta1", "Theta2", "FkX", "FkZ", "IkValid", "FkValid")}


@pytest.mark.parametrize("elbow_up", [True, False])
@pytest.mark.parametrize("x,z", [(199.29, 47.46), (150.0, 60.0), (60.0, 180.0), (30.0, -20.0),
                                 (245.0, 10.0)])
def test_planar_ik_matches_the_reference(planar: PlcVariables, x: float, z: float,
                                         elbow_up: bool) -> None:
    got = _solve(planar, x, z, elbow_up)
    base, shoulder, elbow = arm.inverse(x, 0.0, z, PLANAR, elbow_up=elbow_up)
    assert base == 0.0  # the point is in front: the planar arm's plane
    assert got["IkValid"] and got["FkValid"]
    assert math.isclose(float(got["Theta1"]), shoulder, abs_tol=2e-3)
    assert math.isclose(float(got["Theta2"]), elbow - 180.0, abs_tol=2e-3)
    assert math.dist((float(got["FkX"]), float(got["FkZ"])), (x, z)) < 2e-3


def test_the_labs_own_pose_comes_back(planar: PlcVariables) -> None:
    # Lab 2 step 2: Theta1 = 50, Theta2 = -70 puts the tool at about (199.29, 47.46).
    x = L1 * math.cos(math.radians(50.0)) + L2 * math.cos(math.radians(-20.0))
    z = L1 * math.sin(math.radians(50.0)) + L2 * math.sin(math.radians(-20.0))
    got = _solve(planar, x, z, True)
    assert math.isclose(float(got["Theta1"]), 50.0, abs_tol=2e-3)
    assert math.isclose(float(got["Theta2"]), -70.0, abs_tol=2e-3)


@pytest.mark.parametrize("x,z", [(260.0, 0.0), (5.0, 0.0), (0.0, 0.0)])
def test_points_outside_the_ring_are_invalid(planar: PlcVariables, x: float, z: float) -> None:
    got = _solve(planar, x, z, True)
    assert not got["IkValid"]
    assert (got["Theta1"], got["Theta2"]) == (0.0, 0.0)


def test_a_bad_link_length_is_invalid(planar: PlcVariables) -> None:
    planar.write({"L1": 0.0, "X": 150.0, "Z": 60.0})
    planar.wait_scans(2)
    assert not planar["IkValid"] and not planar["FkValid"]
    assert (planar["FkX"], planar["FkZ"]) == (0.0, 0.0)


def test_the_solution_is_one_file_as_the_guide_says(tmp_path: Path) -> None:
    # The guide tells the teacher to paste the tagged blocks into one file: it has a
    # CONFIGURATION, so armbench run/serve can start it as it is.
    text = _solution_source()
    assert "CONFIGURATION" in text and "PROGRAM Planar2Test" in text
