"""Time per trajectory calculation: the ST planner (st/MotionJerk*.st compiled to C by
armbench's compiler) against Ruckig's C++ on the same cases, side by side in one process and
one run (prints figures, not a test).

What is timed, in one C++ process that reads one case file:
- the ST's MotionJerkPlanner as armbench builds it: the shared library its build makes of
  st/ plus one small timing FB (TIMING_ST, below), with build.CFLAGS and split into
  translation units as on this machine (as pytest and the soft PLC get st/; from the build
  cache when it is there), loaded with dlopen; with `--variant NAME=FLAGS` also the same C
  built with FLAGS added (e.g. `O2=-O2`), and with `--baseline TREE` the same ST compiled by
  another checkout's armbench (before and after a compiler change), each a library of its
  own in the same process. The timing FB plans --reps times per call of the library, so the
  library's entry (a setjmp and the watchdog's clock read, what the soft PLC pays once per
  scan) is paid once per --reps plans (its cost, a trivial FUNCTION's `_run`, is printed as
  "entry");
- Ruckig 0.19.4's C++ (`Ruckig<DynamicDOFs>::calculate`, the PyPI sdist's sources, built
  here at -O2 with -DNDEBUG, cached), linked into the harness, --reps calculations in a C++
  loop.
Per case, each of them calculates once untimed, then in --rounds rounds --reps times in a row
between two clock reads (their cost per calculation is printed as "clock"), the
implementations taking turns round by round: the case's time is the mean per calculation of
its fastest round (the others were interrupted more often by whatever else runs on the
shared machine).

The durations both print are compared (they must agree to 1e-9), so the two timed the same
work; those of several ST builds must be equal bit for bit (as their verdicts). The table
gives per case set and implementation the mean, median and 99th percentile over the cases,
the ratio of the means to Ruckig's, and the median of the per-case ratios.

Also the scan-time share of MotionJerkGenerator with 6 joints at a 10 ms task, one scan per
call of the library: the median scan in which the target changes (a full re-plan of 6 axes
plus the evaluation) and the median scan that only evaluates, as a fraction of 10 ms.

The machine is shared: figures are what this run measured, noisy at the 10 % level.

Run: .venv/bin/python bench/jerk_timing.py [--cases 2000] [--reps 100] [--rounds 5]
[--variant O2=-O2] [--baseline TREE] [--ruckig-src DIR] (PYTHONPATH=sim from a worktree).
Without --ruckig-src the sdist of the installed ruckig version is fetched with pip into
~/.cache/armbench/ruckig-src. JERK_TIMING_PLANS_ONLY=1 in the environment of the built
harness leaves the generator out (for a profiler).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import random
import shlex
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "unit"))

import jerk_support as js  # noqa: E402

from armbench.compiler.build import CFLAGS, build, cache_dir  # noqa: E402
from armbench.compiler.driver import emit_files  # noqa: E402

SYNC = {"Time": 0, "Phase": 1, "None": 2, "TimeIfNecessary": 3}

# Many plans in one call of the library: the planner's inputs are copied in once, then it
# plans Reps times (FB inputs keep their values between calls), so the library's entry (a
# setjmp, the watchdog's clock read) is paid once per Reps plans, as a scan pays it once.
TIMING_ST = """
FUNCTION_BLOCK JerkTimingLoop
  VAR_INPUT
    Reps : DINT;
    Joints : INT;
    VelocityMode : BOOL;
    Sync : INT;
    CurrentPos : MotionJerkVector;
    CurrentVel : MotionJerkVector;
    CurrentAcc : MotionJerkVector;
    TargetPos : MotionJerkVector;
    TargetVel : MotionJerkVector;
    TargetAcc : MotionJerkVector;
    Limits : MotionJerkLimitSet;
  END_VAR
  VAR_OUTPUT
    Valid : BOOL;
    ErrorId : INT;
    Duration : LREAL;
  END_VAR
  VAR
    Planner : MotionJerkPlanner;
    K : DINT;
  END_VAR
  Planner(Joints := Joints, VelocityMode := VelocityMode, Sync := Sync,
          CurrentPos := CurrentPos, CurrentVel := CurrentVel, CurrentAcc := CurrentAcc,
          TargetPos := TargetPos, TargetVel := TargetVel, TargetAcc := TargetAcc,
          Limits := Limits);
  FOR K := 2 TO Reps DO
    Planner(Joints := Joints);
  END_FOR;
  Valid := Planner.Valid;
  ErrorId := Planner.ErrorId;
  Duration := Planner.Duration;
