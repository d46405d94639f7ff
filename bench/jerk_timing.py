"""Time per trajectory calculation: the ST generator (st/MotionJerk*.st compiled to C by
armbench's compiler) against Ruckig's C++ on the same cases, in one run (prints figures, not a
test).

Both are built here with the host's compilers at -O2 and read the same case file: the ST's
MotionJerkPlanner through armbench's emitted C (its own runtime: array bounds checked as the
soft PLC does), Ruckig 0.19.4's C++ sources (the PyPI sdist, `Ruckig<DynamicDOFs>::calculate`).
Each case is calculated --reps times in a row and the mean per calculation is its time; the
table gives the mean, median and 99th percentile over the cases, per case set. The durations
both print are compared (they must agree to 1e-9), so the two timed the same work.

Also the scan-time share of MotionJerkGenerator with 6 joints at a 10 ms task: a scan in which
the target changes (a full re-plan of 6 axes plus the evaluation) and a scan that only
evaluates, as a fraction of 10 ms.

The machine is shared: figures are what this run measured, noisy at the 10 % level.

Run: .venv/bin/python bench/jerk_timing.py [--cases 2000] [--reps 20] [--ruckig-src DIR]
(PYTHONPATH=sim from a worktree). Without --ruckig-src the sdist of the installed ruckig
version is fetched with pip into ~/.cache/armbench/ruckig-src.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import random
import statistics
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "unit"))

import jerk_support as js  # noqa: E402

from armbench.compiler.build import RUNTIME_DIR, cache_dir  # noqa: E402
from armbench.compiler.driver import emit_files  # noqa: E402

SYNC = {"Time": 0, "Phase": 1, "None": 2, "TimeIfNecessary": 3}

ST_HARNESS = r"""
#include "kernel_gen.c"
#include <stdio.h>
#include <stdlib.h>
static double now_s(void) {
    struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec;
}
static FB_MOTIONJERKPLANNER fb;
static FB_MOTIONJERKGENERATOR gen;
static void read_case(FILE *f, int *sync, int *vel) {
    int dofs;
    if (fscanf(f, "%d %d %d", &dofs, sync, vel) != 3) exit(3);
    fb.JOINTS = (int16_t)dofs; fb.SYNC = (int16_t)*sync; fb.VELOCITYMODE = (uint8_t)*vel;
    for (int k = 0; k < dofs; k++) {
        double p0, v0, a0, pf, vf, af, vmax, amax, jmax, vmin, amin; int sep;
        if (fscanf(f, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %d", &p0, &v0, &a0, &pf,
                   &vf, &af, &vmax, &amax, &jmax, &vmin, &amin, &sep) != 12) exit(3);
        fb.CURRENTPOS.v[k] = p0; fb.CURRENTVEL.v[k] = v0; fb.CURRENTACC.v[k] = a0;
        fb.TARGETPOS.v[k] = pf; fb.TARGETVEL.v[k] = vf; fb.TARGETACC.v[k] = af;
        fb.LIMITS.v[k].MAXVEL = vmax; fb.LIMITS.v[k].MAXACC = amax;
        fb.LIMITS.v[k].MAXJERK = jmax; fb.LIMITS.v[k].SEPARATEMIN = (uint8_t)sep;
        fb.LIMITS.v[k].MINVEL = vmin; fb.LIMITS.v[k].MINACC = amin;
    }
}
int main(int argc, char **argv) {
    FILE *f = fopen(argv[1], "r");
    int reps = atoi(argv[2]);
    int n, sync, vel;
    if (!f || fscanf(f, "%d", &n) != 1) return 3;
    FB_MOTIONJERKPLANNER_init(&fb);
    for (int c = 0; c < n; c++) {
        read_case(f, &sync, &vel);
        double t0 = now_s();
        for (int r = 0; r < reps; r++) FB_MOTIONJERKPLANNER_run(&fb);
        double t1 = now_s();
        printf("C %d %d %.17g %.9g\n", c, fb.VALID ? 0 : fb.ERRORID, fb.DURATION,
               (t1 - t0) / reps * 1e6);
    }
    /* the generator, 6 joints at 10 ms: scans with a new target and scans without */
    FB_MOTIONJERKGENERATOR_init(&gen);
    gen.ENABLE = 1; gen.CYCLETIME = 0.01; gen.JOINTS = 6; gen.SYNC = 0;
    for (int k = 0; k < 6; k++) {
        gen.LIMITS.v[k].MAXVEL = 90.0 + 10.0 * k; gen.LIMITS.v[k].MAXACC = 400.0 - 30.0 * k;
        gen.LIMITS.v[k].MAXJERK = 4000.0 + 500.0 * k; gen.STARTPOS.v[k] = 5.0 * k;
        gen.TARGETPOS.v[k] = 5.0 * k;
    }
    FB_MOTIONJERKGENERATOR_run(&gen);
    int scans = reps * 50;
    double replan = 0.0, follow = 0.0;
    for (int s = 0; s < scans; s++) {
        for (int k = 0; k < 6; k++)   /* a target that moves every scan: re-plan each time */
            gen.TARGETPOS.v[k] = 5.0 * k + 40.0 * __builtin_sin(0.013 * s + k);
        double t0 = now_s();
        FB_MOTIONJERKGENERATOR_run(&gen);
        replan += now_s() - t0;
        if (!gen.NEWPLAN || gen.ERROR) { printf("generator did not re-plan\n"); return 4; }
    }
    for (int s = 0; s < scans; s++) {   /* the same target: evaluation only */
        double t0 = now_s();
        FB_MOTIONJERKGENERATOR_run(&gen);
        follow += now_s() - t0;
        if (gen.NEWPLAN) { printf("generator re-planned\n"); return 4; }
    }
    printf("G %.9g %.9g\n", replan / scans * 1e6, follow / scans * 1e6);
    return 0;
}
"""

RUCKIG_HARNESS = r"""
#include <ruckig/ruckig.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
using namespace ruckig;
int main(int argc, char **argv) {
    FILE *f = std::fopen(argv[1], "r");
    int reps = std::atoi(argv[2]);
    int n;
    if (!f || std::fscanf(f, "%d", &n) != 1) return 3;
    for (int c = 0; c < n; c++) {
        int dofs, sync, vel;
        if (std::fscanf(f, "%d %d %d", &dofs, &sync, &vel) != 3) return 3;
        Ruckig<DynamicDOFs> otg(dofs);
        InputParameter<DynamicDOFs> inp(dofs);
        Trajectory<DynamicDOFs> traj(dofs);
        bool separate = false;
        std::vector<double> vmins(dofs), amins(dofs);
        for (int k = 0; k < dofs; k++) {
            double p0, v0, a0, pf, vf, af, vmax, amax, jmax, vmin, amin; int sep;
            if (std::fscanf(f, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %d", &p0, &v0, &a0,
                            &pf, &vf, &af, &vmax, &amax, &jmax, &vmin, &amin, &sep) != 12)
                return 3;
            inp.current_position[k] = p0; inp.current_velocity[k] = v0;
            inp.current_acceleration[k] = a0; inp.target_position[k] = pf;
            inp.target_velocity[k] = vf; inp.target_acceleration[k] = af;
            inp.max_velocity[k] = vmax; inp.max_acceleration[k] = amax; inp.max_jerk[k] = jmax;
            vmins[k] = vmin; amins[k] = amin; separate = separate || sep;
        }
        if (separate) { inp.min_velocity = vmins; inp.min_acceleration = amins; }
        inp.synchronization = sync == 0 ? Synchronization::Time : sync == 1 ?
            Synchronization::Phase : sync == 2 ? Synchronization::None :
            Synchronization::TimeIfNecessary;
        inp.control_interface = vel ? ControlInterface::Velocity : ControlInterface::Position;
        Result r = Result::Working;
        auto t0 = std::chrono::steady_clock::now();
        for (int i = 0; i < reps; i++) r = otg.calculate(inp, traj);
        auto t1 = std::chrono::steady_clock::now();
        double us = std::chrono::duration<double, std::micro>(t1 - t0).count() / reps;
        std::printf("C %d %d %.17g %.9g\n", c, (int)r, r == Result::Working ?
                    traj.get_duration() : 0.0, us);
    }
    return 0;
}
"""


@dataclass(frozen=True)
class CaseSet:
    name: str
    cases: list[tuple[tuple[js.AxisCase, ...], str, str]]  # axes, synchronization, interface


def case_sets(n: int, seed: int) -> list[CaseSet]:
    per = max(1, n // len(js.FAMILIES))
    one_pos = [((c,), "Time", "Position") for _, c in js.axis_cases(seed, per)]
    one_vel = [((c,), "Time", "Velocity") for _, c in js.axis_cases(seed + 1, per)]
    rng = random.Random(seed + 2)
    six = []
    for k in range(n):
        fam = js.FAMILIES[k % len(js.FAMILIES)]
        six.append((js.multi_case(rng, fam, 6).axes, "Time", "Position"))
    return [CaseSet("1 axis, position", one_pos), CaseSet("1 axis, velocity", one_vel),
            CaseSet("6 axes, time sync, position", six)]


def write_cases(path: Path, cases: list[tuple[tuple[js.AxisCase, ...], str, str]]) -> None:
    lines = [str(len(cases))]
    for axes, sync, interface in cases:
        lines.append(f"{len(axes)} {SYNC[sync]} {int(interface == 'Velocity')}")
        for c in axes:
            sep = int(c.vmin is not None or c.amin is not None)
            lines.append(" ".join(repr(float(x)) for x in (c.p0, c.v0, c.a0, c.pf, c.vf, c.af,
                                                            c.vmax, c.amax, c.jmax, c.v_lo,
                                                            c.a_lo)) + f" {sep}")
    path.write_text("\n".join(lines) + "\n")


def ruckig_sources(given: Path | None) -> Path:
    if given is not None:
        return given
    version = importlib.metadata.version("ruckig")
    base = cache_dir() / "ruckig-src"
    src = base / f"ruckig-{version}"
    if not (src / "include" / "ruckig" / "ruckig.hpp").exists():
        base.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "pip", "download", f"ruckig=={version}",
                        "--no-binary", ":all:", "--no-deps", "-d", str(base), "-q"], check=True)
        with tarfile.open(base / f"ruckig-{version}.tar.gz") as tar:
            tar.extractall(base, filter="data")
    return src


def parse(out: str) -> tuple[list[tuple[int, float, float]], tuple[float, float] | None]:
    rows, gen = [], None
    for line in out.splitlines():
        parts = line.split()
        if parts and parts[0] == "C":
            rows.append((int(parts[2]), float(parts[3]), float(parts[4])))
        elif parts and parts[0] == "G":
            gen = (float(parts[1]), float(parts[2]))
    return rows, gen


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000, help="cases per set")
    ap.add_argument("--reps", type=int, default=20, help="calculations per case")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--ruckig-src", type=Path, help="an unpacked ruckig source tree")
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="armbench_jerk_timing_"))
    files = sorted((ROOT / "st").glob("MotionJerk*.st"))
    _, unit = emit_files(files)
    (work / "kernel_gen.c").write_text(unit.code)
    (work / "st_harness.c").write_text(ST_HARNESS)
    (work / "rk_harness.cpp").write_text(RUCKIG_HARNESS)
    src = ruckig_sources(opts.ruckig_src)
    print(f"building in {work} (ST: gcc -O2; Ruckig {src.name}: g++ -O2 -std=c++20)",
          flush=True)
    subprocess.run(["gcc", "-O2", "-std=gnu11", "-fwrapv", "-fno-strict-aliasing", "-w",
                    "-DARMBENCH_NO_WATCHDOG", f"-I{RUNTIME_DIR}", f"-I{work}",
                    str(work / "st_harness.c"), "-lm", "-o", str(work / "st_bench")], check=True)
    rk_sources = [str(p) for p in sorted((src / "src" / "ruckig").glob("*.cpp"))
                  if "cloud" not in p.name]
    subprocess.run(["g++", "-O2", "-DNDEBUG", "-std=c++20", f"-I{src / 'include'}",
                    str(work / "rk_harness.cpp"), *rk_sources, "-o", str(work / "rk_bench")],
                   check=True)
    ok = True
    print()
    print("| cases | n | ST µs mean | median | p99 | Ruckig C++ µs mean | median | p99 | "
          "ST / Ruckig (mean) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    gen_figs = None
    for cs in case_sets(opts.cases, opts.seed):
        path = work / f"cases_{len(cs.name)}.txt"
        write_cases(path, cs.cases)
        st_out = subprocess.run([str(work / "st_bench"), str(path), str(opts.reps)],
                                capture_output=True, text=True, check=True).stdout
        rk_out = subprocess.run([str(work / "rk_bench"), str(path), str(opts.reps)],
                                capture_output=True, text=True, check=True).stdout
        st_rows, gen = parse(st_out)
        rk_rows, _ = parse(rk_out)
        gen_figs = gen or gen_figs
        both = [(s, r) for s, r in zip(st_rows, rk_rows, strict=True) if s[0] == 0 and r[0] == 0]
        differ = [(s, r) for s, r in both if abs(s[1] - r[1]) > 1e-9 * max(r[1], 1e-12)]
        if differ or len(both) < 0.9 * len(st_rows):
            ok = False
            print(f"FAIL {cs.name}: {len(differ)} durations differ, {len(both)} of "
                  f"{len(st_rows)} planned by both")
        st_t = [s[2] for s, _ in both]
        rk_t = [r[2] for _, r in both]
        q = js.percentile
        print(f"| {cs.name} | {len(both)} | {statistics.mean(st_t):.2f} | {q(st_t, 0.5):.2f} | "
              f"{q(st_t, 0.99):.2f} | {statistics.mean(rk_t):.2f} | {q(rk_t, 0.5):.2f} | "
              f"{q(rk_t, 0.99):.2f} | {statistics.mean(st_t) / statistics.mean(rk_t):.2f} |")
    if gen_figs is not None:
        replan, follow = gen_figs
        print()
        print("MotionJerkGenerator, 6 joints, 10 ms task (host, gcc -O2):")
        print(f"  scan with a new target (re-plan + evaluate): {replan:.2f} µs = "
              f"{replan / 100.0:.3f} % of 10 ms")
        print(f"  scan on the same target (evaluate):          {follow:.2f} µs = "
              f"{follow / 100.0:.4f} % of 10 ms")
    print("\nchecks: " + ("both computed the same durations" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
