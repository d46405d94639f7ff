"""Real programs written by others, run through the bench and (optionally) the real OpenPLC v3.

    corpus.py build [--out DIR]            rebuild the units from the pinned sources (sources.json)
    corpus.py run   [--out DIR] [--only S] [--jobs N] [--no-build] [--json FILE]

`build` reads every source of sources.json at its pinned commit from git -- from a mirror
(CORPUS_MIRRORS, default /work/.mirror, laid out <owner>+<name>/repo as the search tool's
`fetch` leaves it) or from a clone it makes under CORPUS_CACHE (default
~/.cache/armbench-corpus) -- and writes one `.st` file per compilation unit into DIR (default
CORPUS_CACHE/units). Nothing of the sources is committed: OSCAT is LGPL, MatIEC and OpenPLC GPL.

A unit is what a user uploads to OpenPLC: one .st file with every POU and type it uses and a
CONFIGURATION. How each kind of source becomes units:
  stlib_closure  a library of one POU per file: one unit per POU, holding the POU, the POUs and
                 types it names (transitively, by identifier), and, when none of them is a
                 PROGRAM, a small program and a CONFIGURATION (an OSCAT POU needs the POUs it
                 uses, and OpenPLC needs a program to build)
  st_pair        library file + test program, per test program
  st_file        the file as it is
  plcopen_xml    the ST the OpenPLC editor's generator (xml2st, env XML2ST + XML2ST_PYTHON) makes
                 of the project; a project it cannot convert is reported as skipped
Units without a CONFIGURATION get the one OpenPLC's editor writes (Config0/Res0, one task).

`run` prints, per unit: the real OpenPLC v3 verdict (when MATIEC_CHECK points at check-st.sh:
iec2c + OpenPLC's C build; verdicts are cached by unit text in CORPUS_CACHE/real-verdicts.json),
the bench's `check --target openplc` verdict, its `build` verdict (C emitted and compiled), and
the bench's first error; then one summary line: units, OpenPLC accepts, bench refuses of those,
bench accepts that OpenPLC refuses, crashes, time. Run it with the repository's sim/ on
PYTHONPATH.
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures
import hashlib
import json
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCES = HERE / "sources.json"

CONFIG = """
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : {program};
  END_RESOURCE
END_CONFIGURATION
"""

STUB_PROGRAM = """
PROGRAM corpus_main
VAR
  corpus_scans : DINT;
END_VAR
  corpus_scans := corpus_scans + 1;
