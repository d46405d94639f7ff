"""The pytest plugin ends the session with one line when the --plc-host PLC does not answer
(refused, silent, not Modbus), instead of one error per test."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

SUITE = """
def test_one(plc):
    plc.status()


def test_two(plc_address):
    assert plc_address


def test_three(plc):
    plc.status()
"""


def run_suite(tmp_path: Path, *options: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "test_suite.py").write_text(SUITE)
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "test_suite.py", *options], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)


def assert_one_line_abort(proc: subprocess.CompletedProcess[str], address: str,
                          reason: str) -> None:
    out = proc.stdout + proc.stderr
    hits = [ln for ln in out.splitlines() if "does not answer" in ln]
    assert len(hits) == 1, out
    assert f"the PLC at {address} " in hits[0] and reason in hits[0], hits[0]
    assert proc.returncode == 4, out
    assert "passed" not in out and "error" not in out.lower().replace(hits[0].lower(), "")
    assert len(out.strip().splitlines()) <= 3, out


@pytest.fixture()
def listener() -> Iterator[socket.socket]:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(8)
    yield s
    s.close()


def test_refused(tmp_path: Path) -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = run_suite(tmp_path, "--plc-host", "127.0.0.1", "--plc-port", str(port))
    assert_one_line_abort(proc, f"127.0.0.1:{port}", "Connection refused")


def test_silent_peer_times_out(tmp_path: Path, listener: socket.socket) -> None:
    port = listener.getsockname()[1]  # accepts (backlog) but never answers
    proc = run_suite(tmp_path, "--plc-host", "127.0.0.1", "--plc-port", str(port))
    assert_one_line_abort(proc, f"127.0.0.1:{port}", "no Modbus TCP answer within 3 s")


def test_peer_that_is_not_modbus(tmp_path: Path, listener: socket.socket) -> None:
    def answer_http() -> None:
        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            with conn:
                conn.recv(256)
                conn.sendall(b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n")

    threading.Thread(target=answer_http, daemon=True).start()
    port = listener.getsockname()[1]
    proc = run_suite(tmp_path, "--plc-host", "127.0.0.1", "--plc-port", str(port))
    assert_one_line_abort(proc, f"127.0.0.1:{port}", "the reply is not Modbus TCP")


def test_bad_port_is_a_usage_error(tmp_path: Path) -> None:
    proc = run_suite(tmp_path, "--plc-host", "127.0.0.1", "--plc-port", "99999")
    assert proc.returncode == 4
    assert "--plc-port: port must be 0..65535, got 99999" in proc.stderr


OTHER_PROGRAM = """
PROGRAM Counter
  VAR
    Count AT %MD0 : UDINT;
  END_VAR
  Count := Count + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK Main(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Inst0 WITH Main : Counter;
  END_RESOURCE
END_CONFIGURATION
"""

COMMANDING_SUITE = """
def test_one(plc):
    assert plc.hello().error_id == 0


def test_two(plc):
    assert plc.hello().error_id == 0
"""


@pytest.fixture()
def other_program(tmp_path: Path) -> Iterator[int]:
    """A soft PLC that answers Modbus but runs a counter, not the arm controller."""
    from armbench.softplc.loader import load_program
    from armbench.softplc.modbus_server import ModbusServer
    from armbench.softplc.scan import SoftPlc

    src = tmp_path / "counter.st"
    src.write_text(OTHER_PROGRAM)
    prog = load_program([src])
    plc = SoftPlc(prog)
    server = ModbusServer(prog.image, plc.lock, host="127.0.0.1", port=0)
    server.start()
    plc.start()
    try:
        yield server.port
    finally:
        plc.stop()
        server.stop()


def test_a_plc_running_another_program_stops_the_session(tmp_path: Path,
                                                        other_program: int) -> None:
    (tmp_path / "test_suite.py").write_text(COMMANDING_SUITE)
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "test_suite.py", "--plc-address", f"127.0.0.1:{other_program}"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    hits = [ln for ln in out.splitlines() if "does not run the arm controller" in ln]
    assert len(hits) == 1, out
    assert f"the PLC at 127.0.0.1:{other_program} (--plc-address)" in hits[0]
    assert proc.returncode == 4, out
    assert "passed" not in out and "failed" not in out  # no test ran
    assert len(out.strip().splitlines()) <= 3, out
