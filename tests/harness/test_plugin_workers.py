"""The pytest plugin under pytest-xdist: each worker its own PLC (a soft PLC of its own, or
the N-th --plc-address), more workers than addresses refused unless --plc-share, and the
points reported with record_points added up over all workers."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from armbench.demo import serve_controller

SUITE = """
import os
import time

import pytest


@pytest.mark.parametrize("k", range(8))
def test_where(plc_address, worker_id, k):
    time.sleep(0.1)  # long enough that every worker gets tests
    host, port = plc_address
    with open("seen.txt", "a") as f:
        f.write(f"{worker_id} {host}:{port}\\n")


def test_points_a(record_points):
    record_points(5, total=12)


def test_points_b(record_points):
    record_points(3, total=12)
    record_points(4, total=12)
"""


def run_suite(tmp_path: Path, *options: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "test_suite.py").write_text(SUITE)
    (tmp_path / "seen.txt").unlink(missing_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "test_suite.py", *options], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)


def seen(tmp_path: Path) -> dict[str, set[str]]:
    """worker id -> the PLC addresses its tests saw."""
    out: dict[str, set[str]] = {}
    for line in (tmp_path / "seen.txt").read_text().splitlines():
        worker, address = line.split()
        out.setdefault(worker, set()).add(address)
    return out


@pytest.fixture(scope="module")
def two_plcs() -> Iterator[list[str]]:
    with contextlib.ExitStack() as stack:
        plcs = [stack.enter_context(serve_controller()) for _ in range(2)]
        yield [f"{p.host}:{p.port}" for p in plcs]


def test_each_worker_gets_its_own_soft_plc_and_points_add_up(tmp_path: Path) -> None:
    proc = run_suite(tmp_path, "-n", "2", "--sweep-progress", "bar")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    by_worker = seen(tmp_path)
    assert set(by_worker) == {"gw0", "gw1"}
    assert all(len(a) == 1 for a in by_worker.values())
    assert by_worker["gw0"] != by_worker["gw1"]
    assert all(a.startswith("127.0.0.1:") for addrs in by_worker.values() for a in addrs)
    # record_points from both workers: one total, one bar that reached it
    assert "armbench sweep: 12 points in " in proc.stdout
    assert "on 2 worker(s)" in proc.stdout
    assert "12/12" in proc.stderr


def test_worker_n_takes_the_nth_address(tmp_path: Path, two_plcs: list[str]) -> None:
    proc = run_suite(tmp_path, "-n", "2", "--plc-address", ",".join(two_plcs))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert seen(tmp_path) == {"gw0": {two_plcs[0]}, "gw1": {two_plcs[1]}}


def test_more_workers_than_addresses_is_a_usage_error(tmp_path: Path,
                                                      two_plcs: list[str]) -> None:
    proc = run_suite(tmp_path, "-n", "3", "--plc-address", ",".join(two_plcs))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4, out
    assert "3 pytest-xdist workers but 2 PLC address(es)" in out and "--plc-share" in out
    assert not (tmp_path / "seen.txt").exists()  # no test ran


def test_plc_share_lets_workers_take_the_addresses_in_turn(tmp_path: Path,
                                                           two_plcs: list[str]) -> None:
    proc = run_suite(tmp_path, "-n", "3", "--plc-address", ",".join(two_plcs), "--plc-share")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    by_worker = seen(tmp_path)
    assert by_worker["gw0"] == {two_plcs[0]} and by_worker["gw1"] == {two_plcs[1]}
    assert by_worker.get("gw2", {two_plcs[0]}) == {two_plcs[0]}


@pytest.mark.parametrize(("options", "message"), [
    (["--plc-address", "a:x"], "not an integer: 'x'"),
    (["--plc-address", "a:70000"], "port must be 0..65535"),
    (["--plc-address", "a:1", "--plc-host", "b"], "either --plc-address or --plc-host"),
    (["--plc-port", "5020"], "--plc-port needs --plc-host"),
])
def test_bad_addresses_are_one_line_usage_errors(tmp_path: Path, options: list[str],
                                                 message: str) -> None:
    proc = run_suite(tmp_path, *options)
    assert proc.returncode == 4, proc.stdout + proc.stderr
    assert message in proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr


SLOW_GARBAGE = """
import gc
import time


class Slow:
    \"\"\"In a reference cycle, so only the cyclic collector frees it, and slow to free: a
    worker's last collection after a long run (compiled programs' syntax trees, hypothesis'
    search trees) took this long on a loaded machine.\"\"\"

    def __init__(self):
        self.me = self

    def __del__(self):
        time.sleep(0.2)


def test_leaves_garbage_that_takes_7_s_to_free():
    gc.disable()  # as in a long run: no full collection before the session ends
    for _ in range(35):
        Slow()
"""


def test_a_green_run_under_xdist_ends_without_a_traceback(tmp_path: Path) -> None:
    """A worker's last garbage collection runs before it reports its end: run after it, as
    pytest's own does, it took longer than the 5 s execnet gives a finished worker, which
    then got a SIGINT and printed a KeyboardInterrupt traceback under a green run."""
    (tmp_path / "test_garbage.py").write_text(SLOW_GARBAGE)
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[2] / "sim"),
                                         env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-n", "1", "test_garbage.py"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 passed" in out, out
    assert "Traceback" not in out and "KeyboardInterrupt" not in out, out
