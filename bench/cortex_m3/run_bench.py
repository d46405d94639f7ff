"""Cortex-M3 instruction counts of the three IK methods of seed document 000 (prints a table).

The ST library is compiled to C by armbench's own compiler, linked into a bare-metal image for
QEMU's stm32vldiscovery (STM32F100, Cortex-M3, no FPU, soft-float) and run for the seed's task:
inverse kinematics of a fixed 360-point circle. Executed instructions are counted exactly from
QEMU's `-singlestep -d exec,nochain` trace between two marker calls around every IK call, minus
the same harness with an empty kernel, index by index. The outputs are checked against the same
ST run on the host (armbench.compiler.compile_files). See docs/cortex-m3-bench.md.

Run: .venv/bin/python bench/cortex_m3/run_bench.py [--opt O0 O2] [--methods dh geometric lut]
Exit: 0 ok, 1 a build, run or check failed, 2 the tool chain is missing and cannot be installed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from armbench.compiler import ast as A
from armbench.compiler import compile_files
from armbench.compiler.driver import emit_files
from armbench.compiler.types import ArrayType, ElemType, EnumType, StructType, Type

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
ST = ROOT / "st"
RUNTIME = ROOT / "sim" / "armbench" / "compiler" / "runtime"

N_POINTS = 360
CENTRE_MM = (150.0, 0.0, 120.0)  # horizontal circle, as in the seed's 360-point circle task
RADIUS_MM = 40.0
GEOMETRY = {"A1": 100.0, "A2": 20.0, "A3": 120.0, "A4": 130.0}  # ArmGeometry defaults
TOL = 1.0e-3  # deg (or mm): target soft-float vs host float, same ST code
SEED_RATIO = {"dh": 8.0, "geometric": 2.0, "lut": 1.0}  # doc 000: DH 4x geometric, 2x LUT

CPU = ["-mcpu=cortex-m3", "-mthumb", "-mfloat-abi=soft"]
CFLAGS = CPU + ["-std=gnu11", "-ffunction-sections", "-fdata-sections", "-w",
                "-DARMBENCH_BARE_METAL", "-DARMBENCH_NO_WATCHDOG",
                f"-I{RUNTIME}", f"-I{HERE}"]
LDFLAGS = CPU + ["--specs=nano.specs", "--specs=nosys.specs", "-nostartfiles",
                 f"-T{HERE / 'stm32f100.ld'}", "-Wl,--gc-sections"]
QEMU_ARGS = ["-M", "stm32vldiscovery", "-nographic", "-monitor", "none", "-serial", "none",
             "-semihosting-config", "enable=on,target=native"]
LENGTH_RE = re.compile(r"^([XYZ])(?:MM(\d*))?$")  # X, XMM, XMM100 (0.01 mm)
SYM_RE = re.compile(rb"\] ?([^\]\n]*)\n")
APT_PACKAGES = ["gcc-arm-none-eabi", "libnewlib-arm-none-eabi", "qemu-system-arm"]


# ------------------------------------------------------------------ tool chain

def missing_tools() -> list[str]:
    missing = []
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "arm-none-eabi-nm"):
        if shutil.which(tool) is None:
            missing.append(f"{tool} (package gcc-arm-none-eabi)")
    if shutil.which("arm-none-eabi-gcc") is not None:
        for spec in ("nano.specs", "nosys.specs"):
            out = subprocess.run(["arm-none-eabi-gcc", "-mcpu=cortex-m3", "-mthumb",
                                  f"-print-file-name={spec}"],
                                 capture_output=True, text=True).stdout.strip()
            if not os.path.isabs(out) or not os.path.exists(out):
                missing.append(f"{spec} (package libnewlib-arm-none-eabi)")
    qemu = shutil.which("qemu-system-arm")
    if qemu is None:
        missing.append("qemu-system-arm (package qemu-system-arm)")
    else:
        machines = subprocess.run([qemu, "-machine", "help"], capture_output=True,
                                  text=True).stdout
        if "stm32vldiscovery" not in machines:
            missing.append("qemu-system-arm with machine stm32vldiscovery (QEMU >= 5.2)")
    return missing


def apt_package_for_qemu() -> str:
    """Debian 12 ships qemu-system-arm as its own package; older ones inside qemu-system-misc."""
    for pkg in ("qemu-system-arm", "qemu-system-misc"):
        out = subprocess.run(["apt-cache", "policy", pkg], capture_output=True, text=True).stdout
        m = re.search(r"Candidate:\s*(\S+)", out)
        if m and m.group(1) != "(none)":
            return pkg
    return "qemu-system-arm"


def snapshot_st(build_root: Path, names: list[str]) -> list[Path]:
    """Copies of the named st/ files under build_root/st_snapshot: the ST files may be edited
    while a benchmark runs, so C is emitted and the host reference run from one snapshot."""
    snap = build_root / "st_snapshot"
    snap.mkdir(parents=True, exist_ok=True)
    for name in names:
        (snap / name).write_bytes((ST / name).read_bytes())
    return [snap / name for name in names]


def ensure_tools() -> None:
    missing = missing_tools()
    if not missing:
        return
    print("missing: " + "; ".join(missing))
    if os.geteuid() == 0 and shutil.which("apt-get"):
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        print("installing with apt-get (running as root) ...", flush=True)
        rc = subprocess.run(["apt-get", "update"], env=env).returncode
        if rc == 0:
            pkgs = APT_PACKAGES[:2] + [apt_package_for_qemu()]
            rc = subprocess.run(["apt-get", "install", "-y", *pkgs], env=env).returncode
        missing = missing_tools() if rc == 0 else missing
        if not missing:
            return
    print("cannot run the Cortex-M3 benchmark; still missing: " + "; ".join(missing))
    print("install as root: apt-get update && apt-get install -y " + " ".join(APT_PACKAGES))
    sys.exit(2)


# ------------------------------------------------------------------ methods and inputs

def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def circle() -> list[tuple[float, float, float]]:
    cx, cy, cz = CENTRE_MM
    return [(f32(cx + RADIUS_MM * math.cos(2 * math.pi * k / N_POINTS)),
             f32(cy + RADIUS_MM * math.sin(2 * math.pi * k / N_POINTS)), f32(cz))
            for k in range(N_POINTS)]


@dataclass
class Method:
    key: str  # dh | geometric | lut
    label: str
    files: list[Path]
    pou: str
    note: str = ""
    args: list[dict[str, Any]] = field(default_factory=list)  # ST-named inputs per point


def st_files(*names: str) -> list[Path]:
    return [ST / n for n in names]


def pou_names(path: Path) -> list[str]:
    if not path.exists():
        return []
    text = re.sub(r"\(\*.*?\*\)", " ", path.read_text(encoding="utf-8"), flags=re.S)
    return re.findall(r"^\s*FUNCTION(?:_BLOCK)?\s+(\w+)", text, flags=re.M | re.I)


def find_methods(opts: argparse.Namespace) -> tuple[dict[str, Method], list[str]]:
    """The three methods; the DH and LUT POUs are found by name in st/ (or given by option)."""
    notes: list[str] = []
    angles, kin = ST / "ArmAngles.st", ST / "Kinematics.st"
    tables = ST / "KinematicsFixedTables.st"
    candidates = [ST / "KinematicsDH.st", ST / "KinematicsFixed.st"]

    def files_for(path: Path) -> list[Path]:
        extra = [tables] if tables.exists() and "Fixed" in path.name else []
        return [angles, kin, *extra, path] if path != kin else [angles, kin]

    def locate(name: str | None, pick: Callable[[str], bool]) -> tuple[str, Path] | None:
        for path in [*candidates, kin]:
            for n in pou_names(path):
                if (name and n.upper() == name.upper()) or (not name and pick(n.upper())):
                    return n, path
        return None

    methods = {"geometric": Method("geometric", "geometric (InverseKinematik_V1, REAL)",
                                   [angles, kin], "InverseKinematik_V1")}
    dh = locate(opts.dh_pou, lambda n: n.startswith("INVERSE") and "DH" in n)
    if dh:
        methods["dh"] = Method("dh", f"DH/matrix ({dh[0]}, REAL)", files_for(dh[1]), dh[0])
    else:
        methods["dh"] = Method("dh", "DH stand-in (ForwardKinematic_V1, H10*H21*H32)",
                               [angles, kin], "ForwardKinematic_V1",
                               note="no InverseKinematik_DH found: the homogeneous-transform "
                                    "FK chain ForwardKinematic_V1 is measured as a stand-in")
        notes.append(methods["dh"].note)
    lut = locate(opts.lut_pou, lambda n: n.startswith("INVERSE") and "FIXED" in n
                 and "DH" not in n and "CHECK" not in n)
    if lut:
        methods["lut"] = Method("lut", f"LUT integer ({lut[0]})", files_for(lut[1]), lut[0])
    else:
        notes.append("LUT method not available: no integer IK (InverseKinematik...Fixed) in "
                     "st/KinematicsFixed.st yet; rerun when it appears, or pass --lut-pou NAME")
    return methods, notes


# ------------------------------------------------------------------ C generation

@dataclass
class Leaf:
    path: str  # C access path below the instance, e.g. ".TARGET.X"
    ctype: str
    kind: str  # real | int | bool


def leaves(t: Type, path: str) -> list[Leaf]:
    if isinstance(t, ElemType):
        kind = "real" if t.kind == "real" else ("bool" if t.kind == "bool" else "int")
        return [Leaf(path, t.ctype, kind)]
    if isinstance(t, EnumType):
        return [Leaf(path, "int32_t", "int")]
    if isinstance(t, StructType):
        out: list[Leaf] = []
        for key, (_spelling, ft) in t.fields.items():
            out += leaves(ft, f"{path}.{key}")
        return out
    if isinstance(t, ArrayType):
        out = []
        for k in range(t.size):
            out += leaves(t.element, f"{path}.v[{k}]")
        return out
    raise TypeError(f"unsupported type {t} at {path}")


def py_leaves(t: Type, value: Any) -> list[Any]:
    """The host value of an ST type flattened in the order of leaves()."""
    if isinstance(t, (ElemType, EnumType)):
        return [value]
    if isinstance(t, StructType):
        out: list[Any] = []
        for key, (spelling, ft) in t.fields.items():
            v = value.get(spelling, value.get(key)) if isinstance(value, dict) else None
            out += py_leaves(ft, v)
        return out
    if isinstance(t, ArrayType):
        flat: list[Any] = []

        def walk(v: Any) -> None:
            if isinstance(v, list):
                for x in v:
                    walk(x)
            else:
                flat.append(v)
        walk(value)
        return [x for f in flat for x in py_leaves(t.element, f)]
    raise TypeError(f"unsupported type {t}")


def c_literal(value: Any, leaf: Leaf) -> str:
    if leaf.kind == "real":
        v = float(value)
        return f"{v.hex()}f" if leaf.ctype == "float" else v.hex()
    if leaf.kind == "bool":
        return "1" if value else "0"
    return f"({leaf.ctype})({int(value)}LL)"


def input_assignments(sym: Any, args: list[dict[str, Any]]
                      ) -> tuple[list[tuple[Leaf, list[Any]]], list[tuple[Leaf, Any]]]:
    """Varying leaves (one value per point, a const table) and constant leaves."""
    varying: list[tuple[Leaf, list[Any]]] = []
    constant: list[tuple[Leaf, Any]] = []
    for var in sym.vars.values():
        if var.kind != A.VAR_INPUT or var.name not in args[0]:
            continue
        lv = leaves(var.type, f".{var.key}")
        per_point = [py_leaves(var.type, a[var.name]) for a in args]
        for j, leaf in enumerate(lv):
            vals = [p[j] for p in per_point]
            if any(v is None for v in vals):
                continue
            if all(v == vals[0] for v in vals):
                constant.append((leaf, vals[0]))
            else:
                varying.append((leaf, vals))
    return varying, constant


def harness_c(sym: Any, args: list[dict[str, Any]]) -> str:
    cname = ("FN_" if sym.kind == "FUNCTION" else "FB_") + sym.key
    varying, constant = input_assignments(sym, args)
    outs = output_leaves(sym)
    lines = ['#include "kernel_gen.c"', '#include "semihost.h"', f"#define N {len(args)}",
             "volatile float bench_sink_f;", "volatile int32_t bench_sink_i;",
             f"static {cname} inst;"]
    for j, (leaf, vals) in enumerate(varying):
        body = ",\n  ".join(", ".join(c_literal(v, leaf) for v in vals[k:k + 6])
                            for k in range(0, len(vals), 6))
        lines.append(f"static const {leaf.ctype} IN_{j}[N] = {{\n  {body}\n}};")
    lines += ["static void put_u32(uint32_t u) { bench_puts(\" \"); bench_put_hex(u); }",
              "static uint32_t fbits(float f) { union { float f; uint32_t u; } c; c.f = f; "
              "return c.u; }",
              "int main(void) {",
              "    float fsum = 0.0f;", "    int32_t isum = 0;", "    int faults = 0;",
              "#ifndef BENCH_EMPTY",
              "" if sym.kind == "FUNCTION" else f"    {cname}_init(&inst);",
              "#endif",
              "    for (int32_t i = 0; i < N; i++) {",
              "        bench_mark_begin(i);",
              "#ifdef BENCH_EMPTY"]
    for j, (leaf, _vals) in enumerate(varying):
        sink = "bench_sink_f" if leaf.kind == "real" else "bench_sink_i"
        lines.append(f"        {sink} = IN_{j}[i];")
    # a FUNCTION is initialised at every call (as the emitted callers do); a FUNCTION_BLOCK
    # instance once, before the loop, as a PLC does at start-up
    init = f"        {cname}_init(&inst);"
    lines += ["        bench_mark_end(i);", "#else", init if sym.kind == "FUNCTION" else ""]
    for leaf, val in constant:
        lines.append(f"        inst{leaf.path} = {c_literal(val, leaf)};")
    for j, (leaf, _vals) in enumerate(varying):
        lines.append(f"        inst{leaf.path} = IN_{j}[i];")
    lines += [f"        int rc = {cname}_run(&inst);", "        bench_mark_end(i);",
              "        faults += rc != 0;",
              '        bench_puts("R "); bench_put_dec(i); bench_puts(" "); bench_put_dec(rc);']
    for leaf in outs:
        if leaf.kind == "real" and leaf.ctype == "float":
            lines.append(f"        put_u32(fbits(inst{leaf.path})); fsum += inst{leaf.path};")
        elif leaf.kind == "real":
            raise TypeError("LREAL outputs are not supported by the harness")
        else:
            lines.append(f'        bench_puts(" "); bench_put_dec((int32_t)inst{leaf.path});'
                         f" isum += (int32_t)inst{leaf.path};")
    lines += ['        bench_puts("\\n");', "#endif", "    }",
              "#ifndef BENCH_EMPTY",
              '    bench_puts("CK"); put_u32(fbits(fsum)); bench_puts(" "); '
              'bench_put_dec(isum); bench_puts("\\n");',
              "#endif", "    return faults ? 1 : 0;", "}", ""]
    return "\n".join(lines)


# ------------------------------------------------------------------ build and run

def run(cmd: list[str], cwd: Path) -> str:
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{p.stdout}{p.stderr}")
    return p.stdout


def build(workdir: Path, kernel_c: str, harness: str, opt: str, empty: bool
          ) -> tuple[Path, dict[str, int]]:
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "kernel_gen.c").write_text(kernel_c, encoding="utf-8")
    (workdir / "harness.c").write_text(harness, encoding="utf-8")
    flags = CFLAGS + [f"-{opt}"] + (["-DBENCH_EMPTY"] if empty else [])
    objs = []
    for src in (workdir / "harness.c", HERE / "startup.c", HERE / "semihost.c"):
        obj = workdir / (src.stem + ".o")
        # start-up and markers always at -O2: the same few instructions in every build
        run(["arm-none-eabi-gcc", *(flags if src.parent == workdir else CFLAGS + ["-O2"]),
             "-c", str(src), "-o", str(obj)], workdir)
        objs.append(str(obj))
    elf = workdir / "bench.elf"
    run(["arm-none-eabi-gcc", *LDFLAGS, *objs, "-lm", "-o", str(elf),
         f"-Wl,-Map={workdir / 'bench.map'}"], workdir)
    size = run(["arm-none-eabi-size", "-B", str(elf)], workdir).splitlines()[1].split()
    syms = {}
    for line in run(["arm-none-eabi-nm", str(elf)], workdir).splitlines():
        parts = line.split()
        if len(parts) == 3:
            syms[parts[2]] = int(parts[0], 16) & ~1
    return elf, {"text": int(size[0]), "data": int(size[1]), "bss": int(size[2]),
                 "begin": syms["bench_mark_begin"], "end": syms["bench_mark_end"]}


def count_trace(stream: Any, begin: int, end: int,
                profile: Counter[str] | None = None) -> list[int]:
    """Executed instructions from each entry of bench_mark_begin to the next bench_mark_end.

    With -singlestep every translation block is one guest instruction and with nochain every
    executed block writes one "Trace" line, so lines = instructions. With profile, also counts
    the measured instructions per function symbol (the last field of a trace line)."""

    def seg(block: bytes, a: int, b: int) -> int:
        if profile is not None:
            profile.update(m.decode() for m in SYM_RE.findall(block, a, b))
        return block.count(b"Trace ", a, b)

    pat_b = b"/%08x/" % begin
    pat_e = b"/%08x/" % end
    counts: list[int] = []
    inside = False
    acc = 0
    rest = b""
    while True:
        data = stream.read(1 << 22)
        if not data:
            break
        block = rest + data
        cut = block.rfind(b"\n") + 1
        block, rest = block[:cut], block[cut:]
        pos = 0
        while True:
            hit = block.find(pat_e if inside else pat_b, pos)
            if hit < 0:
                if inside:
                    acc += seg(block, pos, len(block))
                break
            line_start = block.rfind(b"\n", 0, hit) + 1
            if inside:
                counts.append(acc + seg(block, pos, line_start))
                inside = False
            else:
                inside, acc = True, 0
            pos = block.find(b"\n", hit) + 1
            if not inside:
                continue
            acc += 1  # the bench_mark_begin line itself (constant, cancels with the empty run)
    return counts


def run_qemu(elf: Path, info: dict[str, int], timeout: float,
             profile: Counter[str] | None = None) -> tuple[int, str, list[int]]:
    qemu = shutil.which("qemu-system-arm")
    assert qemu is not None
    with tempfile.TemporaryDirectory() as td:
        fifo = Path(td) / "trace.fifo"
        os.mkfifo(fifo)
        out_path = Path(td) / "stdout.txt"
        result: dict[str, Any] = {}

        def reader() -> None:
            with open(fifo, "rb") as f:
                result["counts"] = count_trace(f, info["begin"], info["end"], profile)

        th = threading.Thread(target=reader, daemon=True)
        th.start()
        with open(out_path, "wb") as out:
            proc = subprocess.Popen([qemu, *QEMU_ARGS, "-kernel", str(elf), "-singlestep",
                                     "-d", "exec,nochain", "-D", str(fifo)],
                                    stdout=out, stderr=subprocess.STDOUT)
            try:
                rc = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                rc = -9
        th.join(timeout=60)
        if th.is_alive():  # QEMU never opened the log: unblock the reader
            with open(fifo, "wb"):
                pass
            th.join()
        return rc, out_path.read_text(errors="replace"), result.get("counts", [])


# ------------------------------------------------------------------ host reference

def host_outputs(method: Method) -> tuple[list[list[Any]], Any]:
    mod = compile_files(method.files)
    sym = mod.pou(method.pou, ("FUNCTION", "FUNCTION_BLOCK"))
    rows = []
    for a in method.args:
        if sym.kind == "FUNCTION":
            assert sym.return_type is not None
            rows.append(py_leaves(sym.return_type, mod.call(method.pou, **a)))
        else:
            inst = mod.new_fb(method.pou)
            inst(**a)
            rows.append([x for v in sym.vars.values() if v.kind == A.VAR_OUTPUT
                         for x in py_leaves(v.type, inst.get(v.name))])
    return rows, mod


def output_leaves(sym: Any) -> list[Leaf]:
    """The result of a FUNCTION, or the VAR_OUTPUTs of a FUNCTION_BLOCK, as the harness prints."""
    if sym.kind == "FUNCTION":
        assert sym.return_type is not None
        return leaves(sym.return_type, ".ret_")
    return [lf for v in sym.vars.values() if v.kind == A.VAR_OUTPUT
            for lf in leaves(v.type, f".{v.key}")]


def joint_leaves(outs: list[Leaf]) -> dict[str, tuple[int, float]]:
    """Index and scale to degrees of the Base, Shoulder and Elbow outputs (REAL deg or DINT
    0.01 deg), empty when the POU has no such outputs (the FK stand-in)."""
    found: dict[str, tuple[int, float]] = {}
    for k, lf in enumerate(outs):
        last = lf.path.rsplit(".", 1)[-1]
        for j in ("BASE", "SHOULDER", "ELBOW"):
            if last in (j, j + "DEG", j + "DEG100") and j not in found:
                found[j] = (k, 0.01 if last.endswith("DEG100") else 1.0)
    return found if len(found) == 3 else {}


def parse_outputs(text: str) -> tuple[dict[int, tuple[int, list[str]]], list[str] | None]:
    rows: dict[int, tuple[int, list[str]]] = {}
    ck = None
    for line in text.splitlines():
        parts = line.split()
        if parts[:1] == ["R"]:
            rows[int(parts[1])] = (int(parts[2]), parts[3:])
        elif parts[:1] == ["CK"]:
            ck = parts[1:]
    return rows, ck


def decode(tok: str, kind: str) -> float:
    if kind == "real":
        return struct.unpack("<f", struct.pack("<I", int(tok, 16)))[0]
    return float(int(tok))


def angle_diff(a: float, b: float) -> float:
    d = abs(a - b) % 360.0
    return min(d, 360.0 - d)


# ------------------------------------------------------------------ the benchmark

def method_args(method: Method, sym: Any, points: list[tuple[float, float, float]],
                geo_angles: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """ST-named inputs per point, chosen from the POU's declared inputs."""
    out = []
    for k, (x, y, z) in enumerate(points):
        a: dict[str, Any] = {}
        for var in sym.inputs():
            t, name = var.type, var.name
            tname = getattr(t, "name", "").upper()
            if var.kind != A.VAR_INPUT:
                continue
            if tname == "COORDINATES":
                a[name] = {"X": x, "Y": y, "Z": z}
            elif tname == "ARMGEOMETRY":
                a[name] = dict(GEOMETRY)
            elif tname == "ARMANGLES":
                a[name] = geo_angles[k]
            elif isinstance(t, ElemType) and t.kind == "bool" and "ELBOW" in var.key:
                a[name] = True
            elif tname == "ARMGEOMETRYFIXED":  # 0.01 mm
                a[name] = {f"{k}Mm100": round(v * 100) for k, v in GEOMETRY.items()}
            elif isinstance(t, ElemType) and (m := LENGTH_RE.match(var.key)):
                v = {"X": x, "Y": y, "Z": z}[m.group(1)]
                unit_mm = 1.0 / float(m.group(2)) if m.group(2) else 1.0
                a[name] = v if t.kind == "real" else round(v / unit_mm)
        out.append(a)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--opt", nargs="+", default=["O0", "O2"], help="gcc levels (O0 O2 Os)")
    ap.add_argument("--methods", nargs="+", default=["dh", "geometric", "lut"])
    ap.add_argument("--dh-pou", help="ST name of the DH/matrix IK (default: found by name)")
    ap.add_argument("--lut-pou", help="ST name of the integer IK in st/KinematicsFixed.st")
    ap.add_argument("--build-dir", type=Path, help="keep the builds here (default: temporary)")
    ap.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 2)))
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per QEMU run")
    ap.add_argument("--json", type=Path, help="also write the results here")
    ap.add_argument("--profile", action="store_true",
                    help="also print the measured instructions per function (top 12)")
    opts = ap.parse_args()

    ensure_tools()
    methods, notes = find_methods(opts)
    build_root = opts.build_dir or Path(tempfile.mkdtemp(prefix="armbench_cm3_"))
    # the ST files may be edited while the benchmark runs: emit C and run the host reference
    # from one snapshot of them
    snap = build_root / "st_snapshot"
    snap.mkdir(parents=True, exist_ok=True)
    sources: dict[str, str] = {}
    for m in methods.values():
        copies = []
        for f in m.files:
            data = f.read_bytes()
            (snap / f.name).write_bytes(data)
            sources[f.name] = hashlib.sha256(data).hexdigest()[:16]
            copies.append(snap / f.name)
        m.files = copies
    for n in notes:
        print("note: " + n)
    points = circle()
    base = methods["geometric"]
    base_mod = compile_files(base.files)
    prog_geo = base_mod.program
    geo_angles = [base_mod.call(base.pou, Target={"X": x, "Y": y, "Z": z},
                                Geometry=dict(GEOMETRY)) for x, y, z in points]

    jobs: list[tuple[Method, str, bool, Path, str, str]] = []
    syms: dict[str, Any] = {}
    for key in opts.methods:
        if key not in methods:
            continue
        m = methods[key]
        prog, unit = emit_files(m.files)
        sym = prog.pous[m.pou.upper()]
        syms[key] = sym
        m.args = method_args(m, sym, points, geo_angles)
        harness = harness_c(sym, m.args)
        for opt in opts.opt:
            for empty in (False, True):
                wd = build_root / f"{key}_{opt}{'_empty' if empty else ''}"
                jobs.append((m, opt, empty, wd, unit.code, harness))

    def do(job: tuple[Method, str, bool, Path, str, str]) -> dict[str, Any]:
        m, opt, empty, wd, code, harness = job
        elf, info = build(wd, code, harness, opt, empty)
        prof: Counter[str] | None = Counter() if opts.profile and not empty else None
        rc, text, counts = run_qemu(elf, info, opts.timeout, prof)
        return {"method": m.key, "opt": opt, "empty": empty, "rc": rc, "stdout": text,
                "counts": counts, "profile": prof, **info}

    print(f"building and running {len(jobs)} images in {build_root} ...", flush=True)
    with ThreadPoolExecutor(max_workers=opts.jobs) as pool:
        runs = list(pool.map(do, jobs))
    by = {(r["method"], r["opt"], r["empty"]): r for r in runs}

    ok = True
    results: list[dict[str, Any]] = []
    geo_sym = prog_geo.pous[base.pou.upper()]
    geo_j = joint_leaves(output_leaves(geo_sym))
    geo_joints = [{j: py_leaves(geo_sym.return_type, a)[idx] * sc
                   for j, (idx, sc) in geo_j.items()} for a in geo_angles]
    for key in opts.methods:
        if key not in syms:
            continue
        m = methods[key]
        ref, _ = host_outputs(m)
        sym = syms[key]
        outs = output_leaves(sym)
        kinds = [lf.kind for lf in outs]
        joints = joint_leaves(outs)
        for opt in opts.opt:
            full, empty = by[(key, opt, False)], by[(key, opt, True)]
            problems = []
            for r in (full, empty):
                if r["rc"] != 0:
                    problems.append(f"QEMU exit {r['rc']} ({'empty' if r['empty'] else 'kernel'})"
                                    f": {r['stdout'][-400:]}")
                if len(r["counts"]) != N_POINTS:
                    problems.append(f"{len(r['counts'])} marker pairs, expected {N_POINTS}")
            rows, ck = parse_outputs(full["stdout"])
            max_err = 0.0
            max_dev: dict[str, float] = {}
            host_fsum = 0.0  # the harness's float32 running sum, replayed on host values
            host_isum = 0
            for i in range(N_POINTS):
                if i not in rows:
                    problems.append(f"point {i}: no output")
                    break
                rc, toks = rows[i]
                if rc != 0:
                    problems.append(f"point {i}: PLC fault on the target")
                vals = [decode(t, k) for t, k in zip(toks, kinds, strict=True)]
                for h, kd in zip(ref[i], kinds, strict=True):
                    if kd == "real":
                        host_fsum = f32(host_fsum + f32(float(h)))
                    else:
                        host_isum += int(h)
                for v, h, kd in zip(vals, ref[i], kinds, strict=True):
                    err = angle_diff(v, float(h)) if kd == "real" else abs(v - float(h))
                    max_err = max(max_err, err)
                if joints and geo_joints:
                    for j, (idx, scale) in joints.items():
                        dev = angle_diff(vals[idx] * scale, geo_joints[i][j])
                        max_dev[j] = max(max_dev.get(j, 0.0), dev)
            ck_f = decode(ck[0], "real") if ck else math.nan
            ck_i = int(ck[1]) if ck else None
            if max_err > TOL:
                problems.append(f"outputs differ from the host run by up to {max_err:.3g}")
            # float part: each term agrees to TOL, the float32 sum rounds in the same order
            if not abs(ck_f - host_fsum) <= TOL * N_POINTS + 4 * math.ulp(f32(abs(host_fsum))):
                problems.append(f"float checksum {ck_f!r} vs host {host_fsum!r}")
            if ck_i != host_isum:
                problems.append(f"integer checksum {ck_i} vs host {host_isum}")
            per = [a - b for a, b in zip(full["counts"], empty["counts"], strict=False)]
            total = sum(per)
            res = {"method": key, "label": m.label, "pou": m.pou, "opt": opt,
                   "instructions_total": total, "per_ik": total / N_POINTS,
                   "per_ik_min": min(per) if per else 0, "per_ik_max": max(per) if per else 0,
                   "flash": full["text"] + full["data"],
                   "flash_empty": empty["text"] + empty["data"],
                   "bss": full["bss"], "max_err_vs_host": max_err,
                   "checksum_target": [ck_f, ck_i], "checksum_host": [host_fsum, host_isum],
                   "max_dev_vs_geometric_deg": max_dev, "problems": problems}
            results.append(res)
            if problems:
                ok = False
                for p in problems:
                    print(f"FAIL {key} -{opt}: {p}")

    if opts.profile:
        for r in runs:
            if r["profile"]:
                tot = sum(r["profile"].values())
                top = ", ".join(f"{name or '?'} {n / tot:.0%}"
                                for name, n in r["profile"].most_common(12))
                print(f"profile {r['method']} -{r['opt']} (incl. markers): {top}")
    print_table(results, opts.opt, notes)
    if opts.json:
        opts.json.write_text(json.dumps({"notes": notes, "sources_sha256": sources,
                                          "results": results}, indent=2) + "\n")
    if not opts.build_dir:
        shutil.rmtree(build_root, ignore_errors=True)
    return 0 if ok else 1


