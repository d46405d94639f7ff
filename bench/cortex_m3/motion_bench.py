"""Cortex-M3 instructions for one Bresenham step and one trapezoidal profile evaluation.

The motion functions of st/ (MotionBresenhamAdvance with Steps = 1, MotionTrapezoidEval) are
compiled to C by armbench's compiler and run on QEMU's stm32vldiscovery (Cortex-M3,
soft-float), with the harness, build, trace counting and empty-kernel subtraction of
run_bench.py (docs/cortex-m3-bench.md). Each call is made as emitted callers make it: the
function frame initialised, the inputs copied in, the body run.

- Bresenham: one 100-step line with deltas (100, -37, 64) from the origin, one call per step;
  every grid point is checked against the exact integer rounding (Python integers).
- Trapezoid: a plan of 120 deg with V0 = 20 deg/s, Vmax 60 deg/s, A 150 deg/s^2 (made on the
  host by the same ST), evaluated at 200 times covering all three phases and the end; every
  output is checked against the same ST run on the host (within 1e-3).

Run: .venv/bin/python bench/cortex_m3/motion_bench.py [--opt O0 O2] [--build-dir DIR]
Exit: 0 ok, 1 a build, run or check failed, 2 the tool chain is missing.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import run_bench as rb  # noqa: E402  (the shared Cortex-M3 harness next to this file)

from armbench.compiler import compile_files  # noqa: E402
from armbench.compiler.driver import emit_files  # noqa: E402

# MotionJoint.st plans profile 4 with the jerk-limited blocks
FILES = ["ArmAngles.st", "Kinematics.st", "MotionTypes.st", "MotionProfiles.st",
         "MotionJerkTypes.st", "MotionJerkRoots.st", "MotionJerkProfile.st",
         "MotionJerkStep1.st", "MotionJerkStep2.st", "MotionJerkVelocity.st",
         "MotionJerkSync.st", "MotionJerkOnline.st", "MotionJoint.st", "MotionLine.st"]
DELTAS = (100, -37, 64)
PLAN_ARGS = {"Dist": 120.0, "V0": 20.0, "VMax": 60.0, "Acc": 150.0}
N_TIMES = 200


def bresenham_ref(k: int) -> list[int]:
    d = [abs(x) for x in DELTAS]
    major = max(d)
    return [(2 * k * di + major) // (2 * major) for di in d]


def harness_bresenham(start: dict[str, Any], state_leaves: list[rb.Leaf],
                      state_type: Any) -> str:
    n = start["Steps"]
    init = [f"    state{lf.path} = {rb.c_literal(v, lf)};"
            for lf, v in zip(state_leaves, rb.py_leaves(state_type, start), strict=True)]
    return "\n".join([
        '#include "kernel_gen.c"', '#include "semihost.h"', f"#define N {n}",
        "volatile int32_t bench_sink_i;", "static S_MOTIONBRESENHAM state;",
        "int main(void) {", *init,
        "    for (int32_t i = 0; i < N; i++) {",
        "        bench_mark_begin(i);",
        "#ifdef BENCH_EMPTY",
        "        bench_sink_i = i;",
        "        bench_mark_end(i);",
        "#else",
        "        FN_MOTIONBRESENHAMADVANCE f;",
        "        FN_MOTIONBRESENHAMADVANCE_init(&f);",
        "        f.STEPS = 1;",
        "        f.STATE = &state;",
        "        int rc = FN_MOTIONBRESENHAMADVANCE_run(&f);",
        "        bench_mark_end(i);",
        '        bench_puts("R "); bench_put_dec(i); bench_puts(" "); bench_put_dec(rc);',
        '        bench_puts(" "); bench_put_dec(f.ret_);',
        "        for (int k = 0; k < 3; k++) { bench_puts(\" \"); "
        "bench_put_dec(state.COUNT.v[k]); }",
        '        bench_puts("\\n");',
        "#endif",
        "    }",
        "    return 0;",
        "}", ""])


def harness_trapezoid(plan: dict[str, Any], plan_leaves: list[rb.Leaf], plan_type: Any,
                      times: list[float]) -> str:
    init = [f"    plan{lf.path} = {rb.c_literal(v, lf)};"
            for lf, v in zip(plan_leaves, rb.py_leaves(plan_type, plan), strict=True)]
    table = ",\n  ".join(", ".join(f"{t.hex()}f" for t in times[k:k + 6])
                         for k in range(0, len(times), 6))
    return "\n".join([
        '#include "kernel_gen.c"', '#include "semihost.h"', f"#define N {len(times)}",
        "volatile float bench_sink_f;", "static S_MOTIONTRAPEZOID plan;",
        f"static const float TIMES[N] = {{\n  {table}\n}};",
        "static void put_f(float x) { union { float f; uint32_t u; } c; c.f = x; "
        "bench_puts(\" \"); bench_put_hex(c.u); }",
        "int main(void) {", *init,
        "    for (int32_t i = 0; i < N; i++) {",
        "        bench_mark_begin(i);",
        "#ifdef BENCH_EMPTY",
        "        bench_sink_f = TIMES[i];",
        "        bench_mark_end(i);",
        "#else",
        "        FN_MOTIONTRAPEZOIDEVAL f;",
        "        FN_MOTIONTRAPEZOIDEVAL_init(&f);",
        "        f.PLAN = plan;",
        "        f.TIMES = TIMES[i];",
        "        int rc = FN_MOTIONTRAPEZOIDEVAL_run(&f);",
        "        bench_mark_end(i);",
        '        bench_puts("R "); bench_put_dec(i); bench_puts(" "); bench_put_dec(rc);',
        "        put_f(f.ret_.POS); put_f(f.ret_.VEL); put_f(f.ret_.ACC);",
        '        bench_puts("\\n");',
        "#endif",
        "    }",
        "    return 0;",
        "}", ""])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opt", nargs="+", default=["O0", "O2"], help="gcc levels (O0 O2 Os)")
    ap.add_argument("--build-dir", type=Path, help="keep the builds here (default: temporary)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per QEMU run")
    opts = ap.parse_args()
    rb.ensure_tools()
    build_root = opts.build_dir or Path(tempfile.mkdtemp(prefix="armbench_cm3_motion_"))
    files = rb.snapshot_st(build_root, list(FILES))

    host = compile_files(files)
    prog, unit = emit_files(files)
    types = prog.types
    start = host.call("MotionBresenhamStart", *DELTAS)
    t_min = host.call("MotionTrapezoidMinTime", **PLAN_ARGS)
    plan = host.call("MotionTrapezoidPlan", Dist=PLAN_ARGS["Dist"], V0=PLAN_ARGS["V0"],
                     Duration=t_min, Acc=PLAN_ARGS["Acc"])
    times = [rb.f32(plan["Duration"] * 1.05 * k / (N_TIMES - 1)) for k in range(N_TIMES)]
    host_trap = [host.call("MotionTrapezoidEval", Plan=plan, TimeS=t) for t in times]

    bres_t, trap_t = types["MOTIONBRESENHAM"], types["MOTIONTRAPEZOID"]
    kernels = {
        "bresenham step": harness_bresenham(start, rb.leaves(bres_t, ""), bres_t),
        "trapezoid eval": harness_trapezoid(plan, rb.leaves(trap_t, ""), trap_t, times),
    }
    print(f"building and running {2 * len(kernels) * len(opts.opt)} images in {build_root}",
          flush=True)
    ok = True
    rows = []
    for name, harness in kernels.items():
        for opt in opts.opt:
            res = {}
            for empty in (False, True):
                wd = build_root / f"{name.split()[0]}_{opt}{'_empty' if empty else ''}"
                elf, info = rb.build(wd, unit.code, harness, opt, empty)
                rc, text, counts = rb.run_qemu(elf, info, opts.timeout)
                res[empty] = (rc, text, counts, info)
            rc, text, counts, info = res[False]
            erc, _etext, ecounts, einfo = res[True]
            problems = []
            if rc != 0 or erc != 0:
                problems.append(f"QEMU exit {rc}/{erc}: {text[-300:]}")
            outs, _ = rb.parse_outputs(text)
            n = len(counts)
            if n != len(ecounts) or n == 0:
                problems.append(f"{n} vs {len(ecounts)} marker pairs")
            for i in range(n):
                if i not in outs:
                    problems.append(f"call {i}: no output")
                    break
                prc, toks = outs[i]
                if prc != 0:
                    problems.append(f"call {i}: PLC fault")
                if name.startswith("bresenham"):
                    got = [int(t) for t in toks]
                    if got != [1, *bresenham_ref(i + 1)]:
                        problems.append(f"step {i + 1}: {got[1:]} vs {bresenham_ref(i + 1)}")
                else:
                    vals = [rb.decode(t, "real") for t in toks]
                    want = host_trap[i]
                    err = max(abs(v - want[k]) for v, k in zip(vals, ("Pos", "Vel", "Acc"),
                                                                strict=True))
                    if err > rb.TOL:
                        problems.append(f"t = {times[i]}: differs from the host by {err:.3g}")
            per = [a - b for a, b in zip(counts, ecounts, strict=False)]
            for p in problems[:5]:
                print(f"FAIL {name} -{opt}: {p}")
            ok = ok and not problems
            if per:
                rows.append((name, opt, statistics.mean(per), min(per), max(per),
                             statistics.median(per),
                             info["text"] + info["data"] - einfo["text"] - einfo["data"]))
    print()
    print("| kernel | -O | instr / call (mean) | median | min..max | Δflash B |")
    print("|---|---|---:|---:|---:|---:|")
    for name, opt, mean, lo, hi, med, dflash in rows:
        print(f"| {name} | -{opt} | {mean:,.1f} | {med:,.0f} | {lo:,}..{hi:,} | {dflash:,} |")
    print("\nchecks: " + ("all calls agree with the references" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
