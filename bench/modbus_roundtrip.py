"""Modbus-verified controller round trips per second: single commands and SolveBatch.

Starts the soft PLC with plc_project/Controller.st (10 ms task, real time) and its Modbus
server on a free loopback port -- or uses a real OpenPLC with --plc-host -- and for a fixed
time issues
  * single MoveXyz commands (one FC16 write, AckSeq polls, one status read per point), and
  * SolveBatch commands of 32 points (targets + command block written, AckSeq polls, results
    read back),
checking every result against the numpy reference FK (error <= 0.05 mm). Prints the points
per second and the Modbus requests per point; not a test.

    .venv/bin/python bench/modbus_roundtrip.py [--seconds 3] [--poll-ms 0.5]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

try:
    from armbench.controller_client import ArmControllerClient
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
    from armbench.controller_client import ArmControllerClient
from armbench.demo import serve_controller
from armbench.plant import arm
from armbench.softplc.modbus_client import PlcClient

TOLERANCE_MM = 0.05


class CountingClient(PlcClient):
    """PlcClient that counts its requests."""

    requests = 0

    def read_holding_registers(self, address: int, count: int = 1) -> list[int]:
        self.requests += 1
        return super().read_holding_registers(address, count)

    def write_registers(self, address: int, values: list[int]) -> None:  # type: ignore[override]
        self.requests += 1
        super().write_registers(address, values)


def targets(n: int, offset: int = 0) -> list[tuple[float, float, float]]:
    pts = []
    for i in range(offset, offset + n):
        u, v, w = (i * 0.618034) % 1.0, (i * 0.754878) % 1.0, (i * 0.569840) % 1.0
        pts.append((120.0 + 60.0 * u, -40.0 + 80.0 * v, 90.0 + 60.0 * w))
    return pts


@contextlib.contextmanager
def plc_at(host: str | None, port: int) -> Iterator[tuple[str, int]]:
    if host is not None:
        yield host, port
        return
    with serve_controller() as running:
        yield running.host, running.port


def single(ctl: ArmControllerClient, seconds: float) -> tuple[int, float]:
    done = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        p = targets(1, done)[0]
        st = ctl.move_xyz(*p)
        if st.error_id != 0 or math.dist(p, arm.forward(*st.joints_deg)) > TOLERANCE_MM \
                or math.dist(p, st.echo_mm) > TOLERANCE_MM:
            raise SystemExit(f"bad single round trip at {p}: {st}")
        done += 1
    return done, time.perf_counter() - start


def batch(ctl: ArmControllerClient, seconds: float) -> tuple[int, float]:
    done = 0
    start = time.perf_counter()
    with ctl.batch_buffer():  # reserved once, as a regression run would
        while time.perf_counter() - start < seconds:
            done += _one_batch(ctl, done)
    return done, time.perf_counter() - start


def _one_batch(ctl: ArmControllerClient, done: int) -> int:
    """One verified SolveBatch; returns its point count."""
    pts = targets(ctl.batch_max, done)
    res = ctl.solve_batch(pts)
    want = np.array(pts)
    ref = arm.forward_batch(np.array([r.joints_deg for r in res]))
    echo = np.array([r.echo_mm for r in res])
    if any(r.error_id for r in res) or np.max(np.linalg.norm(ref - want, axis=1)) > \
            TOLERANCE_MM or np.max(np.linalg.norm(echo - want, axis=1)) > TOLERANCE_MM:
        raise SystemExit(f"bad batch round trip from point {done}")
    return len(pts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=3.0, help="per measurement (3)")
    ap.add_argument("--poll-ms", type=float, default=0.5, help="answer poll interval (0.5)")
    ap.add_argument("--plc-host", default=None, help="a real PLC instead of the soft PLC")
    ap.add_argument("--plc-port", type=int, default=502)
    a = ap.parse_args(argv)
    with plc_at(a.plc_host, a.plc_port) as (host, port):
        modbus = CountingClient(host, port)
        with modbus:
            ctl = ArmControllerClient(modbus, poll_interval_s=a.poll_ms / 1000.0)
            print(f"PLC at {host}:{port}; answer poll interval {a.poll_ms:g} ms; "
                  f"{a.seconds:g} s per measurement; every result checked against the numpy "
                  f"reference FK (<= {TOLERANCE_MM} mm)")
            for name, fn in (("single MoveXyz", single), (f"SolveBatch x{ctl.batch_max}", batch)):
                modbus.requests = 0
                n, dt = fn(ctl, a.seconds)
                print(f"{name:>16}: {n / dt:9.1f} verified points/s  ({n} points in {dt:.2f} s, "
                      f"{modbus.requests / n:.2f} Modbus requests/point)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