END_FUNCTION_BLOCK
"""

HARNESS = r"""
#include <stdint.h>
extern "C" {
#include "st_decls.h"
}
#include <ruckig/ruckig.hpp>
#include <dlfcn.h>
#include <time.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>
using namespace ruckig;

static inline double now_s() {
    struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec;
}

struct StLib {
    void (*plan_init)(FB_JERKTIMINGLOOP *);
    int (*plan_run)(FB_JERKTIMINGLOOP *);
    void (*gen_init)(FB_MOTIONJERKGENERATOR *);
    int (*gen_run)(FB_MOTIONJERKGENERATOR *);
    void (*tiny_init)(FN_DEGTORAD *);
    int (*tiny_run)(FN_DEGTORAD *);
    FB_JERKTIMINGLOOP *fb;
};

template <class F> static F sym(void *h, const char *name) {
    void *p = dlsym(h, name);
    if (!p) { std::fprintf(stderr, "no %s\n", name); std::exit(5); }
    return reinterpret_cast<F>(p);
}

struct Case {
    int dofs, sync, vel;
    double p0[6], v0[6], a0[6], pf[6], vf[6], af[6], vmax[6], amax[6], jmax[6], vmin[6], amin[6];
    int sep[6];
};

static bool read_case(FILE *f, Case &c) {
    if (std::fscanf(f, "%d %d %d", &c.dofs, &c.sync, &c.vel) != 3) return false;
    for (int k = 0; k < c.dofs; k++)
        if (std::fscanf(f, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %d", &c.p0[k], &c.v0[k],
                        &c.a0[k], &c.pf[k], &c.vf[k], &c.af[k], &c.vmax[k], &c.amax[k],
                        &c.jmax[k], &c.vmin[k], &c.amin[k], &c.sep[k]) != 12) return false;
    return true;
}

static void st_set(FB_JERKTIMINGLOOP &fb, const Case &c) {
    fb.JOINTS = (int16_t)c.dofs; fb.SYNC = (int16_t)c.sync; fb.VELOCITYMODE = (uint8_t)c.vel;
    for (int k = 0; k < c.dofs; k++) {
        fb.CURRENTPOS.v[k] = c.p0[k]; fb.CURRENTVEL.v[k] = c.v0[k];
        fb.CURRENTACC.v[k] = c.a0[k]; fb.TARGETPOS.v[k] = c.pf[k];
        fb.TARGETVEL.v[k] = c.vf[k]; fb.TARGETACC.v[k] = c.af[k];
        fb.LIMITS.v[k].MAXVEL = c.vmax[k]; fb.LIMITS.v[k].MAXACC = c.amax[k];
        fb.LIMITS.v[k].MAXJERK = c.jmax[k]; fb.LIMITS.v[k].SEPARATEMIN = (uint8_t)c.sep[k];
        fb.LIMITS.v[k].MINVEL = c.vmin[k]; fb.LIMITS.v[k].MINACC = c.amin[k];
    }
}

