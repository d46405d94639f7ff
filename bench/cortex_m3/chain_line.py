"""Cortex-M3 instruction count of document 003's 100-interval line (prints a table).

The fixed-point resolved-rate step ``ChainResolvedRateFixed`` (st/KinematicsChainFixed.st) is
compiled to C by armbench's ST compiler, linked into the bare-metal image of run_bench.py
(QEMU stm32vldiscovery, Cortex-M3, no FPU) and called 101 times: once with Reset (the start
configuration, not counted) and once per interval of the seed's line. Instructions are
counted exactly from QEMU's single-step trace between the markers around every call, minus
the same harness with an empty kernel, call by call. The target's outputs must equal the same
ST run on the host bit for bit. The seed measured 34 ms on a TMS320F206 at 25 ns per
instruction, i.e. about 1.36 M instructions for the 100 intervals.

Run: .venv/bin/python bench/cortex_m3/chain_line.py [--opt O0 O2] [--json FILE]
Exit: 0 ok, 1 a build, run or check failed, 2 the tool chain is missing.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import run_bench as rb  # noqa: E402  (the harness of the IK benchmark, same folder)

from armbench.compiler.driver import emit_files  # noqa: E402
from armbench.plant import redundant_chain as rc  # noqa: E402

POU = "ChainResolvedRateFixed"
FILES = ["ArmAngles.st", "KinematicsFixedTables.st", "KinematicsFixed.st",
         "KinematicsChainFixed.st"]
KERNEL_F32 = HERE.parent / "kernels" / "chain_step_f32.c"
SEED_MS = 34.0
SEED_NS_PER_INSTRUCTION = 25.0


def call_args() -> list[dict[str, Any]]:
    """Call 0 resets to the start configuration, calls 1..100 step along the line."""
    points = rc.line_points()
    init = rc.to_turn24(rc.start_configuration(points[0]))
    geo = rc.DEFAULT_CHAIN.as_st_um()
    out = []
    for k, x in enumerate(points):
        xu, yu, zu = (int(round(v * 1e6)) for v in x)
        out.append({"TargetXUm": xu, "TargetYUm": yu, "TargetZUm": zu, "Geometry": geo,
                    "DampingUm": 0, "Reset": k == 0, "InitJoints": init})
    return out


def host_outputs(files: list[Path], sym: Any, args: list[dict[str, Any]]) -> list[list[Any]]:
    """The same ST on the host, one instance for all calls (the block keeps its joints)."""
    inst = rb.compile_files(files).new_fb(POU)
    rows = []
    for a in args:
        inst(**a)
        rows.append([x for v in sym.vars.values() if v.kind == rb.A.VAR_OUTPUT
                     for x in rb.py_leaves(v.type, inst.get(v.name))])
    return rows


def float_harness() -> tuple[str, list[list[float]]]:
    """The C harness of the float32 kernel (same line, same start) and the host float32
    joints (armbench.plant.redundant_chain.track_float32) it must reproduce."""
    points = rc.line_points()
    q0 = rc.from_turn24(rc.to_turn24(rc.start_configuration(points[0])))
    geo = rc.DEFAULT_CHAIN
    host = rc.track_float32(points, q0).tolist()
    tgt = ",\n  ".join(", ".join(f"{float(v).hex()}f" for v in x) for x in points.astype("f4"))
    lines = ['#include "kernel_gen.c"', '#include "semihost.h"', f"#define N {len(points)}",
             "volatile float bench_sink_f;",
             f"static const float TARGET[N][3] = {{\n  {tgt}\n}};",
             "static const chain_geo_f32 GEO = {" + ", ".join(
                 f"{v.hex()}f" for v in (geo.a1, geo.a2, geo.a3, geo.a4, geo.a5)) + "};",
             "static uint32_t fbits(float f) { union { float f; uint32_t u; } c; c.f = f; "
             "return c.u; }",
             "int main(void) {",
             "    float q[4] = {" + ", ".join(f"{float(v).hex()}f" for v in q0) + "};",
             "    int fails = 0;",
             "    for (int32_t i = 0; i < N; i++) {",
             "        bench_mark_begin(i);",
             "#ifdef BENCH_EMPTY",
             "        bench_sink_f = TARGET[i][0] + TARGET[i][1] + TARGET[i][2];",
             "        bench_mark_end(i);",
             "#else",
             "        int rc = i == 0 ? 0 : chain_step_f32(&GEO, q, TARGET[i]);",
             "        bench_mark_end(i);",
             "        fails += rc;",
             '        bench_puts("R "); bench_put_dec(i); bench_puts(" 0");',
             "        for (int k = 0; k < 4; k++) {",
             "            bench_puts(\" \"); bench_put_hex(fbits(q[k]));",
             "        }",
             '        bench_puts("\\n");',
             "#endif",
             "    }",
             "    return fails ? 1 : 0;",
             "}", ""]
    return "\n".join(lines), host


def count_float(root: Path, opt: str, timeout: float) -> dict[str, Any]:
    """Instructions of the float32 kernel over the 100 intervals, checked against the host."""
    harness, host = float_harness()
    kernel = KERNEL_F32.read_text(encoding="utf-8")
    runs = {}
    for empty in (False, True):
        wd = root / f"chain_f32_{opt}{'_empty' if empty else ''}"
        elf, info = rb.build(wd, kernel, harness, opt, empty)
        runs[empty] = (*rb.run_qemu(elf, info, timeout), info)
    rc_full, text, counts, info = runs[False]
    rc_empty, _, counts_empty, info_empty = runs[True]
    problems = []
    if rc_full != 0 or rc_empty != 0:
        problems.append(f"QEMU exit {rc_full}/{rc_empty}: {text[-300:]}")
    rows, _ = rb.parse_outputs(text)
    worst = 0.0
    for i, want in enumerate(host):
        if i not in rows:
            problems.append(f"float step {i}: no output")
            break
        got = [rb.decode(t, "real") for t in rows[i][1]]
        worst = max(worst, max(abs(a - b) for a, b in zip(got, want, strict=True)))
    if worst > 1e-5:  # newlib's sinf/cosf vs numpy's float32 sin/cos: a few ulp per step
        problems.append(f"float joints differ from the host float32 run by {worst:.2e} rad")
    per = [a - b for a, b in zip(counts, counts_empty, strict=False)][1:]
    return {"opt": opt, "instructions_100_intervals": sum(per),
            "per_step": sum(per) / max(len(per), 1),
            "per_step_min": min(per) if per else 0, "per_step_max": max(per) if per else 0,
            "flash_delta": info["text"] + info["data"] - info_empty["text"]
            - info_empty["data"], "max_dev_vs_host_rad": worst, "problems": problems}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opt", nargs="+", default=["O0", "O2"], help="gcc levels")
    ap.add_argument("--build-dir", type=Path, help="keep the builds here")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per QEMU run")
    ap.add_argument("--json", type=Path, help="also write the results here")
    opts = ap.parse_args()
    rb.ensure_tools()
    root = opts.build_dir or Path(tempfile.mkdtemp(prefix="armbench_chain_"))
    files = rb.snapshot_st(root, list(FILES))
    method = rb.Method("chain", "003 line (ChainResolvedRateFixed)", files, POU)
    method.args = call_args()
    prog, unit = emit_files(files)
    sym = prog.pous[POU.upper()]
    harness = rb.harness_c(sym, method.args)
    ref = host_outputs(files, sym, method.args)
    kinds = [lf.kind for lf in rb.output_leaves(sym)]
    n = len(method.args)
    ok = True
    results = []
    for opt in opts.opt:
        runs = {}
        for empty in (False, True):
            wd = root / f"chain_{opt}{'_empty' if empty else ''}"
            elf, info = rb.build(wd, unit.code, harness, opt, empty)
            rc_, text, counts = rb.run_qemu(elf, info, opts.timeout)
            runs[empty] = (rc_, text, counts, info)
        rc_full, text, counts, info = runs[False]
        rc_empty, _, counts_empty, info_empty = runs[True]
        problems = []
        if rc_full != 0 or rc_empty != 0:
            problems.append(f"QEMU exit {rc_full}/{rc_empty}: {text[-300:]}")
        if len(counts) != n or len(counts_empty) != n:
            problems.append(f"{len(counts)}/{len(counts_empty)} marker pairs, expected {n}")
        rows, _ = rb.parse_outputs(text)
        for i in range(n):
            if i not in rows:
                problems.append(f"call {i}: no output")
                break
            vals = [rb.decode(t, k) for t, k in zip(rows[i][1], kinds, strict=True)]
            if [float(v) for v in ref[i]] != vals:
                problems.append(f"call {i}: target {vals} != host {ref[i]}")
                break
        per = [a - b for a, b in zip(counts, counts_empty, strict=False)]
        steps = per[1:]  # call 0 is the reset
        total = sum(steps)
        res = {"opt": opt, "instructions_100_intervals": total,
               "per_step": total / max(len(steps), 1),
               "per_step_min": min(steps) if steps else 0,
               "per_step_max": max(steps) if steps else 0,
               "reset_call": per[0] if per else 0,
               "flash_delta": info["text"] + info["data"] - info_empty["text"]
               - info_empty["data"], "problems": problems}
        results.append(res)
        if problems:
            ok = False
            for p in problems:
                print(f"FAIL -{opt}: {p}")
    floats = [count_float(root, opt, opts.timeout) for opt in opts.opt]
    for r in floats:
        for p in r["problems"]:
            ok = False
            print(f"FAIL float32 -{r['opt']}: {p}")
    seed_instr = SEED_MS * 1e6 / SEED_NS_PER_INSTRUCTION
    print(f"\nDocument 003's line, 100 intervals, {POU} (Cortex-M3 soft, QEMU "
          "stm32vldiscovery): executed instructions")
    hdr = (f"{'kernel':<22} {'-O':<4} {'100 intervals':>14} {'per step':>10} {'min..max':>15} "
           f"{'Δflash B':>9} {'at 25 ns':>9} {'seed 34 ms':>11} {'check':>6}")
    print(hdr)
    print("-" * len(hdr))
    for name, r in [*(("fixed point ST", r) for r in results),
                    *(("float32 C (soft-float)", r) for r in floats)]:
        ms = r["instructions_100_intervals"] * SEED_NS_PER_INSTRUCTION * 1e-6
        print(f"{name:<22} {'-' + r['opt']:<4} {r['instructions_100_intervals']:>14,} "
              f"{r['per_step']:>10.1f} {str(r['per_step_min']) + '..' + str(r['per_step_max']):>15}"
              f" {r['flash_delta']:>9} {ms:>7.2f} ms {seed_instr:>11,.0f} "
              f"{'ok' if not r['problems'] else 'FAIL':>6}")
    print(f"seed = 34 ms / 25 ns = {seed_instr:,.0f} instructions (TMS320F206, the truss's own "
          "equations); 'at 25 ns' = our count at the seed's instruction time.")
    if opts.json:
        opts.json.write_text(json.dumps({"results": results, "float32": floats}, indent=2)
                             + "\n")
    if not opts.build_dir:
        shutil.rmtree(root, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