END_PROGRAM
"""


def cache_root() -> Path:
    return Path(os.environ.get("CORPUS_CACHE", Path.home() / ".cache" / "armbench-corpus"))


# ------------------------------------------------------------------ git access
def gitdir(repo: str, commit: str) -> Path:
    """A git directory holding ``commit`` of github ``repo``: a mirror, else a clone made here."""
    mirrors = Path(os.environ.get("CORPUS_MIRRORS", "/work/.mirror"))
    cand = mirrors / repo.replace("/", "+") / "repo"
    if cand.is_dir() and _has(cand, commit):
        return cand
    clone = cache_root() / "repos" / repo.replace("/", "+")
    if not clone.is_dir():
        clone.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "clone", "--bare", "--filter=blob:none",
                        f"https://github.com/{repo}.git", str(clone)], check=True)
    if not _has(clone, commit):
        subprocess.run(["git", "-C", str(clone), "fetch", "origin", commit], check=True)
    return clone


def _has(gd: Path, commit: str) -> bool:
    return subprocess.run(["git", "-C", str(gd), "cat-file", "-e", f"{commit}^{{commit}}"],
                          capture_output=True).returncode == 0


def show(gd: Path, commit: str, path: str) -> bytes:
    return subprocess.run(["git", "-C", str(gd), "show", f"{commit}:{path}"],
                          capture_output=True, check=True).stdout


def ls(gd: Path, commit: str, under: str) -> list[str]:
    out = subprocess.run(["git", "-C", str(gd), "ls-tree", "-r", "--name-only", commit, "--",
                          under], capture_output=True, check=True, text=True).stdout
    return out.split()


# ------------------------------------------------------------------ units
_COMMENT = re.compile(r"\(\*.*?\*\)|//[^\n]*|/\*.*?\*/", re.S)
_IDENT = re.compile(r"[A-Za-z_]\w*")
_POU = re.compile(r"^\s*(PROGRAM|FUNCTION_BLOCK|FUNCTION|TYPE|VAR_GLOBAL)\b", re.I | re.M)


def _words(text: str) -> set[str]:
    return {w.upper() for w in _IDENT.findall(_COMMENT.sub(" ", text))}


def _decoded(data: bytes) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("cp1252")


def with_config(text: str) -> str:
    """``text`` as an upload: with a CONFIGURATION running its (first) PROGRAM, or a stub one."""
    bare = _COMMENT.sub(" ", text)
    if re.search(r"\bCONFIGURATION\b", bare, re.I):
        return text
    m = re.search(r"\bPROGRAM\s+(\w+)", bare, re.I)
    if m is None:
        return text + STUB_PROGRAM + CONFIG.format(program="corpus_main")
    return text + CONFIG.format(program=m.group(1))


def stlib_units(data: bytes) -> dict[str, str]:
    lib = json.loads(data)
    entries: dict[str, str] = {}
    globals_: list[str] = []
    for s in lib["sources"]:
        kind = _POU.search(_COMMENT.sub(" ", s["source"]))
        if kind and kind.group(1).upper() == "VAR_GLOBAL":
            globals_.append(s["source"])
            continue
        entries[s["fileName"].split(".")[0].upper()] = s["source"]
    uses = {n: (_words(t) & entries.keys()) - {n} for n, t in entries.items()}
    gnames = {g: _words(g) for g in globals_}
    units = {}
    for name in sorted(entries):
        seen: list[str] = []
        todo = [name]
        while todo:
            n = todo.pop()
            if n in seen:
                continue
            seen.append(n)
            todo.extend(sorted(uses[n]))
        types = [n for n in seen if entries[n].lstrip().upper().startswith("TYPE")]
        pous = [n for n in reversed(seen) if n not in types]
        text = "\n".join(entries[n] for n in [*sorted(types), *pous])
        used = _words(text)
        glob = [g for g in globals_ if any(
            re.search(rf"\b{w}\b\s*:", g, re.I) and w in used for w in gnames[g])]
        if glob:  # globals of the library: OpenPLC takes them in the CONFIGURATION only
            body = "\n".join(g.strip() for g in glob)
            text += STUB_PROGRAM + CONFIG.format(program="corpus_main").replace(
                "  RESOURCE", body + "\n  RESOURCE", 1)
        units[name.lower()] = with_config(text)
    return units


def built_file(src: dict[str, str]) -> bytes:
    """A file STruC++'s build makes of its sources (the OSCAT .stlib is made from the CODESYS
    .library in libs/sources at build time): read from the checkout STRUCPP_ROOT (default
    /opt/strucpp/src), which must be at the pinned commit."""
    root = Path(os.environ.get("STRUCPP_ROOT", "/opt/strucpp/src"))
    head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                          text=True).stdout.strip()
    if head != src["commit"]:
        raise SystemExit(f"{root} is at {head or 'no commit'}, not {src['commit']}: build "
                         f"STruC++ at the pinned commit and point STRUCPP_ROOT at it")
    return (root / src["path"]).read_bytes()


def xml_to_st(xml: bytes, work: Path) -> str | None:
    """The ST xml2st (the OpenPLC editor's generator) makes of a PLCopen project, or None."""
    x2s = os.environ.get("XML2ST", "")
    if not x2s:
        raise SystemExit("plcopen_xml sources need XML2ST (and XML2ST_PYTHON), see docs")
    py = os.environ.get("XML2ST_PYTHON", sys.executable)
    work.mkdir(parents=True, exist_ok=True)
    f = work / "plc.xml"
    f.write_bytes(xml)
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import xml2st\n"
              "t = xml2st.compile_xml_to_st(sys.argv[2])\n"
              "sys.stdout.write(t if t else '')\n")
    p = subprocess.run([py, "-c", script, x2s, str(f)], capture_output=True, text=True,
                       timeout=120)
    if p.returncode != 0 or "PROGRAM" not in p.stdout.upper():
        return None
    # the generator prints progress on stdout before the ST
    st = p.stdout
    start = re.search(r"^(TYPE|FUNCTION|PROGRAM|CONFIGURATION)\b", st, re.M)
    return st[start.start():] if start else None


