"""Cortex-M3 instructions per jerk-limited trajectory calculation (prints a table).

The ST generator (st/MotionJerk*.st) is compiled to C by armbench's compiler and run on QEMU
with the harness, build, trace counting and empty-kernel subtraction of run_bench.py
(docs/cortex-m3-bench.md): soft-float (LREAL is a double in libgcc's software routines).
The board differs from the IK bench: MotionJerkPlanner holds six axes' blocks and profiles
(about 27 KB) and a calculation needs about 13 KB of stack, more than the STM32F100's 8 KB
of SRAM, so the image runs on QEMU's lm3s6965evb (Stellaris LM3S6965, also a Cortex-M3,
256 KB flash, 64 KB SRAM; the instruction count depends on the core, not the board).

Kernels, each call between the two markers:
- plan 1 axis: MotionJerkPlanner with Joints = 1, position interface (input check, brake,
  step 1), on the jerk_support case families;
- plan 6 axes: Joints = 6, time synchronisation (6 step-1 and up to 5 step-2 searches);
- generator scan, re-plan: MotionJerkGenerator with 6 joints in a scan where the target
  moves (a 6-axis plan and the evaluation);
- generator scan, evaluate: the same block in a scan on an unchanged target.
Every planned duration (the double's bits, over semihosting) must equal the same ST run on
the host (armbench.compiler.compile_files) and Ruckig's within 1e-9.

Run: .venv/bin/python bench/cortex_m3/jerk_m3.py [--opt O2 Os] [--cases 48] [--scans 20]
Exit: 0 ok, 1 a build, run or check failed, 2 the tool chain is missing.
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import struct
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent.parent / "tests" / "unit"))

import jerk_support as js  # noqa: E402
import run_bench as rb  # noqa: E402  (the shared Cortex-M3 harness next to this file)

from armbench.compiler import compile_files  # noqa: E402
from armbench.compiler.driver import emit_files  # noqa: E402

FILES = ["MotionJerkTypes.st", "MotionJerkRoots.st", "MotionJerkProfile.st",
         "MotionJerkStep1.st", "MotionJerkStep2.st", "MotionJerkVelocity.st",
         "MotionJerkSync.st", "MotionJerkOnline.st"]

LD_SCRIPT = """/* TI Stellaris LM3S6965 (QEMU machine lm3s6965evb): 256 KB flash, 64 KB SRAM. */
ENTRY(Reset_Handler)
MEMORY
{
  FLASH (rx)  : ORIGIN = 0x00000000, LENGTH = 256K
  SRAM  (rwx) : ORIGIN = 0x20000000, LENGTH = 64K
}
_estack = ORIGIN(SRAM) + LENGTH(SRAM);
_min_stack = 0x6000;
SECTIONS
{
  .isr_vector : { KEEP(*(.isr_vector)) } > FLASH
  .text : { *(.text .text.*) *(.rodata .rodata.*) KEEP(*(.init)) KEEP(*(.fini))
            . = ALIGN(4); } > FLASH
  .ARM.exidx : { *(.ARM.exidx* .gnu.linkonce.armexidx.*) } > FLASH
  _sidata = LOADADDR(.data);
  .data : { . = ALIGN(4); _sdata = .; *(.data .data.*) . = ALIGN(4); _edata = .; }
          > SRAM AT > FLASH
  .bss (NOLOAD) : { . = ALIGN(4); _sbss = .; *(.bss .bss.* COMMON) . = ALIGN(4); _ebss = .;
                    end = .; _end = .; } > SRAM
  ASSERT(_ebss + _min_stack <= _estack, "SRAM overflow: not enough room for the stack")
}
"""

HARNESS_HEAD = r"""
#include "kernel_gen.c"
#include "semihost.h"
static FB_MOTIONJERKPLANNER fb;
static FB_MOTIONJERKGENERATOR gen;
volatile double bench_sink_d;
static void put_d(double x) {
    union { double d; uint32_t u[2]; } c; c.d = x;
    bench_puts(" "); bench_put_hex(c.u[1]); bench_put_hex(c.u[0]);
}
static void load(const double *c, int k) {
    fb.CURRENTPOS.v[k] = c[0]; fb.CURRENTVEL.v[k] = c[1]; fb.CURRENTACC.v[k] = c[2];
    fb.TARGETPOS.v[k] = c[3]; fb.TARGETVEL.v[k] = c[4]; fb.TARGETACC.v[k] = c[5];
    fb.LIMITS.v[k].MAXVEL = c[6]; fb.LIMITS.v[k].MAXACC = c[7]; fb.LIMITS.v[k].MAXJERK = c[8];
    fb.LIMITS.v[k].MINVEL = c[9]; fb.LIMITS.v[k].MINACC = c[10];
    fb.LIMITS.v[k].SEPARATEMIN = c[11] != 0.0;
}
/* the stack's high-water mark: paint the free SRAM below the stack, find the deepest write */
extern uint32_t _ebss;
#define PAINT 0x5a5aa5a5u
static void paint_stack(void) {
    uint32_t *p = &_ebss, *sp = (uint32_t *)__builtin_frame_address(0) - 64;
    while (p < sp) *p++ = PAINT;
}
static void put_stack(void) {
    uint32_t *p = &_ebss;
    while (*p == PAINT) p++;
    bench_puts("S "); bench_put_dec((int32_t)(0x20010000u - (uint32_t)p)); bench_puts("\n");
}
"""


def table(name: str, rows: list[list[float]]) -> str:
    body = ",\n  ".join("{" + ", ".join(x.hex() for x in r) + "}" for r in rows)
    return f"static const double {name}[{len(rows)}][{len(rows[0])}] = {{\n  {body}\n}};"


def axis_row(c: js.AxisCase) -> list[float]:
    sep = 1.0 if c.vmin is not None or c.amin is not None else 0.0
    return [float(x) for x in (c.p0, c.v0, c.a0, c.pf, c.vf, c.af, c.vmax, c.amax, c.jmax,
                               c.v_lo, c.a_lo, sep)]


def planner_harness(rows: list[list[float]], joints: int, count: int) -> str:
    """The C main timing MotionJerkPlanner on ``count`` cases of ``joints`` axes (``rows``:
    one axis_row per axis, the cases one after another)."""
    return "\n".join([
        HARNESS_HEAD, table("CASES", rows),
        "int main(void) {",
        "    paint_stack();",
        "    FB_MOTIONJERKPLANNER_init(&fb);",
        f"    fb.JOINTS = {joints}; fb.SYNC = 0; fb.VELOCITYMODE = 0;",
        f"    for (int32_t i = 0; i < {count}; i++) {{",
        f"        for (int k = 0; k < {joints}; k++) load(CASES[{joints} * i + k], k);",
        "        bench_mark_begin(i);",
        "#ifdef BENCH_EMPTY",
        f"        bench_sink_d = CASES[{joints} * i][0];",
        "        bench_mark_end(i);",
        "#else",
        "        int rc = FB_MOTIONJERKPLANNER_run(&fb);",
        "        bench_mark_end(i);",
        '        bench_puts("R "); bench_put_dec(i); bench_puts(" "); bench_put_dec(rc);',
        '        bench_puts(" "); bench_put_dec(fb.ERRORID); put_d(fb.DURATION);',
        '        bench_puts("\\n");',
        "#endif",
        "    }",
        "    put_stack();",
        "    return 0;",
        "}", ""])


def harness(kernel: str, one: list[js.AxisCase], six: list[tuple[js.AxisCase, ...]],
            scans: int) -> str:
    if kernel == "plan 1 axis":
        return planner_harness([axis_row(c) for c in one], 1, len(one))
    if kernel == "plan 6 axes":
        return planner_harness([axis_row(c) for axes in six for c in axes], 6, len(six))
    replan = kernel == "generator scan, re-plan"
    targets = [[5.0 * k + 40.0 * math.sin(0.013 * s + k) for k in range(6)]
               for s in range(scans)]
    return "\n".join([
        HARNESS_HEAD, table("TARGETS", targets),
        "int main(void) {",
        "    paint_stack();",
        "    FB_MOTIONJERKGENERATOR_init(&gen);",
        "    gen.ENABLE = 1; gen.CYCLETIME = 0.01; gen.JOINTS = 6; gen.SYNC = 0;",
        "    for (int k = 0; k < 6; k++) {",
        "        gen.LIMITS.v[k].MAXVEL = 90.0 + 10.0 * k;",
        "        gen.LIMITS.v[k].MAXACC = 400.0 - 30.0 * k;",
        "        gen.LIMITS.v[k].MAXJERK = 4000.0 + 500.0 * k;",
        "        gen.STARTPOS.v[k] = 5.0 * k;",
        # re-plan: every scan's target is new; evaluate: the enabling scan already has it
        f"        gen.TARGETPOS.v[k] = {'5.0 * k' if replan else 'TARGETS[0][k]'};",
        "    }",
        "#ifndef BENCH_EMPTY",
        "    FB_MOTIONJERKGENERATOR_run(&gen);  /* enable: plan to the start, 1 scan */",
        "#endif",
        f"    for (int32_t i = 0; i < {scans}; i++) {{",
        f"        for (int k = 0; k < 6; k++) "
        f"gen.TARGETPOS.v[k] = TARGETS[{'i' if replan else '0'}][k];",
        "        bench_mark_begin(i);",
        "#ifdef BENCH_EMPTY",
        "        bench_sink_d = gen.TARGETPOS.v[0];",
        "        bench_mark_end(i);",
        "#else",
        "        int rc = FB_MOTIONJERKGENERATOR_run(&gen);",
        "        bench_mark_end(i);",
        '        bench_puts("R "); bench_put_dec(i); bench_puts(" "); bench_put_dec(rc);',
        '        bench_puts(" "); bench_put_dec(gen.NEWPLAN * 100 + gen.ERRORID);',
        "        put_d(gen.DURATION);",
        '        bench_puts("\\n");',
        "#endif",
        "    }",
        "    put_stack();",
        "    return 0;",
        "}", ""])


def decode_double(tok: str) -> float:
    """put_d's 16 hex digits: the double's bits, most significant word first."""
    return float(struct.unpack("<d", struct.pack("<Q", int(tok, 16)))[0])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opt", nargs="+", default=["O2", "Os"],
                    help="gcc levels (O2 Os; at -O0 the code, about 300 KB, does not fit the "
                         "LM3S6965's 256 KB of flash)")
    ap.add_argument("--cases", type=int, default=48, help="single-axis cases (6-axis: 1/3)")
    ap.add_argument("--scans", type=int, default=20, help="generator scans per kind")
    ap.add_argument("--build-dir", type=Path, help="keep the builds here (default: temporary)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per QEMU run")
    opts = ap.parse_args()
    rb.ensure_tools()
    build_root = opts.build_dir or Path(tempfile.mkdtemp(prefix="armbench_cm3_jerk_"))
    files = rb.snapshot_st(build_root, list(FILES))
    ld = build_root / "lm3s6965.ld"
    ld.write_text(LD_SCRIPT)
    # the IK bench's board has 8 KB of SRAM: this one runs on the LM3S6965 (64 KB)
    rb.LDFLAGS = [f"-T{ld}" if f.startswith("-T") else f for f in rb.LDFLAGS]
    rb.QEMU_ARGS = [("lm3s6965evb" if a == "stm32vldiscovery" else a) for a in rb.QEMU_ARGS]

    host = compile_files(files)
    runner = js.StRunner(host)
    per = max(1, opts.cases // len(js.FAMILIES))
    one = [c for _, c in js.axis_cases(3, per)]
    rng = random.Random(9)
    six = [js.multi_case(rng, ("rest", "moving", "target_velocity")[k % 3], 6).axes
           for k in range(max(1, opts.cases // 3))]
    want: dict[str, list[float]] = {
        "plan 1 axis": [runner.plan((c,)).duration for c in one],
        "plan 6 axes": [runner.plan(axes).duration for axes in six],
    }
    ref_one = [js.ruckig_plan((c,)).duration for c in one]
    ref_six = [js.ruckig_plan(axes) for axes in six]
    prog, unit = emit_files(files)
    kernels = ["plan 1 axis", "plan 6 axes", "generator scan, re-plan",
               "generator scan, evaluate"]
    print(f"building and running {2 * len(kernels) * len(opts.opt)} images in {build_root}",
          flush=True)
    ok = True
    rows = []
    for name in kernels:
        code = harness(name, one, six, opts.scans)
        for opt in opts.opt:
            res: dict[bool, Any] = {}
            for empty in (False, True):
                wd = build_root / f"{name.replace(' ', '_').replace(',', '')}_{opt}" \
                    f"{'_empty' if empty else ''}"
                elf, info = rb.build(wd, unit.code, code, opt, empty)
                rc, text, counts = rb.run_qemu(elf, info, opts.timeout)
                res[empty] = (rc, text, counts, info)
            rc, text, counts, info = res[False]
            erc, _t, ecounts, einfo = res[True]
            problems = []
            if rc != 0 or erc != 0:
                problems.append(f"QEMU exit {rc}/{erc}: {text[-300:]}")
            outs, _ = rb.parse_outputs(text)
            if len(counts) != len(ecounts) or not counts:
                problems.append(f"{len(counts)} vs {len(ecounts)} marker pairs")
            for i in range(len(counts)):
                if i not in outs:
                    problems.append(f"call {i}: no output")
                    break
                prc, toks = outs[i]
                code_out = int(toks[0])
                dur = decode_double(toks[1])
                if prc != 0:
                    problems.append(f"call {i}: PLC fault")
                if name in want:
                    ref = ref_one[i] if name == "plan 1 axis" else ref_six[i].duration
                    if dur != want[name][i] and not (math.isnan(dur) and math.isnan(want[name][i])):
                        problems.append(f"case {i}: {dur!r} vs the host's {want[name][i]!r}")
                    if math.isfinite(ref) and abs(dur - ref) > 1e-9 * max(ref, 1.0):
                        problems.append(f"case {i}: {dur!r} vs Ruckig's {ref!r}")
                elif name.endswith("re-plan") and code_out != 100:
                    problems.append(f"scan {i}: no re-plan ({code_out})")
                elif name.endswith("evaluate") and code_out != 0:
                    problems.append(f"scan {i}: re-planned or error ({code_out})")
            per_call = [a - b for a, b in zip(counts, ecounts, strict=False)]
            stack = max((int(ln.split()[1]) for ln in text.splitlines()
                         if ln.startswith("S ")), default=-1)
            for p in problems[:5]:
                print(f"FAIL {name} -{opt}: {p}")
            ok = ok and not problems
            if per_call:
                rows.append((name, opt, len(per_call), statistics.mean(per_call),
                             statistics.median(per_call), min(per_call), max(per_call),
                             info["text"] + info["data"] - einfo["text"] - einfo["data"],
                             info["bss"], stack))
    print()
    print("| kernel | -O | calls | instr / call (mean) | median | min..max | Δflash B | "
          "static RAM B | stack B |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, opt, n, mean, med, lo, hi, dflash, bss, stack in rows:
        print(f"| {name} | -{opt} | {n} | {mean:,.0f} | {med:,.0f} | {lo:,}..{hi:,} | "
              f"{dflash:,} | {bss:,} | {stack:,} |")
    print("\nchecks: " + ("every duration equals the host's and Ruckig's" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
