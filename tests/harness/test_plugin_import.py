"""The pytest plugin is loaded into every pytest run of the environment (entry point
``pytest11``), so importing it must cost nothing that a run which never asks for a PLC
fixture would pay: no compiler, no numpy, no pymodbus, no ST file read. And ``pytest
--fixtures`` documents every fixture it provides."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

# Runs in a fresh interpreter: records every .st file opened (audit hook on "open") and the
# modules loaded, after importing the module named on the command line.
_PROBE = r"""
import json
import os
import sys

opened = []


def hook(event, args):
    if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        name = os.fsdecode(args[0])
        if name.lower().endswith(".st"):
            opened.append(name)


sys.addaudithook(hook)
__import__(sys.argv[1])
heavy = sorted(m for m in sys.modules
               if m.split(".")[0] in ("numpy", "pymodbus", "cffi", "tree_sitter", "tqdm")
               or m.startswith(("armbench.compiler", "armbench.softplc",
                                "armbench.controller_client", "armbench.registermap",
                                "armbench.demo", "armbench.locate")))
print(json.dumps({"heavy": heavy, "opened": opened}))
"""

# Modules whose import is the work the plugin must leave until a fixture needs it.
_HEAVY_ROOTS = ("numpy", "pymodbus", "armbench.compiler", "armbench.controller_client")


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    sim = str(Path(__file__).resolve().parents[2] / "sim")
    env["PYTHONPATH"] = os.pathsep.join([sim, env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def _import_report(module: str) -> dict[str, list[str]]:
    proc = subprocess.run([sys.executable, "-c", _PROBE, module], capture_output=True,
                          text=True, timeout=120, env=_env())
    assert proc.returncode == 0, proc.stderr
    report: dict[str, list[str]] = json.loads(proc.stdout.strip().splitlines()[-1])
    return report


def test_the_probe_sees_heavy_imports_and_st_reads() -> None:
    # the detector itself: the controller client parses Controller.st when imported
    report = _import_report("armbench.controller_client")
    assert any(m.startswith(_HEAVY_ROOTS) for m in report["heavy"]), report
    assert any(name.endswith("Controller.st") for name in report["opened"]), report


def test_importing_the_plugin_does_no_heavy_work() -> None:
    report = _import_report("armbench.harness.pytest_plugin")
    assert report == {"heavy": [], "opened": []}


def _fixture_docs(tmp_path: Path) -> dict[str, str]:
    """name -> first docstring line of each fixture ``pytest --fixtures -v`` lists under the
    armbench plugin."""
    (tmp_path / "test_empty.py").write_text("def test_nothing():\n    pass\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "--fixtures", "-v", "-p",
                           "no:cacheprovider", "test_empty.py"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120, env=_env())
    assert proc.returncode == 0, proc.stdout + proc.stderr
    section: list[str] = []
    inside = False
    for line in proc.stdout.splitlines():
        if line.startswith("---") and "fixtures defined from" in line:
            inside = "armbench.harness.pytest_plugin" in line
            continue
        if line.startswith("==="):
            inside = False
        if inside:
            section.append(line)
    docs: dict[str, str] = {}
    name = None
    for line in section:
        head = re.match(r"^(\w+)( \[\w+ scope\])? -- ", line)
        if head:
            name = head.group(1)
            docs[name] = ""
        elif name is not None and line.strip() and not docs[name]:
            docs[name] = line.strip()
    return docs


def test_every_plugin_fixture_has_a_docstring(tmp_path: Path) -> None:
    docs = _fixture_docs(tmp_path)
    undocumented = sorted(n for n, d in docs.items() if d in ("", "no docstring available"))
    assert undocumented == []
    assert {"plc_address", "plc", "motion_recorder", "record_points", "plc_program",
            "program_plc", "modbus", "plc_vars", "soft_plc"} <= set(docs), docs
