"""`armbench serve`: the warning for a non-loopback address and the connection options."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextmanager
def serve(prog: Path, *options: str) -> Iterator[tuple[subprocess.Popen[str], int]]:
    port = _free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "armbench.cli", "serve", str(prog), "--port", str(port),
         "--duration", "1", *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "serving Modbus TCP" in line, line
        yield proc, port
    finally:
        proc.kill()
        proc.wait()


def _finish(proc: subprocess.Popen[str]) -> Sequence[str]:
    _out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    return err.splitlines()


def test_all_interfaces_warns_on_stderr_and_idle_timeout_option(prog: Path) -> None:
    with serve(prog, "--host", "0.0.0.0", "--idle-timeout", "0.3") as (proc, port):
        # Before the connect: the server's clock starts at its accept, which a loaded machine
        # may run before this process returns from connect().
        start = time.monotonic()
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            assert sock.recv(1) == b""  # closed by the server, not by the 5 s timeout
            assert 0.3 <= time.monotonic() - start < 5
        lines = _finish(proc)
    warnings = [line for line in lines if "move the servos" in line]
    assert len(warnings) == 1, lines
    assert warnings[0].startswith("armbench: WARNING: Modbus TCP on 0.0.0.0:")
    assert "any host" in warnings[0]


def test_loopback_is_quiet_and_max_clients_option(prog: Path) -> None:
    with serve(prog, "--max-clients", "1", "--idle-timeout", "0") as (proc, port):
        with socket.create_connection(("127.0.0.1", port), timeout=5) as first:
            time.sleep(0.1)  # accepted before the second one arrives
            with socket.create_connection(("127.0.0.1", port), timeout=5):
                assert first.recv(1) == b""  # made room for the second client
        assert _finish(proc) == []


@pytest.mark.parametrize("options", [["--idle-timeout", "-1"], ["--max-clients", "0"]])
def test_bad_limits_are_one_line_errors(prog: Path, options: list[str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "armbench.cli", "serve", str(prog), "--port", "0", *options],
        capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2  # a usage error
    assert len(proc.stderr.splitlines()) == 1 and proc.stderr.startswith("armbench serve: error:")
