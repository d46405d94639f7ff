"""Modbus server speed with one client: the soft PLC against the real OpenPLC v3 runtime.

Builds ``bench/modbus_pairs.c`` (a raw-socket C client: FC16 write + FC3 read pairs on one
connection, every read checked against the values just written) with the system C compiler,
then measures, in the same run and on the same program (the arm controller, 10 ms scans
running), transactions per second of

* the soft PLC with its compiled request path (``armbench serve``'s default),
* the soft PLC with the Python request path (``ModbusServer(fast_path=False)``, the server
  before the fast path),
* the soft PLC serving the CODESYS variant's layout (``armbench serve --flavor codesys``:
  its Modbus TCP Server Device model, always in Python), where BatchX01.. are holding
  registers 800.. (plc_project/codesys/register-map.md),
* the soft PLC answering as OpenPLC v4's Modbus plugin (``--flavor openplc-v4``: its model
  of the plugin's segments, journal and pymodbus's framing, in Python; not v4 itself, which
  serves from pymodbus's asyncio loop),
* the OpenPLC v3 runtime running ``plc_project/openplc/arm_controller.st``, where the
  environment variable ``OPENPLC_RUN`` names a script that starts it (``OPENPLC_RUN FILE.st
  PORT``: builds FILE.st into the runtime, serves Modbus TCP on PORT, prints a line with
  "listening on" once it does, stops the runtime on SIGTERM); otherwise a line says it was
  skipped and why.

The client writes the batch target registers (BatchX01.., three REALs = 6 holding registers in
the %MD area), which the controller reads only when a SolveBatch command arrives. All servers
run for the whole bench; the rounds rotate their order, so a burst of load from elsewhere on
the machine does not land on one server only, and the table shows the median and the best
round of each. Beside the rate it prints the server process's CPU time per transaction (all
its threads, the 10 ms scans included, from /proc/PID/stat): a figure that load from
elsewhere on the machine hardly moves, where the rate can halve.

    .venv/bin/python bench/modbus_server_speed.py [--seconds 3] [--rounds 5] [--cpus split]
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path

from modbus_tps import free_port, pin  # the bench folder: run as a script

try:
    from armbench.registermap import SOURCES, controller_map
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
    from armbench.registermap import SOURCES, controller_map

ROOT = Path(__file__).resolve().parents[1]
CLIENT_SOURCE = ROOT / "bench" / "modbus_pairs.c"
OPENPLC_PROGRAM = ROOT / "plc_project" / "openplc" / "arm_controller.st"
REGISTERS = 6  # three REALs


def build_client(out_dir: Path) -> Path:
    cc = next((c for c in (os.environ.get("CC"), "cc", "gcc", "clang") if c and shutil.which(c)),
              None)
    if cc is None:
        raise SystemExit("no C compiler found: install one (Debian: apt-get install gcc)")
    exe = out_dir / "modbus_pairs"
    subprocess.run([cc, "-O2", "-std=c11", "-o", str(exe), str(CLIENT_SOURCE)], check=True)
    return exe


def serve_soft_plc(conn: Connection, fast: bool, cpus: set[int] | None,
                   flavor: str = "openplc") -> None:
    """Child process: the controller in a real-time soft PLC with its Modbus server, as
    `armbench serve` runs it, on the compiled or the Python request path (``flavor``
    codesys: the CODESYS layout; openplc-v4: OpenPLC v4's plugin; Python only)."""
    import threading

    from armbench.softplc import ModbusServer, SoftPlc
    from armbench.softplc.loader import load_program
    from armbench.softplc.serving import soft_plc as serving

    pin(cpus)
    prog = load_program(list(SOURCES))
    if flavor != "openplc":
        plc, server = serving(prog, flavor, port=0)
    else:
        # The Python path takes a threading.Lock, as the server did before the compiled path.
        plc = SoftPlc(prog) if fast else SoftPlc(prog, lock=threading.Lock())
        server = ModbusServer(prog.image, plc.lock, port=0, fast_path=fast)
    if server.fast_path != fast:
        raise SystemExit("the compiled request path is not available")
    with server:
        plc.start()
        conn.send(server.port)
        conn.recv()
        plc.stop()


def cpu_ns(pid: int) -> int:
    """CPU time so far of process pid, all its threads, ended ones included (ns; the
    kernel counts it in clock ticks, 10 ms on most systems)."""
    text = Path(f"/proc/{pid}/stat").read_text()
    utime, stime = text[text.rindex(")") + 2:].split()[11:13]
    return (int(utime) + int(stime)) * 1_000_000_000 // os.sysconf("SC_CLK_TCK")


def child_named(parent: int, name: str, timeout_s: float = 10.0) -> int:
    """pid of the child of ``parent`` whose command is ``name``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for stat in Path("/proc").glob("[0-9]*/stat"):
            with contextlib.suppress(OSError, ValueError, IndexError):
                text = stat.read_text()
                comm = text[text.index("(") + 1: text.rindex(")")]
                ppid = int(text[text.rindex(")") + 2:].split()[1])
                if ppid == parent and comm == name:
                    return int(stat.parent.name)
        time.sleep(0.1)
    raise SystemExit(f"no process {name!r} under pid {parent}")


@dataclass(frozen=True)
class Server:
    port: int
    pid: int
    address: int  # of BatchX01 in the layout this server serves


@contextlib.contextmanager
def soft_plc(fast: bool, cpus: set[int] | None, flavor: str = "openplc") -> Iterator[Server]:
    ctx = multiprocessing.get_context("spawn")
    parent, child = ctx.Pipe()
    process = ctx.Process(target=serve_soft_plc, args=(child, fast, cpus, flavor),
                          daemon=True)
    process.start()
    try:
        if not parent.poll(120):
            raise SystemExit("the soft PLC did not start")
        port: int = parent.recv()
        assert process.pid is not None
        yield Server(port, process.pid, controller_map(flavor)["BATCHX01"].address)
    finally:
        parent.send("stop")
        process.join(10)
        if process.is_alive():
            process.kill()
            process.join()


@contextlib.contextmanager
def openplc(cpus: set[int] | None) -> Iterator[Server | None]:
    """The real runtime on a free port (None, with the reason printed, where it is absent)."""
    script = os.environ.get("OPENPLC_RUN")
    if not script or not Path(script).is_file():
        print("OpenPLC runtime: skipped (" + (f"OPENPLC_RUN={script} is no file" if script else
              "OPENPLC_RUN is not set") + ": set it to a script that starts the OpenPLC v3 "
              "runtime, `OPENPLC_RUN FILE.st PORT`; see docs/modbus-parity.md)")
        yield None
        return
    port = free_port()
    log = tempfile.TemporaryFile(mode="w+")
    proc = subprocess.Popen([script, str(OPENPLC_PROGRAM), str(port)], stdout=log,
                            stderr=subprocess.STDOUT, preexec_fn=lambda: pin(cpus))
    try:
        deadline = time.monotonic() + 180
        while True:
            log.seek(0)
            text = log.read()
            if "listening on" in text:
                break
            if proc.poll() is not None or time.monotonic() > deadline:
                print(f"OpenPLC runtime: skipped (OPENPLC_RUN={script} did not start):\n"
                      f"{text[-2000:]}")
                yield None
                return
            time.sleep(0.2)
        yield Server(port, child_named(proc.pid, "openplc"),
                     controller_map()["BATCHX01"].address)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)  # the script stops the runtime and cleans up
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        log.close()


def measure(client: Path, server: Server, seconds: float,
            cpus: set[int] | None) -> tuple[float, float]:
    """(transactions/s, server CPU µs per transaction)."""
    cpu0 = cpu_ns(server.pid)
    out = subprocess.run([str(client), "127.0.0.1", str(server.port), f"{seconds:g}",
                          str(server.address), str(REGISTERS)], capture_output=True, text=True,
                         preexec_fn=(lambda: pin(cpus)) if cpus else None)
    cpu = cpu_ns(server.pid) - cpu0
    if out.returncode != 0:
        raise SystemExit(f"modbus_pairs on port {server.port} failed: {out.stderr.strip()}")
    found = re.search(r"pairs=(\d+) .*tps=(\d+)", out.stdout)
    if found is None:
        raise SystemExit(f"modbus_pairs printed {out.stdout!r}")
    # the warm-up's 200 pairs ran on the server's CPU clock too
    transactions = 2 * (int(found.group(1)) + 200)
    return float(found.group(2)), cpu / 1000.0 / transactions


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="per measurement (3)")
    ap.add_argument("--rounds", type=int, default=5, help="measurements per server (5)")
    ap.add_argument("--cpus", choices=["any", "split"], default="any",
                    help="split: client on the first CPU, servers on the second")
    ap.add_argument("--no-openplc", action="store_true", help="skip the real runtime")
    a = ap.parse_args(argv)
    if a.seconds <= 0 or a.rounds < 1:
        ap.error("--seconds must be positive and --rounds at least 1")
    client_cpus: set[int] | None = None
    server_cpus: set[int] | None = None
    if a.cpus == "split":
        first, *rest = sorted(os.sched_getaffinity(0))
        client_cpus, server_cpus = {first}, {rest[0] if rest else first}
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        client = build_client(Path(tmp))
        servers: dict[str, Server] = {
            "soft PLC, compiled path": stack.enter_context(soft_plc(True, server_cpus)),
            "soft PLC, Python path": stack.enter_context(soft_plc(False, server_cpus)),
            "soft PLC, CODESYS layout": stack.enter_context(
                soft_plc(False, server_cpus, "codesys")),
            "soft PLC, OpenPLC v4 model": stack.enter_context(
                soft_plc(False, server_cpus, "openplc-v4")),
        }
        if a.no_openplc:
            print("OpenPLC runtime: skipped (--no-openplc)")
        else:
            real = stack.enter_context(openplc(server_cpus))
            if real is not None:
                servers["OpenPLC v3 runtime"] = real
        names = list(servers)
        figures: dict[str, list[float]] = {n: [] for n in names}
        cpu: dict[str, list[float]] = {n: [] for n in names}
        print(f"FC16 write of {REGISTERS} registers at BatchX01 (OpenPLC "
              f"{servers[names[0]].address}, CODESYS {servers['soft PLC, CODESYS layout'].address})"
              f" + FC3 read back, one connection, {a.seconds:g} s per measurement, CPUs "
              f"{a.cpus}; tx/s per round:")
        for r in range(a.rounds):
            order = names[r % len(names):] + names[: r % len(names)]
            for name in order:
                tps, us = measure(client, servers[name], a.seconds, client_cpus)
                figures[name].append(tps)
                cpu[name].append(us)
            print(f"  round {r + 1}: " + ", ".join(f"{n} {figures[n][-1]:.0f}" for n in names))

    print(f"\n{'server':<26}{'median tx/s':>13}{'best tx/s':>11}{'server CPU µs/tx':>18}")
    for n in names:
        print(f"{n:<26}{statistics.median(figures[n]):>13.0f}{max(figures[n]):>11.0f}"
              f"{statistics.median(cpu[n]):>18.2f}")
    if "OpenPLC v3 runtime" in figures:
        ratio = statistics.median(figures[names[0]]) / statistics.median(
            figures["OpenPLC v3 runtime"])
        cpu_ratio = statistics.median(cpu[names[0]]) / statistics.median(
            cpu["OpenPLC v3 runtime"])
        print(f"soft PLC (compiled) / OpenPLC, medians: rate {ratio:.2f}, "
              f"CPU per transaction {cpu_ratio:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