def print_table(results: list[dict[str, Any]], opt_levels: list[str], notes: list[str]) -> None:
    by = {(r["method"], r["opt"]): r for r in results}
    print()
    print(f"IK of a {N_POINTS}-point circle (centre {CENTRE_MM} mm, r = {RADIUS_MM} mm), "
          "Cortex-M3 soft-float (QEMU stm32vldiscovery), executed instructions per call")
    hdr = (f"{'method':<48} {'opt':<4} {'instr/IK':>10} {'min..max':>15} {': LUT':>7} "
           f"{': geom':>7} {'seed':>5} {'flash B':>8} {'Δflash B':>9} {'dev°':>7} {'check':>6}")
    print(hdr)
    print("-" * len(hdr))
    for key in ("dh", "geometric", "lut"):
        for opt in opt_levels:
            r = by.get((key, opt))
            if r is None:
                if key == "lut":
                    print(f"{'LUT integer':<48} {'-' + opt:<4} {'not available':>10}")
                continue
            lut = by.get(("lut", opt))
            geo = by.get(("geometric", opt))
            r_lut = f"{r['per_ik'] / lut['per_ik']:.2f}" if lut and lut["per_ik"] else "-"
            r_geo = f"{r['per_ik'] / geo['per_ik']:.2f}" if geo and geo["per_ik"] else "-"
            seed = f"{SEED_RATIO[key]:g}"
            mm = f"{r['per_ik_min']}..{r['per_ik_max']}"
            devs = r["max_dev_vs_geometric_deg"]
            dev = f"{max(devs.values()):.4f}" if devs else "-"
            print(f"{r['label']:<48} {'-' + opt:<4} {r['per_ik']:>10.1f} {mm:>15} {r_lut:>7} "
                  f"{r_geo:>7} {seed:>5} {r['flash']:>8} {r['flash'] - r['flash_empty']:>9} "
                  f"{dev:>7} "
                  f"{'ok' if not r['problems'] else 'FAIL':>6}")
    print("seed = doc 000's ratio DH : geometric : LUT = 8 : 2 : 1 (STM32F103 at -O0, cycles);"
          " ': LUT' / ': geom' = measured ratio at the same -O level.")
    print("flash B = text+data of the whole image; Δflash B = minus the empty-kernel image; "
          "dev° = largest |Base/Shoulder/Elbow - geometric| over the circle.")
    for n in notes:
        print("note: " + n)


if __name__ == "__main__":
    sys.exit(main())
