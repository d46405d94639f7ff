"""The wheel works outside the repository.

Builds the wheel from a copy of the build inputs, installs it into a fresh virtual
environment and, from a temporary folder that is no checkout, runs `armbench check` (the
packaged library and a user's cp1252 file), `armbench run`, `armbench serve` (read over
Modbus), `armbench serve --web` (the live view's page from the wheel), `armbench export
--out`, and a small pytest suite using the plugin's `plc` fixture against the packaged
controller. Values are checked against math (pi), the numpy reference
kinematics and the repository's own files.

Needs PyPI or pip's cache (setuptools for the build, the dependencies for the install, at the
versions of tests/packaging/constraints-current.txt); skips, saying so, only when neither can
provide them.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import socket
import struct
import subprocess
import sys
import time
import tomllib
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from packaging.requirements import Requirement

REPO = Path(__file__).resolve().parents[2]
BUILD_INPUTS = ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE", "sim", "st",
                "plc_project")
LOCK = REPO / "tests" / "packaging" / "constraints-current.txt"
OFFLINE_SIGNS = ("No matching distribution found", "Could not find a version",
                 "NewConnectionError", "Temporary failure in name resolution",
                 "Network is unreachable", "Failed to establish a new connection")

USER_PROGRAM = """(* A user's program from CODESYS V2, cp1252: Winkel 180\u00b0, f\u00fcr Tests *)
PROGRAM UserMain
VAR
  half AT %MD0 : REAL;
  n AT %QW0 : INT;
END_VAR
  half := DegToRad(180.0);
  n := n + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH MainTask : UserMain;
  END_RESOURCE
END_CONFIGURATION
"""

USER_SUITE = """
import math

from armbench.plant import arm


def test_move_reaches_the_target(plc):
    status = plc.move_xyz(150.0, 0.0, 120.0)
    assert status.error_id == 0
    assert math.dist((150.0, 0.0, 120.0), arm.forward(*status.joints_deg)) <= 0.05


def test_address_is_a_loopback_soft_plc(plc_address):
    host, port = plc_address
    assert host == "127.0.0.1" and 0 < port < 65536
"""


@dataclass(frozen=True)
class Installed:
    venv: Path
    site: Path  # site-packages holding armbench
    work: Path  # a folder outside any checkout: the commands' current directory
    env: dict[str, str]

    def run(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        return subprocess.run(list(args), cwd=self.work, env=self.env, capture_output=True,
                              text=True, timeout=timeout)

    def armbench(self, *args: str) -> subprocess.CompletedProcess[str]:
        return self.run(str(self.venv / "bin" / "armbench"), *args)


def _require(proc: subprocess.CompletedProcess[str], what: str) -> None:
    if proc.returncode == 0:
        return
    out = proc.stdout + proc.stderr
    sign = next((line for line in out.splitlines() if any(s in line for s in OFFLINE_SIGNS)),
                None)
    if sign is not None:
        pytest.skip(f"cannot {what}: PyPI is unreachable and pip's cache lacks a package "
                    f"({sign.strip()[:160]})")
    pytest.fail(f"{what} failed (rc {proc.returncode}):\n{out[-4000:]}")


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    for name in BUILD_INPUTS:  # a clean copy: no build/ or egg-info left from earlier builds
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns(
                "__pycache__", "*.egg-info", "build"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy2(path, src / name)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    t0 = time.perf_counter()
    proc = subprocess.run([*pip, "wheel", "--no-deps", "-q", "-w", str(tmp / "dist"),
                           str(src)], capture_output=True, text=True, timeout=600)
    _require(proc, "build the wheel")
    build_s = time.perf_counter() - t0
    wheel = next((tmp / "dist").glob("armbench-*.whl"))

    venv = tmp / "venv"
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    # --no-compile: byte-compiling numpy and matplotlib is most of an install's time
    proc = subprocess.run([*pip, "--python", str(venv / "bin" / "python"), "install", "-q",
                           "--no-compile", "-c", str(LOCK), str(wheel), "pytest"],
                          capture_output=True, text=True, timeout=900)
    _require(proc, "install the wheel into a fresh venv")
    install_s = time.perf_counter() - t0
    print(f"\nwheel {wheel.name}: {wheel.stat().st_size / 1024:.0f} KiB, built in "
          f"{build_s:.1f} s; fresh venv + install {install_s:.1f} s")

    site = next(venv.glob("lib/python3*/site-packages"))
    work = tmp / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    (work / "user.st").write_bytes(USER_PROGRAM.encode("cp1252"))
    return Installed(venv, site, work, env)


def test_runs_from_the_installed_package(installed: Installed) -> None:
    proc = installed.run(str(installed.venv / "bin" / "python"), "-c",
                         "import armbench, armbench.locate as l; print(armbench.__file__); "
                         "print(l.default_project().root)")
    assert proc.returncode == 0, proc.stderr
    package, data = proc.stdout.split()
    assert Path(package).is_relative_to(installed.site)
    assert Path(data) == installed.site / "armbench" / "_data"


def test_packaged_files_are_the_repository_files(installed: Installed) -> None:
    data = installed.site / "armbench" / "_data"
    packaged = sorted(p.name for p in (data / "st").glob("*.st"))
    assert packaged == sorted(p.name for p in (REPO / "st").glob("*.st"))
    for name in packaged:
        assert (data / "st" / name).read_bytes() == (REPO / "st" / name).read_bytes(), name
    controller = data / "plc_project" / "Controller.st"
    assert controller.read_bytes() == (REPO / "plc_project" / "Controller.st").read_bytes()
    blocks = sorted(p.name for p in (data / "plc_project" / "controller").glob("*.st"))
    assert blocks == sorted(p.name for p in (REPO / "plc_project" / "controller").glob("*.st"))
    for name in blocks:
        assert (data / "plc_project" / "controller" / name).read_bytes() == \
            (REPO / "plc_project" / "controller" / name).read_bytes(), name


def test_check_packaged_library_and_a_user_file(installed: Installed) -> None:
    n_lib = len(list((REPO / "st").glob("*.st")))
    n_blocks = len(list((REPO / "plc_project" / "controller").glob("*.st")))
    proc = installed.armbench("check")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.fullmatch(rf"checked {n_lib + n_blocks + 1} files \(the armbench library and "
                        r"plc_project/Controller.st\), \d+ POUs: 0 errors",
                        proc.stderr.strip().splitlines()[-1]), proc.stderr
    proc = installed.armbench("check", str(installed.site / "armbench" / "_data" / "st"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith(f"checked {n_lib} files, ")
    proc = installed.armbench("check", "user.st")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.startswith("user.st:1:1: note[N0001]: "), proc.stdout
    assert proc.stderr.strip().splitlines()[-1].endswith(": 0 errors, 1 note")


def test_run_a_user_program_with_the_packaged_library(installed: Installed) -> None:
    proc = installed.armbench("run", "user.st", "--cycles", "3", "--dump")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    inst = json.loads(proc.stdout)["inst0"]
    assert inst["n"] == 3
    assert inst["half"] == pytest.approx(math.pi, abs=2e-7)  # REAL: float32 of pi


def _read_md0(port: int, deadline: float) -> float:
    """FC3 of holding registers 2048..2049 (%MD0), raw MBAP frames."""
    while True:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
                s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, 2048, 2))
                reply = s.recv(64)
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
            continue
        value: float = struct.unpack(">f", reply[9:13])[0]
        if value != 0.0 or time.monotonic() > deadline:
            return value
        time.sleep(0.05)


def test_serve_a_user_program_over_modbus(installed: Installed) -> None:
    proc = subprocess.Popen([str(installed.venv / "bin" / "armbench"), "serve", "user.st",
                             "--port", "0", "--duration", "60"], cwd=installed.work,
                            env=installed.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        m = re.search(r"serving Modbus TCP on 127\.0\.0\.1:(\d+)", line)
        assert m, line + (proc.stderr.read() if proc.stderr else "")
        value = _read_md0(int(m.group(1)), time.monotonic() + 10.0)
        assert value == pytest.approx(math.pi, abs=2e-7)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_export_goes_to_the_named_folder_only(installed: Installed) -> None:
    proc = installed.armbench("export", "user.st")
    assert proc.returncode == 2 and "--out" in proc.stderr
    proc = installed.armbench("export", "--regenerate")
    assert proc.returncode == 2 and "not inside a checkout" in proc.stderr, proc.stderr
    proc = installed.armbench("export", "user.st", "--out", "out")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = (installed.work / "out" / "openplc" / "UserMain.st").read_text("utf-8")
    assert "Winkel 180\u00b0, f\u00fcr Tests" in text  # cp1252 in, UTF-8 out
    assert "FUNCTION DegToRad : REAL" in text and "PROGRAM UserMain" in text
    data = installed.site / "armbench" / "_data"
    assert sorted(p.name for p in data.rglob("*")) == sorted(
        [*(p.name for p in (REPO / "st").glob("*.st")), "Controller.st", "st",
         "plc_project", "controller",
         *(p.name for p in (REPO / "plc_project" / "controller").glob("*.st"))])
    # nothing written into site-packages


def test_generators_refuse_to_run_outside_a_checkout(installed: Installed) -> None:
    for module in ("armbench.docgen", "armbench.lutgen", "armbench.registermap"):
        proc = installed.run(str(installed.venv / "bin" / "python"), "-m", module)
        assert proc.returncode == 2, (module, proc.stdout, proc.stderr)
        assert "not inside a checkout" in proc.stderr and "Traceback" not in proc.stderr


@pytest.fixture()
def user_suite(installed: Installed) -> Iterator[Path]:
    path = installed.work / "test_user_suite.py"
    path.write_text(USER_SUITE)
    yield path
    path.unlink()


def test_pytest_plugin_against_the_packaged_controller(installed: Installed,
                                                       user_suite: Path) -> None:
    proc = installed.run(str(installed.venv / "bin" / "python"), "-m", "pytest", "-q",
                         "-p", "no:cacheprovider", user_suite.name)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert re.search(r"\b2 passed\b", proc.stdout), proc.stdout


def test_web_view_from_the_installed_package(installed: Installed) -> None:
    """`armbench serve --web` outside the checkout: the page and its scripts come from the
    wheel (byte for byte the repository's), and a command sent from the page's API moves the
    PLC's joints to the numpy reference IK."""
    static = installed.site / "armbench" / "web" / "static"
    repo_static = REPO / "sim" / "armbench" / "web" / "static"
    assert sorted(p.name for p in static.iterdir()) == sorted(
        p.name for p in repo_static.iterdir())
    proc = subprocess.Popen([str(installed.venv / "bin" / "armbench"), "serve", "--web",
                             "--port", "0", "--web-port", "0", "--duration", "60"],
                            cwd=installed.work, env=installed.env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline(), proc.stdout.readline()]
        m = re.search(r"live view on (http://127\.0\.0\.1:\d+/)", lines[1])
        assert m, "".join(lines) + (proc.stderr.read() if proc.stderr else "")
        url = m.group(1)
        for path in ("", "static/app.js", "static/style.css"):
            with urllib.request.urlopen(url + path, timeout=10) as r:
                name = "index.html" if path == "" else path.split("/")[-1]
                assert r.read() == (repo_static / name).read_bytes(), path
        deadline = time.monotonic() + 20.0
        while not json.load(urllib.request.urlopen(url + "api/state", timeout=10))["connected"]:
            assert time.monotonic() < deadline, "the view never polled the PLC"
            time.sleep(0.1)
        req = urllib.request.Request(
            url + "api/command", json.dumps({"name": "CmdMoveXyz", "fields": {
                "x": 150, "y": 0, "z": 120}}).encode(), {"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=20) as r:
            assert json.load(r)["result"] == 0
        from armbench.plant import arm

        expected = arm.inverse(150.0, 0.0, 120.0)
        while True:
            joints = json.load(urllib.request.urlopen(url + "api/state", timeout=10))[
                "joints"]["plc"]
            if joints == pytest.approx(expected, abs=1e-3):
                break
            assert time.monotonic() < deadline, joints
            time.sleep(0.05)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_wheel_metadata_carries_the_licence(installed: Installed) -> None:
    """What pip shows a user: the licence expression and file, the summary, the README as the
    long description, and dependency ranges (no exact pins)."""
    dist = next(installed.site.glob("armbench-*.dist-info"))
    meta = (dist / "METADATA").read_text(encoding="utf-8")
    assert "\nLicense-Expression: MIT\n" in meta
    assert "\nLicense-File: LICENSE\n" in meta
    assert (dist / "licenses" / "LICENSE").read_bytes() == (REPO / "LICENSE").read_bytes()
    assert "\nSummary: A portable IEC 61131-3 Structured Text library" in meta
    assert "\nDescription-Content-Type: text/markdown\n" in meta
    assert "# arm-kinematics PLC library and test bench" in meta
    requires = re.findall(r"^Requires-Dist: (.*)$", meta, re.M)
    runtime = [r for r in requires if "extra ==" not in r]
    declared = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    as_dict = {Requirement(r).name: Requirement(r).specifier for r in runtime}
    assert as_dict == {Requirement(r).name: Requirement(r).specifier
                       for r in declared["project"]["dependencies"]}
    assert not any("==" in r for r in runtime), runtime
