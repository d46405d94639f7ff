"""What the armbench pytest plugin costs a pytest run that never uses it.

The plugin is registered for every pytest run in the environment (entry point ``pytest11``),
so its import is paid by unrelated suites too. Prints, best and median of ``--runs`` fresh
interpreters:

- the plugin's own import time, measured after ``import pytest`` (pytest is loaded anyway);
- the plugin's cumulative import time as ``python -X importtime`` reports it (pytest
  included, when nothing imported it before), and ``import pytest`` alone;
- the wall time of ``pytest`` on one empty test in a temporary folder, with the plugin and
  with ``-p no:armbench``.

``--sim DIR`` measures another checkout's package (e.g. an older commit's ``sim/``).

    .venv/bin/python bench/plugin_import.py [--runs 5] [--sim sim]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_OWN = ("import time, pytest\n"
        "t = time.perf_counter()\n"
        "import armbench.harness.pytest_plugin\n"
        "print(time.perf_counter() - t)\n")


def _env(sim: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    env["PYTHONPATH"] = str(sim.resolve())
    return env


def pytest_import_s(sim: Path) -> float:
    out = subprocess.run([sys.executable, "-c", "import time\nt = time.perf_counter()\n"
                          "import pytest\nprint(time.perf_counter() - t)\n"], env=_env(sim),
                         check=True, capture_output=True, text=True).stdout
    return float(out.strip())


def own_import_s(sim: Path) -> float:
    out = subprocess.run([sys.executable, "-c", _OWN], env=_env(sim), check=True,
                         capture_output=True, text=True).stdout
    return float(out.strip())


def importtime_s(sim: Path) -> float:
    err = subprocess.run([sys.executable, "-X", "importtime", "-c",
                          "import armbench.harness.pytest_plugin"], env=_env(sim), check=True,
                         capture_output=True, text=True).stderr
    line = next(ln for ln in reversed(err.splitlines())
                if ln.rstrip().endswith("| armbench.harness.pytest_plugin"))
    m = re.match(r"import time:\s+\d+\s+\|\s+(\d+)\s+\|", line)
    assert m is not None, line
    return int(m.group(1)) / 1e6


def pytest_run_s(sim: Path, folder: Path, *extra: str) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                    "test_empty.py", *extra], cwd=folder, env=_env(sim), check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def _line(what: str, samples: list[float]) -> str:
    return (f"{what:<52} best {min(samples):7.3f} s   median "
            f"{statistics.median(samples):7.3f} s")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--sim", type=Path, default=Path(__file__).resolve().parents[1] / "sim",
                   help="the folder holding the armbench package (default: this checkout's)")
    args = p.parse_args(argv)
    sim: Path = args.sim
    print(f"armbench from {sim.resolve()}, {args.runs} runs each")
    print(_line("plugin import after `import pytest`", [own_import_s(sim)
                                                         for _ in range(args.runs)]))
    print(_line("plugin import, -X importtime cumulative", [importtime_s(sim)
                                                             for _ in range(args.runs)]))
    print(_line("  of which `import pytest` alone", [pytest_import_s(sim)
                                                      for _ in range(args.runs)]))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "test_empty.py").write_text("def test_nothing():\n    pass\n")
        with_plugin: list[float] = []
        without: list[float] = []
        for _ in range(args.runs):  # interleaved: a busy machine slows both alike
            with_plugin.append(pytest_run_s(sim, folder))
            without.append(pytest_run_s(sim, folder, "-p", "no:armbench"))
    print(_line("pytest, one empty test, with the plugin", with_plugin))
    print(_line("pytest, one empty test, -p no:armbench", without))
    return 0


if __name__ == "__main__":
    sys.exit(main())
