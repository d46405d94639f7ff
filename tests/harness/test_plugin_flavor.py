"""--plc-flavor: a session that speaks the wrong register layout for the PLC it is given ends
at once with one line naming the layout the PLC serves (not a time-out per test), the right
one runs; a session of OpenPLC v3 against a v4 PLC (or the other way round) ends the same way;
and the Modbus suite passes against the soft PLC serving the CODESYS layout and as OpenPLC
v4's Modbus plugin."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from armbench.demo import serve_controller

REPO = Path(__file__).resolve().parents[2]

CONTROLLER_SUITE = """
def test_one(plc):
    assert plc.hello().error_id == 0


def test_two(plc):
    assert plc.status().scan_count > 0
"""

PROGRAM = """
PROGRAM Gauge
  VAR
    Signature AT %MD0 : UDINT := 16#6A06E001;
    Level AT %MD1 : REAL;
    ScanCount AT %MD2 : UDINT;
    Twice AT %MD3 : REAL;
  END_VAR
  ScanCount := ScanCount + 1;
  Twice := Level * 2.0;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#5ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Gauge;
  END_RESOURCE
END_CONFIGURATION
"""

PROGRAM_SUITE = """
def test_typed_access(plc_vars):
    plc_vars["Level"] = 1.25
    plc_vars.wait_scans(2)
    assert plc_vars["Twice"] == 2.5
"""


def run_pytest(cwd: Path, *args: str, env: dict[str, str] | None = None,
               timeout_s: float = 120.0) -> tuple[subprocess.CompletedProcess[str], float]:
    base = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *args], cwd=cwd, env={**base, **(env or {})},
                          capture_output=True, text=True, timeout=timeout_s)
    return proc, time.monotonic() - t0


def one_line_stop(proc: subprocess.CompletedProcess[str], address: str) -> str:
    """The session's one line about the PLC; asserts nothing else ran."""
    out = proc.stdout + proc.stderr
    hits = [ln for ln in out.splitlines() if f"the PLC at {address} (--plc-address)" in ln]
    assert len(hits) == 1, out
    assert proc.returncode == 4, out
    assert "passed" not in out and "failed" not in out, out
    assert len(out.strip().splitlines()) <= 3, out
    return hits[0]


@pytest.fixture(scope="module")
def codesys_controller() -> Iterator[str]:
    with serve_controller(flavor="codesys") as running:
        yield f"{running.host}:{running.port}"


@pytest.fixture(scope="module")
def openplc_controller() -> Iterator[str]:
    with serve_controller() as running:
        yield f"{running.host}:{running.port}"


def test_openplc_session_against_a_codesys_controller(tmp_path: Path,
                                                      codesys_controller: str) -> None:
    (tmp_path / "test_suite.py").write_text(CONTROLLER_SUITE)
    proc, took = run_pytest(tmp_path, "test_suite.py", "--plc-address", codesys_controller)
    line = one_line_stop(proc, codesys_controller)
    assert line.endswith("runs the arm controller in the CODESYS variant's layout, not the "
                         "openplc one this session speaks (--plc-flavor openplc): add "
                         "--plc-flavor codesys !"), line
    # OpenPLC's %MD area lies past the device's 993 holding registers: the first read is
    # refused (exception 2), no Hello waits for its time-out
    assert took < 30.0


def test_codesys_session_against_an_openplc_controller(tmp_path: Path,
                                                       openplc_controller: str) -> None:
    (tmp_path / "test_suite.py").write_text(CONTROLLER_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", openplc_controller,
                         "--plc-flavor", "codesys")
    line = one_line_stop(proc, openplc_controller)
    assert line.endswith("runs the arm controller in OpenPLC's register map, not the codesys "
                         "one this session speaks (--plc-flavor codesys): leave out "
                         "--plc-flavor (or give --plc-flavor openplc) !"), line


@pytest.fixture(scope="module")
def v4_controller() -> Iterator[str]:
    with serve_controller(flavor="openplc-v4") as running:
        yield f"{running.host}:{running.port}"