def build_units(out: Path) -> tuple[dict[str, str], list[str]]:
    spec = json.loads(SOURCES.read_text())
    units: dict[str, str] = {}
    skipped: list[str] = []
    for src in spec["sources"]:
        gd = gitdir(src["repo"], src["commit"])
        c = src["commit"]
        pre = src["name"]
        kind = src["kind"]
        if kind == "stlib_closure":
            for n, t in stlib_units(built_file(src)).items():
                units[f"{pre}/{n}"] = t
        elif kind == "st_pair":
            files = ls(gd, c, src["dir"])
            progs = [f for f in files if re.fullmatch(
                src["program_glob"].replace("*", ".*"), Path(f).name)]
            for p in progs:
                libname = Path(p).name.removeprefix("test_")
                lib = [f for f in files if Path(f).name == libname]
                text = "\n".join(_decoded(show(gd, c, f)) for f in [*lib, p])
                units[f"{pre}/{Path(p).stem}"] = with_config(text)
        elif kind == "st_file":
            for p in src["paths"]:
                units[f"{pre}/{Path(p).stem}"] = with_config(_decoded(show(gd, c, p)))
        elif kind == "plcopen_xml":
            paths = list(src.get("paths", []))
            for under in src.get("under", []):
                paths += [f for f in ls(gd, c, under) if f.endswith("/plc.xml")]
            for p in paths:
                name = f"{pre}/{Path(p).parent.name if p.endswith('plc.xml') else Path(p).stem}"
                st = xml_to_st(show(gd, c, p), cache_root() / "xml2st")
                if st is None:
                    skipped.append(f"{name}: xml2st cannot generate ST for it")
                    continue
                units[name] = with_config(st)
        else:
            raise SystemExit(f"sources.json: unknown kind {kind!r}")
    out.mkdir(parents=True, exist_ok=True)
    for old in out.rglob("*.st"):
        old.unlink()
    for n, t in units.items():
        f = out / f"{n}.st"
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(t, encoding="utf-8")
    (out / "skipped.txt").write_text("".join(s + "\n" for s in skipped))
    return units, skipped


# ------------------------------------------------------------------ verdicts
@dataclass
class Verdict:
    unit: str
    real: bool | None  # None: MATIEC_CHECK unset
    check: bool
    build: bool | None  # None: not tried (check failed, or --no-build)
    first: str  # the bench's first error (or crash), "" when it accepts
    crash: bool


def real_verdicts(files: list[Path], jobs: int) -> dict[Path, bool | None]:
    tool = os.environ.get("MATIEC_CHECK", "")
    if not tool:
        return {f: None for f in files}
    store = cache_root() / "real-verdicts.json"
    cache: dict[str, bool] = json.loads(store.read_text()) if store.is_file() else {}

    def key(f: Path) -> str:
        return hashlib.sha256(f.read_bytes()).hexdigest()

    todo = [f for f in files if key(f) not in cache]

    def one(f: Path) -> tuple[Path, bool]:
        p = subprocess.run([tool, str(f)], capture_output=True, timeout=300)
        return f, p.returncode == 0

    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as ex:
        for i, (f, ok) in enumerate(ex.map(one, todo)):
            cache[key(f)] = ok
            if i % 20 == 19:
                store.write_text(json.dumps(cache, indent=0, sort_keys=True))
    store.parent.mkdir(parents=True, exist_ok=True)
    store.write_text(json.dumps(cache, indent=0, sort_keys=True))
    return {f: cache[key(f)] for f in files}