static void rk_set(InputParameter<DynamicDOFs> &inp, const Case &c) {
    bool separate = false;
    std::vector<double> vmins(c.dofs), amins(c.dofs);
    for (int k = 0; k < c.dofs; k++) {
        inp.current_position[k] = c.p0[k]; inp.current_velocity[k] = c.v0[k];
        inp.current_acceleration[k] = c.a0[k]; inp.target_position[k] = c.pf[k];
        inp.target_velocity[k] = c.vf[k]; inp.target_acceleration[k] = c.af[k];
        inp.max_velocity[k] = c.vmax[k]; inp.max_acceleration[k] = c.amax[k];
        inp.max_jerk[k] = c.jmax[k];
        vmins[k] = c.vmin[k]; amins[k] = c.amin[k]; separate = separate || c.sep[k];
    }
    if (separate) { inp.min_velocity = vmins; inp.min_acceleration = amins; }
    inp.synchronization = c.sync == 0 ? Synchronization::Time : c.sync == 1 ?
        Synchronization::Phase : c.sync == 2 ? Synchronization::None :
        Synchronization::TimeIfNecessary;
    inp.control_interface = c.vel ? ControlInterface::Velocity : ControlInterface::Position;
}

/* MotionJerkGenerator, 6 joints at 10 ms: scans with a new target and scans without */
static void generator(StLib &L, int reps, int idx) {
    static FB_MOTIONJERKGENERATOR gen;
    L.gen_init(&gen);
    gen.ENABLE = 1; gen.CYCLETIME = 0.01; gen.JOINTS = 6; gen.SYNC = 0;
    for (int k = 0; k < 6; k++) {
        gen.LIMITS.v[k].MAXVEL = 90.0 + 10.0 * k; gen.LIMITS.v[k].MAXACC = 400.0 - 30.0 * k;
        gen.LIMITS.v[k].MAXJERK = 4000.0 + 500.0 * k; gen.STARTPOS.v[k] = 5.0 * k;
        gen.TARGETPOS.v[k] = 5.0 * k;
    }
    L.gen_run(&gen);
    int scans = reps * 50;
    std::vector<double> replan(scans), follow(scans);
    for (int s = 0; s < scans; s++) {
        for (int k = 0; k < 6; k++)   /* a target that moves every scan: re-plan each time */
            gen.TARGETPOS.v[k] = 5.0 * k + 40.0 * std::sin(0.013 * s + k);
        double t0 = now_s();
        L.gen_run(&gen);
        replan[s] = now_s() - t0;
        if (!gen.NEWPLAN || gen.ERROR) { std::printf("generator did not re-plan\n"); std::exit(4); }
    }
    for (int s = 0; s < scans; s++) {   /* the same target: evaluation only */
        double t0 = now_s();
        L.gen_run(&gen);
        follow[s] = now_s() - t0;
        if (gen.NEWPLAN) { std::printf("generator re-planned\n"); std::exit(4); }
    }
    std::sort(replan.begin(), replan.end());
    std::sort(follow.begin(), follow.end());
    std::printf("G %d %.9g %.9g\n", idx, replan[scans / 2] * 1e6, follow[scans / 2] * 1e6);
}