def test_openplc_session_against_a_v4_controller(tmp_path: Path, v4_controller: str) -> None:
    """The same map, another server: told apart by a request to unit id 2."""
    (tmp_path / "test_suite.py").write_text(CONTROLLER_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", v4_controller)
    line = one_line_stop(proc, v4_controller)
    assert line.endswith("runs the arm controller, but answers as OpenPLC v4's Modbus server, "
                         "not OpenPLC v3's this session speaks (--plc-flavor openplc; a "
                         "request to unit id 2 gets exception 0x0B): add --plc-flavor "
                         "openplc-v4 !"), line


def test_v4_session_against_an_openplc_controller(tmp_path: Path,
                                                  openplc_controller: str) -> None:
    (tmp_path / "test_suite.py").write_text(CONTROLLER_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", openplc_controller,
                         "--plc-flavor", "openplc-v4")
    line = one_line_stop(proc, openplc_controller)
    assert line.endswith("runs the arm controller, but answers as OpenPLC v3's Modbus server, "
                         "not OpenPLC v4's this session speaks (--plc-flavor openplc-v4; a "
                         "request to unit id 2 is answered): leave out --plc-flavor (or give "
                         "--plc-flavor openplc) !"), line


def test_v4_session_against_a_v4_controller_runs(tmp_path: Path, v4_controller: str) -> None:
    (tmp_path / "test_suite.py").write_text(CONTROLLER_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", v4_controller,
                         "--plc-flavor", "openplc-v4")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "2 passed" in out, out


@pytest.fixture(scope="module")
def codesys_program(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, str]]:
    from armbench.harness.program import PlcProgram, serve_program

    src = tmp_path_factory.mktemp("gauge") / "gauge.st"
    src.write_text(PROGRAM)
    with serve_program(PlcProgram.load([src], library=False, flavor="codesys")) as plc:
        yield src, f"{plc.host}:{plc.port}"


def test_openplc_session_against_a_program_in_the_codesys_layout(
        tmp_path: Path, codesys_program: tuple[Path, str]) -> None:
    src, address = codesys_program
    (tmp_path / "test_suite.py").write_text(PROGRAM_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", address,
                         "--plc-program", str(src), "--plc-no-library")
    line = one_line_stop(proc, address)
    assert line.endswith("serves gauge.st in the CODESYS layout, not the OpenPLC one this "
                         "session speaks (--plc-flavor openplc): add --plc-flavor codesys !"), line


def test_codesys_session_against_a_program_in_the_codesys_layout_runs(
        tmp_path: Path, codesys_program: tuple[Path, str]) -> None:
    src, address = codesys_program
    (tmp_path / "test_suite.py").write_text(PROGRAM_SUITE)
    proc, _ = run_pytest(tmp_path, "test_suite.py", "--plc-address", address,
                         "--plc-program", str(src), "--plc-no-library",
                         "--plc-flavor", "codesys")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 passed" in out, out
    # the signature is never assigned: %I in the CODESYS variant, where it identifies nothing
    assert "Signature cannot identify gauge.st" in out and "assign it in the program " \
        "(`Signature := 16#6A06E001;`) to move it to %Q" in out, out


# The part of tests/modbus that reads and writes every kind of block through the client, raw
# words, spoofing, reconnections and ten concurrent clients; left out for CI time: the long
# motion runs (circle, sweep, five-axis, joint and linear moves), which read the same blocks.
CODESYS_SUITE = ("test_handshake.py", "test_controller.py", "test_disconnect.py",
                 "test_lut.py", "test_motion_clients.py", "test_wrist_jog_gripper.py",
                 "test_soak.py")


def test_the_modbus_suite_passes_against_the_codesys_layout() -> None:
    """tests/modbus --plc-flavor codesys against the soft PLC serving the CODESYS layout
    (the whole suite: run it so by hand; README, Testing a real PLC over Modbus)."""
    files = [str(REPO / "tests" / "modbus" / f) for f in CODESYS_SUITE]
    proc, took = run_pytest(REPO, *files, "--plc-flavor", "codesys",
                            env={"ARMBENCH_SOAK_SECONDS": "3"}, timeout_s=600.0)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    summary = re.search(r"(\d+) passed", out)
    assert summary is not None and int(summary.group(1)) >= 60, out
    assert "skipped" not in out, out
    print(f"\ntests/modbus ({len(files)} files) --plc-flavor codesys: "
          f"{summary.group(0)} in {took:.0f} s")


# OpenPLC v4: its own rules (test_modbus_openplc_v4.py) and the part of the suite that writes
# raw blocks, reconnects and runs ten clients at once (the motion files read the same blocks)
V4_SUITE = ("test_modbus_openplc_v4.py", "test_handshake.py", "test_controller.py",
            "test_disconnect.py", "test_soak.py")


def test_the_modbus_suite_passes_as_openplc_v4() -> None:
    """tests/modbus --plc-flavor openplc-v4 against the soft PLC answering as OpenPLC v4's
    Modbus plugin (the whole suite: run it so by hand; docs/modbus-parity.md)."""
    files = [str(REPO / "tests" / "modbus" / f) for f in V4_SUITE]
    proc, took = run_pytest(REPO, *files, "--plc-flavor", "openplc-v4",
                            env={"ARMBENCH_SOAK_SECONDS": "3"}, timeout_s=600.0)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    summary = re.search(r"(\d+) passed", out)
    assert summary is not None and int(summary.group(1)) >= 60, out
    assert "skipped" not in out, out
    print(f"\ntests/modbus ({len(files)} files) --plc-flavor openplc-v4: "
          f"{summary.group(0)} in {took:.0f} s")
