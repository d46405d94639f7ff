"""The plugin's fixtures for a user's own program, run as a user runs them (pytest in a
subprocess): the README's worked example (examples/my_program) on the soft PLC and on a PLC
found by address, and one line ending the session when that PLC runs another program, does
not scan, or the program is not given or does not compile."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from armbench.demo import serve_controller
from armbench.harness.program import PlcProgram, ProgramPlc, serve_program

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "my_program"
SIM = Path(__file__).resolve().parents[2] / "sim"


def run_pytest(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    env["PYTHONPATH"] = os.pathsep.join([str(SIM), env.get("PYTHONPATH", "")]).rstrip(
        os.pathsep)
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def one_line_stop(proc: subprocess.CompletedProcess[str], *parts: str) -> str:
    """The one line that ended the session; asserts no test ran."""
    out = proc.stdout + proc.stderr
    hits = [ln for ln in out.splitlines() if "armbench: " in ln]
    assert len(hits) == 1, out
    assert proc.returncode == 4, out
    assert " passed" not in out and " failed" not in out, out
    for part in parts:
        assert part in hits[0], hits[0]
    return hits[0]


@pytest.fixture(scope="module")
def tank() -> PlcProgram:
    return PlcProgram.load([EXAMPLE / "tank.st"], library=False)


@pytest.fixture()
def tank_plc(tank: PlcProgram) -> Iterator[ProgramPlc]:
    """A soft PLC running the example, standing in for a real PLC found by address."""
    with serve_program(tank) as running:
        yield running


def test_the_readme_example_passes_on_the_soft_plc() -> None:
    proc = run_pytest(EXAMPLE, "-q")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "6 passed" in proc.stdout
    assert "armbench: program tank.st on a soft PLC per test module" not in proc.stdout  # -q


def test_the_readme_example_from_the_repository_root() -> None:
    # as CI and the README run it: the example's pytest.ini gives plc_program = tank.st
    proc = run_pytest(ROOT, "examples/my_program")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "armbench: program tank.st on a soft PLC per test module" in proc.stdout
    assert "6 passed" in proc.stdout


def test_the_same_tests_against_a_plc_by_address(tank_plc: ProgramPlc) -> None:
    proc = run_pytest(EXAMPLE, "-q", "--plc-address", f"{tank_plc.host}:{tank_plc.port}")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "6 passed" in proc.stdout
    assert "Warning" not in proc.stdout  # the signature was checked


def test_a_plc_running_another_program_stops_the_session() -> None:
    with serve_controller() as controller:
        address = f"{controller.host}:{controller.port}"
        proc = run_pytest(EXAMPLE, "-q", "--plc-address", address)
    one_line_stop(proc, f"the PLC at {address} (--plc-address) runs another program (or "
                        "another version of tank.st): Signature at %MD0 reads 16#",
                  "tank.st declares 16#7A4B0001")


def test_a_plc_that_does_not_scan_stops_the_session(tank_plc: ProgramPlc) -> None:
    assert tank_plc.soft is not None
    tank_plc.soft.halt()  # answers Modbus, runs no scan: an OpenPLC left in STOP
    address = f"{tank_plc.host}:{tank_plc.port}"
    proc = run_pytest(EXAMPLE, "-q", "--plc-address", address)
    one_line_stop(proc, f"the PLC at {address} (--plc-address) does not scan tank.st: its "
                        "scan counter ScanCount (%MD1) stays at ")


def test_a_plc_that_does_not_answer_stops_the_session() -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = run_pytest(EXAMPLE, "-q", "--plc-address", f"127.0.0.1:{port}")
    one_line_stop(proc, f"the PLC at 127.0.0.1:{port} (--plc-address) does not answer: ")


SUITE = """
def test_reads(plc_vars):
    assert plc_vars["Count"] >= 0
"""

COUNTER = """
PROGRAM Counter
  VAR
    Count AT %MD0 : UDINT;
  END_VAR
  Count := Count + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Counter;
  END_RESOURCE