def bench_verdict(f: Path, name: str, real: bool | None, do_build: bool) -> Verdict:
    from armbench.compiler import check_files
    from armbench.compiler.build import build
    from armbench.compiler.driver import emit_files
    from armbench.compiler.targets import OPENPLC_ONLY

    try:
        errs = [d for d in check_files([f], target=OPENPLC_ONLY) if d.severity == "error"]
    except Exception as e:  # a crash of the bench is a finding, not the end of the run
        return Verdict(name, real, False, None, f"crash in check: {e!r}"[:200], True)
    if errs:
        return Verdict(name, real, False, None, errs[0].render().split(": ", 1)[1], False)
    if not do_build:
        return Verdict(name, real, True, None, "", False)
    try:
        _, unit = emit_files([f])
        build(unit)
    except Exception as e:
        msg = str(e).strip().splitlines()
        first = msg[0] if msg else repr(e)
        crash = type(e).__name__ not in ("CompileFailed", "BuildFailed", "CalledProcessError")
        return Verdict(name, real, True, False, f"build: {first}"[:200], crash)
    return Verdict(name, real, True, True, "", False)


def _mark(v: bool | None) -> str:
    return "-" if v is None else "ok" if v else "NO"


def run(out: Path, only: str, jobs: int, do_build: bool, json_out: Path | None) -> int:
    t0 = time.perf_counter()
    files = sorted(out.rglob("*.st"))
    files = [f for f in files if only in str(f.relative_to(out))]
    if not files:
        raise SystemExit(f"no units under {out}: run `corpus.py build` first")
    real = real_verdicts(files, jobs)
    rows: list[Verdict] = []
    print(f"{'unit':48} {'openplc':7} {'check':5} {'build':5}  first bench error")
    for f in files:
        name = str(f.relative_to(out).with_suffix(""))
        v = bench_verdict(f, name, real[f], do_build)
        rows.append(v)
        print(f"{name:48} {_mark(v.real):7} {_mark(v.check):5} {_mark(v.build):5}  {v.first}",
              flush=True)
    accepts = [v for v in rows if v.real]
    bench_ok = [v for v in rows if v.check and v.build is not False]
    refuses = [v for v in accepts if v not in bench_ok]
    false_acc = [v for v in rows if v.real is False and v.check]
    crashes = [v for v in rows if v.crash]
    groups = collections.Counter(re.sub(r"'[^']*'", "'…'", v.first)[:90] for v in refuses)
    if refuses:
        print("\nbench refusals of units OpenPLC builds, by first error:")
        for msg, n in groups.most_common():
            print(f"  {n:4}  {msg}")
    dt = time.perf_counter() - t0
    print(f"\nunits {len(rows)}, OpenPLC accepts {len(accepts) if real else 'n/a'}, "
          f"bench refuses {len(refuses)} of those, bench accepts {len(false_acc)} that "
          f"OpenPLC refuses, crashes {len(crashes)}, time {dt:.0f} s")
    if json_out:
        json_out.write_text(json.dumps([v.__dict__ for v in rows], indent=1))
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cmd", choices=["build", "run"])
    ap.add_argument("--out", type=Path, default=None, help="units directory")
    ap.add_argument("--only", default="", help="units whose name contains this")
    ap.add_argument("--jobs", type=int, default=1, help="parallel real-OpenPLC checks")
    ap.add_argument("--no-build", action="store_true", help="bench check only, no C build")
    ap.add_argument("--json", type=Path, default=None, help="write the rows as JSON")
    a = ap.parse_args()
    out = a.out or cache_root() / "units"
    if a.cmd == "build":
        units, skipped = build_units(out)
        print(f"{len(units)} units in {out}; {len(skipped)} sources skipped")
        for s in skipped:
            print(f"  skipped {s}")
        return 0
    return run(out, a.only, a.jobs, not a.no_build, a.json)


if __name__ == "__main__":
    sys.exit(main())
