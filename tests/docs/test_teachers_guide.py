"""The teacher's guide's model ST solutions run in the soft PLC and give the right answers.

docs/teachers-guide.md is also a code page of test_teaching_docs.py (its Python keys run, its
ST blocks are checked one by one). Here the blocks of each model solution (tagged
``lab2-solution``: Lab 2 Q3 and Q4; ``lab2-fixes``: the fixed snippets of Lab 2 step 3) are
put into one file, as the guide tells the teacher to, run through ``armbench check``, served
by a real-time soft PLC with its Modbus server, and driven over Modbus. The answers are
compared with references that are not ST code: the float64 reference IK of the 3-DOF arm
reduced to two links (a1 = a2 = 0) for Q4, ``math`` and numpy's float32 arithmetic for the
fixes.

The ST exercises of the course are all in Lab 2 (the other labs have the student run,
measure and explain, not write ST): step 3's snippets to fix, and Q3 and Q4.
``test_every_broken_snippet_has_a_model_fix`` keeps that list and the guide in step.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from test_teaching_docs import DOCS, blocks

from armbench import cli
from armbench.harness.program import PlcProgram, PlcVariables, serve_program
from armbench.plant import arm

GUIDE = DOCS / "teachers-guide.md"
LAB2 = DOCS / "labs" / "lab2-st-portability.md"
L1, L2 = 120.0, 130.0
PLANAR = arm.ArmGeometry(a1=0.0, a2=0.0, a3=L1, a4=L2)
SOLUTIONS = ("lab2-solution", "lab2-fixes")
_POU = re.compile(r"^\s*(?:FUNCTION|FUNCTION_BLOCK|PROGRAM)\s+(\w+)", re.M)


def _tagged(tag: str) -> list[str]:
    parts = [b.text for b in blocks(GUIDE) if b.info[:1] == ["st"] and tag in b.info]
    assert len(parts) >= 2, f"the guide lost its model solution blocks tagged {tag}"
    return parts


def _solution_source(tag: str = "lab2-solution") -> str:
    return "\n".join(_tagged(tag))


def _serve(tmp_path_factory: pytest.TempPathFactory, tag: str) -> Iterator[PlcVariables]:
    src = tmp_path_factory.mktemp(tag) / f"{tag}.st"
    src.write_text(_solution_source(tag), encoding="utf-8")
    program = PlcProgram.load([src])  # raises CompileFailed with the diagnostics
    with serve_program(program) as plc, plc.connect() as v:
        yield v


@pytest.fixture(scope="module")
def planar(tmp_path_factory: pytest.TempPathFactory) -> Iterator[PlcVariables]:
    yield from _serve(tmp_path_factory, "lab2-solution")


@pytest.fixture(scope="module")
def fixes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[PlcVariables]:
    yield from _serve(tmp_path_factory, "lab2-fixes")


@pytest.mark.parametrize("tag", SOLUTIONS)
def test_armbench_check_passes_the_solution(tag: str, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    # The command the guide tells the teacher to run, on the file the guide says to paste.
    src = tmp_path / f"{tag}.st"
    src.write_text(_solution_source(tag), encoding="utf-8")
    code = cli.main(["check", str(src)])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    assert re.search(r": 0 errors$", err.strip()), err


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


# --------------------------------------------------------------------------- Lab 2 step 3

def test_every_broken_snippet_has_a_model_fix() -> None:
    # Each failing snippet of the lab is an exercise; its POUs must be declared by a model fix.
    broken = {name.upper() for b in blocks(LAB2) if b.info[:2] == ["st", "fail"]
              for name in _POU.findall(b.text)}
    fixed = {name.upper() for text in _tagged("lab2-fixes") for name in _POU.findall(text)}
    assert len(broken) >= 8, broken
    assert broken <= fixed, f"snippets of Lab 2 without a model fix: {sorted(broken - fixed)}"


def _run(v: PlcVariables, **inputs: float | int) -> dict[str, float | int | bool]:
    v.write(inputs)
    v.wait_scans(2)
    return dict(v.read("Reach", "Angle", "Half", "Steps", "Sum", "Value", "Elbow", "LenOut",
                       "ReadingOk"))


def _scans_and_calls(v: PlcVariables) -> tuple[int, int]:
    """ScanCount and Calls from one Modbus request: the PLC answers a request between two
    scans, so both come from the same scan (two requests could straddle one)."""
    scans, calls = v.program.variable("ScanCount"), v.program.variable("Calls")
    assert calls.address == scans.address + scans.count, "the guide moved Calls away"
    words = v.client.read_holding_registers(scans.address, scans.count + calls.count)
    return int(scans.decode(words[:scans.count])), int(calls.decode(words[scans.count:]))


def _f32(x: float) -> float:
    return float(np.float32(x))


@pytest.mark.parametrize("x,z", [(3.0, 4.0), (-120.5, 33.25), (1e-3, -2e-3), (0.0, 0.0),
                                 (250.0, -0.5), (-7.0, -24.0), (0.0, 90.0), (-60.0, 0.0)])
def test_reach_and_angle(fixes: PlcVariables, x: float, z: float) -> None:
    got = _run(fixes, X=x, Z=z)
    reach = math.hypot(x, z)
    assert math.isclose(float(got["Reach"]), reach, rel_tol=3e-7, abs_tol=1e-12)
    # ArcTan2(0, 0) is 0 by the library's contract, as is math.atan2(0.0, 0.0)
    assert math.isclose(float(got["Angle"]), math.atan2(z, x), abs_tol=1e-6)


@pytest.mark.parametrize("length", [250.0, 0.0, -3.5, 1e-30, 12345.678])
def test_half(fixes: PlcVariables, length: float) -> None:
    assert _run(fixes, L=length)["Half"] == _f32(length) / 2.0  # halving a float is exact


@pytest.mark.parametrize("n", [-32768, -7, 0, 1, 32767])
def test_steps(fixes: PlcVariables, n: int) -> None:
    assert _run(fixes, N=n)["Steps"] == float(n)  # every INT is exact in REAL


@pytest.mark.parametrize("v1,v2", [(1.5, 2.25), (0.1, 0.2), (-1e6, 1e-3), (3.0e38, 3.0e38)])
def test_sum(fixes: PlcVariables, v1: float, v2: float) -> None:
    with np.errstate(over="ignore"):
        want = float(np.float32(v1) + np.float32(v2))  # IEEE single, as REAL adds
    assert _run(fixes, V1=v1, V2=v2)["Sum"] == want


@pytest.mark.parametrize("raw", [123, 0, -32768, 32767, -5])
def test_sampler_scales_and_counts(fixes: PlcVariables, raw: int) -> None:
    got = _run(fixes, Raw=raw)
    assert got["Value"] == float(np.float32(raw) * np.float32(0.1))
    assert got["ReadingOk"] is True
    # one call per scan since the PLC started: the VAR_IN_OUT counter is the block's own
    scans, calls = _scans_and_calls(fixes)
    assert calls == scans >= 2
    fixes.wait_scans(3)
    assert _scans_and_calls(fixes)[1] >= calls + 3


@pytest.mark.parametrize("t,a3", [(0.0, 120.0), (math.pi / 3, 120.0), (math.pi / 2, 120.0),
                                  (2.5, 87.5), (-1.0, 300.0)])
def test_elbow_takes_the_geometry_as_input(fixes: PlcVariables, t: float, a3: float) -> None:
    got = _run(fixes, T=t, A3=a3)
    assert math.isclose(float(got["Elbow"]), a3 * math.cos(t), abs_tol=4e-7 * a3)


@pytest.mark.parametrize("length", [42.0, -1.25, 0.0])
def test_len_renamed(fixes: PlcVariables, length: float) -> None:
    assert _run(fixes, Length=length)["LenOut"] == length


# --------------------------------------------------------------------------- a key per question

# A lab asks its questions in a "## Questions" list (1. 2. ...) or inline in its steps,
# numbered ("**Question 1.**" or "*Question 1.*"); the guide answers each in its "## Lab N"
# section with a paragraph that opens "**QN." or "**QN (step M).".
LABS = sorted((DOCS / "labs").glob("lab*.md"))
_LAB_FILE = re.compile(r"^lab(\d+)-")
_FENCES = re.compile(r"^```.*?^```\s*$", re.S | re.M)
_INLINE_QUESTION = re.compile(r"(?:^|\s)\*{1,2}Question (\d+)\.\*{1,2}", re.M)
_LISTED_QUESTION = re.compile(r"^(\d+)\. ", re.M)
_KEY = re.compile(r"^\*\*Q(\d+)[.\s]", re.M)


def _lab_questions(page: Path) -> list[int]:
    text = _FENCES.sub("", page.read_text(encoding="utf-8"))
    found = [int(n) for n in _INLINE_QUESTION.findall(text)]
    section = re.search(r"^## Questions\s*$(.*?)(?=^## |\Z)", text, re.M | re.S)
    if section:
        found += [int(n) for n in _LISTED_QUESTION.findall(section.group(1))]
    return found


def _guide_keys() -> dict[int, list[int]]:
    text = _FENCES.sub("", GUIDE.read_text(encoding="utf-8"))
    return {int(m.group(1)): [int(n) for n in _KEY.findall(m.group(2))]
            for m in re.finditer(r"^## Lab (\d+)\b.*?$(.*?)(?=^## |\Z)", text, re.M | re.S)}


def test_the_labs_are_numbered_and_ask_numbered_questions() -> None:
    numbers = [int(m.group(1)) for p in LABS if (m := _LAB_FILE.match(p.name))]
    assert numbers == list(range(1, len(LABS) + 1)), [p.name for p in LABS]
    for page in LABS:
        asked = _lab_questions(page)
        assert asked and asked == list(range(1, len(asked) + 1)), (
            f"{page.name}: questions {asked}; number them 1, 2, ... (see the comment above)")


@pytest.mark.parametrize("page", LABS, ids=lambda p: p.stem)
def test_every_lab_question_has_a_key(page: Path) -> None:
    match = _LAB_FILE.match(page.name)
    assert match, f"{page.name}: name a lab labN-topic.md"
    lab = int(match.group(1))
    keys = _guide_keys()
    assert lab in keys, f"the teacher's guide has no '## Lab {lab}' section"
    asked, keyed = set(_lab_questions(page)), keys[lab]
    assert asked, f"{page.name} asks no question the test can find"
    assert len(keyed) == len(set(keyed)), f"Lab {lab}: a question keyed twice: {keyed}"
    assert asked == set(keyed), (
        f"Lab {lab}: questions without a key {sorted(asked - set(keyed))}, "
        f"keys without a question {sorted(set(keyed) - asked)}")