int main(int argc, char **argv) {
    FILE *f = std::fopen(argv[1], "r");
    int reps = std::atoi(argv[2]);
    int rounds = std::atoi(argv[3]);
    int nlib = argc - 4;
    std::vector<StLib> libs(nlib);
    for (int i = 0; i < nlib; i++) {
        void *h = dlopen(argv[4 + i], RTLD_NOW | RTLD_LOCAL);
        if (!h) { std::fprintf(stderr, "%s\n", dlerror()); return 5; }
        StLib &L = libs[i];
        L.plan_init = sym<void (*)(FB_JERKTIMINGLOOP *)>(h, "FB_JERKTIMINGLOOP_init");
        L.plan_run = sym<int (*)(FB_JERKTIMINGLOOP *)>(h, "FB_JERKTIMINGLOOP_run");
        L.gen_init = sym<void (*)(FB_MOTIONJERKGENERATOR *)>(h, "FB_MOTIONJERKGENERATOR_init");
        L.gen_run = sym<int (*)(FB_MOTIONJERKGENERATOR *)>(h, "FB_MOTIONJERKGENERATOR_run");
        L.tiny_init = sym<void (*)(FN_DEGTORAD *)>(h, "FN_DEGTORAD_init");
        L.tiny_run = sym<int (*)(FN_DEGTORAD *)>(h, "FN_DEGTORAD_run");
        L.fb = new FB_JERKTIMINGLOOP;
        L.plan_init(L.fb);
    }
    int n;
    if (!f || std::fscanf(f, "%d", &n) != 1) return 3;
    /* what the measuring costs: two clock reads; the ST's entry: a trivial FUNCTION's _run */
    {
        const int k = 200000;
        double t0 = now_s();
        for (int i = 0; i < k; i++) { volatile double x = now_s(); (void)x; }
        double clock_us = (now_s() - t0) / k * 1e6;
        std::printf("K clock %.9g\n", 2.0 * clock_us / reps);
        std::vector<double> entry(nlib, 1e300);
        for (int round = 0; round < 5; round++)
            for (int l = 0; l < nlib; l++) {
                FN_DEGTORAD tiny; libs[l].tiny_init(&tiny); tiny.ANGLEDEG = 1.0f;
                t0 = now_s();
                for (int i = 0; i < k / 5; i++) libs[l].tiny_run(&tiny);
                entry[l] = std::min(entry[l], (now_s() - t0) / (k / 5) * 1e6);
            }
        for (int l = 0; l < nlib; l++) std::printf("K entry%d %.9g\n", l, entry[l]);
    }
    Case c;
    std::vector<double> best(nlib + 1);
    for (int ci = 0; ci < n; ci++) {
        if (!read_case(f, c)) return 3;
        Ruckig<DynamicDOFs> otg(c.dofs);
        InputParameter<DynamicDOFs> inp(c.dofs);
        Trajectory<DynamicDOFs> traj(c.dofs);
        rk_set(inp, c);
        Result res = otg.calculate(inp, traj);
        for (int l = 0; l < nlib; l++) {
            st_set(*libs[l].fb, c);
            libs[l].fb->REPS = 1;
            libs[l].plan_run(libs[l].fb);
            libs[l].fb->REPS = reps;
        }
        /* rounds: each implementation in turn, the fastest round of each counts */
        for (int l = 0; l <= nlib; l++) best[l] = 1e300;
        for (int round = 0; round < rounds; round++) {
            for (int l = 0; l < nlib; l++) {
                double t0 = now_s();
                libs[l].plan_run(libs[l].fb);   /* reps plans */
                double t1 = now_s();
                best[l] = std::min(best[l], (t1 - t0) / reps);
            }
            double t0 = now_s();
            for (int r = 0; r < reps; r++) res = otg.calculate(inp, traj);
            double t1 = now_s();
            best[nlib] = std::min(best[nlib], (t1 - t0) / reps);
        }
        std::printf("C %d", ci);
        for (int l = 0; l < nlib; l++)
            std::printf(" %d %.17g %.9g", libs[l].fb->VALID ? 0 : libs[l].fb->ERRORID,
                        libs[l].fb->DURATION, best[l] * 1e6);
        std::printf(" %d %.17g %.9g\n", (int)res, res == Result::Working ? traj.get_duration()
                    : 0.0, best[nlib] * 1e6);
    }
    if (!std::getenv("JERK_TIMING_PLANS_ONLY"))   /* set: for a profiler, plans only */
        for (int l = 0; l < nlib; l++) generator(libs[l], reps, l);
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
    rng = random.Random(seed + 3)
    three_vel = []
    for k in range(n):
        fam = js.FAMILIES[k % len(js.FAMILIES)]
        three_vel.append((js.multi_case(rng, fam, 3).axes, "Time", "Velocity"))
    return [CaseSet("1 axis, position", one_pos), CaseSet("1 axis, velocity", one_vel),
            CaseSet("6 axes, time sync, position", six),
            CaseSet("3 axes, time sync, velocity", three_vel)]


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


RUCKIG_FLAGS = ["-O2", "-DNDEBUG", "-std=c++20"]


def ruckig_objects(src: Path) -> list[str]:
    """Ruckig's sources compiled once (cached beside them, by flags)."""
    out = src.parent / f"build-{src.name}-{'_'.join(f.strip('-') for f in RUCKIG_FLAGS)}"
    out.mkdir(exist_ok=True)
    objs, procs = [], []
    for cpp in sorted((src / "src" / "ruckig").glob("*.cpp")):
        if "cloud" in cpp.name:
            continue
        obj = out / (cpp.stem + ".o")
        objs.append(str(obj))
        if not obj.exists():
            procs.append(subprocess.Popen(["g++", *RUCKIG_FLAGS, f"-I{src / 'include'}", "-c",
                                           str(cpp), "-o", str(obj)]))
    for p in procs:
        if p.wait() != 0:
            raise SystemExit("g++ failed on Ruckig's sources")
    return objs


BASELINE = """
import sys
from pathlib import Path
from armbench.compiler.build import build
from armbench.compiler.driver import emit_files
_, unit = emit_files([Path(p) for p in sys.argv[1:]])
print(build(unit).path)
"""


def baseline_library(tree: Path, files: list[Path]) -> Path:
    """The library another checkout's armbench builds of ``files`` (only the FB structs the
    harness touches must be laid out alike: the emitted C of FUNCTIONs may differ)."""
    out = subprocess.run([sys.executable, "-c", BASELINE, *map(str, files)],
                         env={**os.environ, "PYTHONPATH": str(tree / "sim")},
                         capture_output=True, text=True, check=True).stdout
    return Path(out.strip().splitlines()[-1])


def parse(out: str, nlib: int) -> tuple[list[list[tuple[int, float, float]]],
                                        dict[str, float], dict[int, tuple[float, float]]]:
    """Per case: (code, duration, µs) of each ST library, then Ruckig's; the "K" figures;
    the generator's figures per library."""
    rows: list[list[tuple[int, float, float]]] = []
    extra: dict[str, float] = {}
    gen: dict[int, tuple[float, float]] = {}
    for line in out.splitlines():
        parts = line.split()
        if parts and parts[0] == "C":
            vals = parts[2:]
            rows.append([(int(vals[3 * i]), float(vals[3 * i + 1]), float(vals[3 * i + 2]))
                         for i in range(nlib + 1)])
        elif parts and parts[0] == "K":
            extra[parts[1]] = float(parts[2])
        elif parts and parts[0] == "G":
            gen[int(parts[1])] = (float(parts[2]), float(parts[3]))
    return rows, extra, gen


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000, help="cases per set")
    ap.add_argument("--reps", type=int, default=100, help="calculations per round")
    ap.add_argument("--rounds", type=int, default=5,
                    help="rounds per case (the implementations take turns; the fastest counts)")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--variant", action="append", default=[], metavar="NAME=FLAGS",
                    help="also time the bench's build with FLAGS added (repeatable)")
    ap.add_argument("--baseline", type=Path, action="append", default=[], metavar="TREE",
                    help="also time the same ST compiled by the armbench of another checkout "
                         "(its sim/: e.g. a worktree of an older commit), repeatable")
    ap.add_argument("--ruckig-src", type=Path, help="an unpacked ruckig source tree")
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="armbench_jerk_timing_"))
    files = sorted((ROOT / "st").glob("*.st"))
    (work / "jerk_timing_loop.st").write_text(TIMING_ST)
    _, unit = emit_files([*files, work / "jerk_timing_loop.st"])
    variants: list[tuple[str, tuple[str, ...]]] = [("ST bench", ())]
    for v in opts.variant:
        name, _, flags = v.partition("=")
        variants.append((f"ST {name}", tuple(shlex.split(flags))))
    libs = []
    names_extra: list[str] = []
    for name, extra_flags in variants:
        t0 = time.perf_counter()
        lib = build(unit, extra_flags=extra_flags)
        how = "cached" if lib.cached else f"built, {lib.units} units, " \
            f"{time.perf_counter() - t0:.1f} s wall"
        print(f"{name}: st/ + the timing FB with {' '.join([*CFLAGS, *extra_flags])} "
              f"({how}): {lib.path}")
        libs.append(lib.path)
    for tree in opts.baseline:
        t0 = time.perf_counter()
        path = baseline_library(tree, [*files, work / "jerk_timing_loop.st"])
        print(f"ST {tree.name}: the same ST by {tree}'s armbench "
              f"({time.perf_counter() - t0:.1f} s wall): {path}")
        names_extra.append(f"ST {tree.name}")
        libs.append(path)
    (work / "st_decls.h").write_text(unit.decls)
    (work / "harness.cpp").write_text(HARNESS)
    src = ruckig_sources(opts.ruckig_src)
    print(f"Ruckig {src.name}: g++ {' '.join(RUCKIG_FLAGS)}; harness in {work}", flush=True)
    objs = ruckig_objects(src)
    subprocess.run(["g++", *RUCKIG_FLAGS, f"-I{src / 'include'}", f"-I{work}",
                    str(work / "harness.cpp"), *objs, "-ldl", "-o", str(work / "bench")],
                   check=True)
    names = [n for n, _ in variants] + names_extra + ["Ruckig C++"]
    ok = True
    print()
    print("| cases | n | implementation | µs mean | median | p99 | mean / Ruckig's | "
          "median of ratios |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    extra: dict[str, float] = {}
    gen: dict[int, tuple[float, float]] = {}
    for i, cs in enumerate(case_sets(opts.cases, opts.seed)):
        path = work / f"cases_{i}.txt"
        write_cases(path, cs.cases)
        out = subprocess.run([str(work / "bench"), str(path), str(opts.reps),
                              str(opts.rounds), *map(str, libs)], capture_output=True, text=True,
                             check=True).stdout
        rows, extra, gen = parse(out, len(libs))
        both = [r for r in rows if all(x[0] == 0 for x in r)]
        for k in range(len(libs)):
            differ = [r for r in both if abs(r[k][1] - r[-1][1]) > 1e-9 * max(r[-1][1], 1e-12)]
            if differ or len(both) < 0.9 * len(rows):
                ok = False
                print(f"FAIL {cs.name}, {names[k]}: {len(differ)} durations differ, "
                      f"{len(both)} of {len(rows)} planned by all")
        for k in range(1, len(libs)):  # the ST builds: bit for bit the same durations
            unequal = sum(r[k][:2] != r[0][:2] for r in rows)
            if unequal:
                ok = False
                print(f"FAIL {cs.name}: {names[k]} and {names[0]} differ in {unequal} of "
                      f"{len(rows)} cases (verdict or duration, bit for bit)")
        rk_t = [r[-1][2] for r in both]
        for k, name in enumerate(names):
            t = [r[k][2] for r in both]
            ratio = statistics.mean(t) / statistics.mean(rk_t)
            per = statistics.median(a / b for a, b in zip(t, rk_t, strict=True))
            q = js.percentile
            print(f"| {cs.name} | {len(both)} | {name} | {statistics.mean(t):.3f} | "
                  f"{q(t, 0.5):.3f} | {q(t, 0.99):.3f} | {ratio:.2f} | {per:.2f} |", flush=True)
    print()
    print(f"measuring: two clock reads per {opts.reps} calculations = "
          f"{extra.get('clock', 0.0) * 1e3:.1f} ns per calculation; the ST's entry "
          "(setjmp, watchdog clock; a trivial FUNCTION's _run): " +
          ", ".join(f"{names[k]} {extra.get(f'entry{k}', 0.0) * 1e3:.1f} ns"
                    for k in range(len(libs))))
    print()
    print("MotionJerkGenerator, 6 joints, 10 ms task:")
    for k, (replan, follow) in sorted(gen.items()):
        print(f"  {names[k]}: scan with a new target (re-plan + evaluate) {replan:.2f} µs = "
              f"{replan / 100.0:.3f} % of 10 ms; on the same target (evaluate) {follow:.2f} µs"
              f" = {follow / 100.0:.4f} %")
    print("\nchecks: " + ("all computed the same durations (the ST builds bit for bit)" if ok
                           else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