END_CONFIGURATION
"""


def test_without_a_signature_the_plc_by_address_is_used_with_a_warning(
        tmp_path: Path) -> None:
    (tmp_path / "counter.st").write_text(COUNTER)
    (tmp_path / "test_counter.py").write_text(SUITE)
    program = PlcProgram.load([tmp_path / "counter.st"], library=False)
    with serve_program(program) as running:
        proc = run_pytest(tmp_path, "-q", "test_counter.py", "--plc-address",
                          f"{running.host}:{running.port}", "--plc-no-library",
                          "--plc-program", "counter.st")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed, 1 warning" in proc.stdout
    assert "ProgramIdentityWarning: counter.st declares no Signature variable" in proc.stdout


@pytest.mark.parametrize(("files", "options", "parts"), [
    ({}, [], ["need your program: --plc-program FILE.st"]),
    ({}, ["--plc-program", "nothere.st"], ["--plc-program: no such file: nothere.st"]),
    ({"counter.st": COUNTER}, ["--plc-no-library", "--plc-program", "counter.st",
                               "test_counter.py"],
     ["--plc-program: test_counter.py is not an .st file (test paths go before"]),
    ({"bad.st": COUNTER.replace("Count + 1", "Count + Missing")},
     ["--plc-no-library", "--plc-program", "bad.st"], ["--plc-program does not compile:"]),
    ({"bad.st": COUNTER.replace("Count + 1", "Count + Missing")}, ["--plc-program", "bad.st"],
     ["bad.st:6:", "'Missing' is not declared", "compiled together with the armbench ST "
      "library; --plc-no-library (plc_no_library = true in the ini file) leaves it out"]),
    ({"counter.st": COUNTER}, ["--plc-no-library", "--plc-program", "counter.st",
                               "--plc-signature", "Ident"],
     ["--plc-program: the program declares no located variable Ident"]),
])
def test_usage_errors_are_one_line(tmp_path: Path, files: dict[str, str], options: list[str],
                                   parts: list[str]) -> None:
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "test_counter.py").write_text(SUITE)
    proc = run_pytest(tmp_path, "-q", "test_counter.py", *options)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4, out
    assert " passed" not in out and " failed" not in out, out
    assert "Traceback" not in out
    for part in parts:
        assert part in out, out


def test_the_command_line_overrides_the_ini_file(tmp_path: Path) -> None:
    (tmp_path / "counter.st").write_text(COUNTER)
    (tmp_path / "pytest.ini").write_text("[pytest]\nplc_program = missing.st\n")
    (tmp_path / "test_counter.py").write_text(SUITE)
    proc = run_pytest(tmp_path, "-q", "--plc-no-library", "--plc-program=counter.st")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = run_pytest(tmp_path, "-q", "--plc-no-library")
    one_line = [ln for ln in proc.stderr.splitlines() if "missing.st" in ln]
    assert proc.returncode == 4 and one_line == ["ERROR: plc_program (ini): no such file: "
                                                 f"{tmp_path / 'missing.st'}"], proc.stderr


def test_the_readmes_excerpts_are_the_example_files() -> None:
    """Every README block whose info string names a file under examples/ is a verbatim
    excerpt of that file, so the README shows the code the repository's suite runs."""
    import re

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    fences = re.findall(r"^```\w+ (examples/\S+)\n(.*?)^```\s*$", readme, re.S | re.M)
    assert {name for name, _ in fences} == {"examples/my_program/tank.st",
                                            "examples/my_program/pytest.ini",
                                            "examples/my_program/test_tank.py"}
    for name, text in fences:
        assert text in (ROOT / name).read_text(encoding="utf-8"), name


def test_the_readme_shows_the_whole_configuration() -> None:
    """A program runs only under a CONFIGURATION (Config0, Res0, a periodic TASK, the PROGRAM
    instance WITH it): the README's own-program section shows tank.st's, whole, so a reader
    who copies the excerpts has a program every command runs."""
    import re

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## Testing your own program with pytest", 1)[1].split("\n## ", 1)[0]
    shown = re.findall(r"^```st examples/my_program/tank.st\n(.*?)^```\s*$", section, re.S | re.M)
    tank = (EXAMPLE / "tank.st").read_text(encoding="utf-8")
    config = re.search(r"^CONFIGURATION .*?^END_CONFIGURATION\n", tank, re.S | re.M)
    assert config is not None
    assert config.group(0) in shown
    assert re.search(r"TASK \w+\(INTERVAL := T#\w+", config.group(0))
    assert re.search(r"PROGRAM \w+ WITH \w+ : TankControl;", config.group(0))


COUNTER = """
PROGRAM Counter
  VAR
    Count AT %MD0 : DINT;
  END_VAR
  Count := Count + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Main WITH MainTask : Counter;
  END_RESOURCE
END_CONFIGURATION
"""

NEVER = """
def test_waits_for_what_never_comes(plc_vars):
    plc_vars.wait_until("Count", lambda v: v < 0)
"""


def test_the_wait_timeout_by_option_and_by_ini(tmp_path: Path) -> None:
    """--plc-wait-timeout, else plc_wait_timeout in the ini file, is how long plc_vars' waits
    wait; the failure names the condition, the last value and how to raise the limit."""
    (tmp_path / "counter.st").write_text(COUNTER)
    (tmp_path / "test_waits.py").write_text(NEVER)
    ini = tmp_path / "pytest.ini"
    ini.write_text("[pytest]\nplc_program = counter.st\nplc_no_library = true\n")
    said = ("wait_until('Count', lambda v: v < 0 (test_waits.py:3)) gave up after {} s: Count "
            "last read ")
    for setting, limit in ((["--plc-wait-timeout", "0.3"], "0.3"), ([], "0.4")):
        if not setting:
            ini.write_text(ini.read_text() + "plc_wait_timeout = 0.4\n")
        proc = run_pytest(tmp_path, "-q", *setting)
        out = proc.stdout + proc.stderr
        assert proc.returncode == 1 and "1 failed" in out, out
        assert said.format(limit) in out, out
        assert f"--plc-wait-timeout {float(limit) * 4:g}" in out, out
    ini.write_text(ini.read_text().replace("plc_wait_timeout = 0.4", "plc_wait_timeout = soon"))
    proc = run_pytest(tmp_path, "-q")
    assert proc.returncode == 4, proc.stdout + proc.stderr
    assert "plc_wait_timeout (ini) is 'soon'" in proc.stderr, proc.stderr
    proc = run_pytest(tmp_path, "-q", "--plc-wait-timeout", "0")
    assert proc.returncode == 4 and "must be a number of seconds above 0" in proc.stderr, \
        proc.stderr


def test_the_readme_shows_a_waits_real_timeout_message() -> None:
    import re

    from armbench.harness import program

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    shown = re.search(r"^```\n(TimeoutError: wait_until.*?)^```$", readme, re.S | re.M)
    assert shown is not None
    assert " ".join(shown.group(1).split()) == (
        "TimeoutError: wait_until('Pump', True) gave up after 5 s: Pump last read False; "
        + program._raise_the_limit(program.DEFAULT_WAIT_TIMEOUT_S))
