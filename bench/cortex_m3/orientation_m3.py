"""Cortex-M3 instructions per orientation-filter update (REAL, soft float), on QEMU.

Same method as run_bench.py (docs/cortex-m3-bench.md), whose harness, build and trace counter
it reuses: the ST library is compiled to C by armbench's compiler, linked for QEMU's
stm32vldiscovery (Cortex-M3, no FPU), and the executed instructions between two marker calls
around each block call are counted from QEMU's -singlestep trace, minus the same harness with
an empty kernel. The filter block is initialised once and then fed one simulated IMU sample
per call (armbench.plant.imu, seed 5, 100 Hz), so its state carries from sample to sample as
on a PLC; the same chain runs on the host (armbench.compiler) and every output must agree.

Run: .venv/bin/python bench/cortex_m3/orientation_m3.py [--opt O0 O2] [--samples 200]
Exit: 0 ok, 1 a build, run or check failed, 2 the tool chain is missing.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from run_bench import (  # noqa: E402  (the sibling script, not a package)
    ST,
    build,
    decode,
    ensure_tools,
    harness_c,
    output_leaves,
    parse_outputs,
    py_leaves,
    run_qemu,
)

from armbench.compiler import ast as A  # noqa: E402
from armbench.compiler import compile_files  # noqa: E402
from armbench.compiler.driver import emit_files  # noqa: E402
from armbench.orientation import st_samples  # noqa: E402
from armbench.plant.imu import HandTrajectory, ImuModel, simulate  # noqa: E402

BLOCKS = {"gyro": "GyroIntegrator", "complementary": "ComplementaryFilter",
          "imu": "MadgwickImu", "marg": "MadgwickMarg"}
TOL = 1.0e-5  # target soft float vs host float, same ST


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opt", nargs="+", default=["O0", "O2"])
    ap.add_argument("--blocks", nargs="+", default=list(BLOCKS), choices=list(BLOCKS))
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--timeout", type=float, default=1800.0)
    opts = ap.parse_args()
    if not 2 <= opts.samples <= 600:
        ap.error("--samples must lie in 2..600 (the samples are const tables in 128 KB flash)")
    ensure_tools()
    build_root = Path(tempfile.mkdtemp(prefix="armbench_cm3_orient_"))
    snap = build_root / "st"
    snap.mkdir()
    files = []
    for f in sorted(ST.glob("*.st")):
        (snap / f.name).write_bytes(f.read_bytes())
        files.append(snap / f.name)
    mod = compile_files(files)
    record = simulate(HandTrajectory(), ImuModel(), duration_s=(opts.samples - 1) / 100.0,
                      rate_hz=100.0, seed=5)
    samples = st_samples(mod, record)
    prog, unit = emit_files(files)

    jobs = []
    refs: dict[str, list[list[Any]]] = {}
    kinds: dict[str, list[str]] = {}
    for key in opts.blocks:
        pou = BLOCKS[key]
        sym = prog.pous[pou.upper()]
        args = [{"Reset": False, "SamplePeriodS": record.period_s, "Sample": s}
                for s in samples]
        # the host chain: one instance, one call per sample, from the same defaults
        inst = mod.new_fb(pou)
        rows = []
        for a in args:
            inst(**a)
            rows.append([x for v in sym.vars.values() if v.kind == A.VAR_OUTPUT
                         for x in py_leaves(v.type, inst.get(v.name))])
        refs[key] = rows
        kinds[key] = [lf.kind for lf in output_leaves(sym)]
        harness = harness_c(sym, args)
        for opt in opts.opt:
            for empty in (False, True):
                jobs.append((key, opt, empty,
                             build_root / f"{key}_{opt}{'_e' if empty else ''}", harness))

    def do(job: tuple[str, str, bool, Path, str]) -> dict[str, Any]:
        key, opt, empty, wd, harness = job
        elf, info = build(wd, unit.code, harness, opt, empty)
        rc, text, counts = run_qemu(elf, info, opts.timeout)
        return {"key": key, "opt": opt, "empty": empty, "rc": rc, "out": text,
                "counts": counts, **info}

    print(f"building and running {len(jobs)} images in {build_root} ...", flush=True)
    with ThreadPoolExecutor(max_workers=2) as pool:
        runs = {(r["key"], r["opt"], r["empty"]): r for r in pool.map(do, jobs)}

    ok = True
    print(f"\none update per call, {opts.samples} simulated samples, Cortex-M3 soft float "
          "(QEMU stm32vldiscovery), executed instructions")
    print(f"{'block':22} {'opt':4} {'instr/update':>12} {'min..max':>15} {'Δflash B':>9} "
          f"{'max |target-host|':>18}")
    for key in opts.blocks:
        for opt in opts.opt:
            full, empty = runs[(key, opt, False)], runs[(key, opt, True)]
            problems = [f"QEMU exit {r['rc']}" for r in (full, empty) if r["rc"] != 0]
            rows, _ = parse_outputs(full["out"])
            worst = 0.0
            for i, ref in enumerate(refs[key]):
                if i not in rows or rows[i][0] != 0:
                    problems.append(f"sample {i}: no output or a fault")
                    break
                for tok, h, kd in zip(rows[i][1], ref, kinds[key], strict=True):
                    worst = max(worst, abs(decode(tok, kd) - float(h)))
            if worst > TOL:
                problems.append(f"outputs differ from the host by {worst:.3g}")
            per = [a - b for a, b in zip(full["counts"], empty["counts"], strict=False)]
            if len(per) != len(samples):
                problems.append(f"{len(per)} marker pairs, expected {len(samples)}")
            # sample 0 is the complementary filter's start (TRIAD only): leave it out
            steady = per[1:] if per else [0]
            mean = sum(steady) / max(1, len(steady))
            dflash = full["text"] + full["data"] - empty["text"] - empty["data"]
            print(f"{BLOCKS[key]:22} -{opt:3} {mean:12,.0f} {min(steady):>7,}..{max(steady):<7,} "
                  f"{dflash:9,} {worst:18.2e}")
            for p in problems:
                ok = False
                print(f"FAIL {key} -{opt}: {p}")
    print("Δflash: the block's code and the library routines it pulls in (the sample tables "
          "are in the empty image too)")
    shutil.rmtree(build_root, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
