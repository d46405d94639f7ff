"""Compiler and runtime figures (prints figures; not a test).

1. an IK-like REAL kernel compiled from ST vs the same kernel hand-written in C (ratio);
2. cold and cached build of all of st/;
3. real-time loop jitter of a 10 ms task (p99).
Run: .venv/bin/python bench/compiler_bench.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cffi

from armbench.compiler import compile_files
from armbench.compiler.build import CFLAGS, find_cc
from armbench.softplc.loader import load_program
from armbench.softplc.scan import SoftPlc

HERE = Path(__file__).parent
ROOT = HERE.parent
N = 200_000


def best_of(fn: object, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return min(times)


def kernel_ratio() -> None:
    mod = compile_files([HERE / "kernels" / "ik_kernel.st"])
    fb = mod.new_fb("IkKernel")
    fb.set(Count=N)
    st_time = best_of(lambda: fb())
    st_sum = fb.Checksum

    tmp = Path(tempfile.mkdtemp())
    so = tmp / "ik_kernel.so"
    subprocess.run([find_cc(), *CFLAGS, str(HERE / "kernels" / "ik_kernel.c"), "-o", str(so),
                    "-lm"], check=True)
    ffi = cffi.FFI()
    ffi.cdef("float ik_kernel(int32_t count);")
    lib = ffi.dlopen(str(so))
    c_time = best_of(lambda: lib.ik_kernel(N))
    c_sum = lib.ik_kernel(N)
    print(f"kernel: {N} IK points, best of 5: ST->C {st_time * 1e3:.2f} ms, hand C "
          f"{c_time * 1e3:.2f} ms, ratio {st_time / c_time:.3f} (goal <= 1.1); "
          f"checksums {st_sum:.4f} / {c_sum:.4f}")


def build_times() -> None:
    files = sorted((ROOT / "st").glob("*.st"))
    with tempfile.TemporaryDirectory() as cache:
        os.environ["ARMBENCH_CACHE"] = cache
        t0 = time.perf_counter()
        compile_files(files)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        compile_files(files)
        warm = time.perf_counter() - t0
        del os.environ["ARMBENCH_CACHE"]
    lines = sum(len(f.read_text().splitlines()) for f in files)
    print(f"build of st/ ({len(files)} files, {lines} lines): cold {cold:.3f} s (goal <= 2), "
          f"cached {warm:.3f} s (goal <= 0.2)")


JITTER_ST = """
PROGRAM Tick
VAR n : DINT; END_VAR
  n := n + 1;
END_PROGRAM
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Tick;
  END_RESOURCE
END_CONFIGURATION
"""


def jitter(seconds: float = 5.0) -> None:
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "tick.st"
        src.write_text(JITTER_ST)
        prog = load_program([src])
    plc = SoftPlc(prog)
    plc.run()
    plc.start()
    time.sleep(seconds)
    plc.stop()
    st = plc.stats()["task0"]
    j = st.jitter
    print(f"real-time loop, 10 ms task, {seconds:.0f} s: {st.scans} scans, release jitter "
          f"p50 {j.p50_ns / 1e3:.0f} us, p99 {j.p99_ns / 1e3:.0f} us, max {j.max_ns / 1e3:.0f} us "
          f"(goal p99 <= 1000 us), overruns {st.overruns}")


if __name__ == "__main__":
    kernel_ratio()
    build_times()
    jitter(float(sys.argv[1]) if len(sys.argv) > 1 else 5.0)
