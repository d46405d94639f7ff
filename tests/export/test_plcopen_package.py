"""The committed PLCopen XML exports load, strictly, into the class model of the PyPI package
`plcopen` (generated from the TC6 XML schema with xsdata, with CODESYS's additions): an
unknown element or attribute, or a value its type cannot take, is an error, not skipped.
A reading independent of our exporter and of lxml's schema validation (test_export.py).

Each load runs in a fresh interpreter: xsdata resolves types by walking every class the
process has loaded, and a class of `colored` (which blark, tested beside this, imports) raises
its own error, not AttributeError, for an attribute it lacks.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.frontend import check_syntax
from armbench.compiler.lower import lower
from armbench.compiler.parse import parse_text
from armbench.locate import Project

REPO = Path(__file__).resolve().parents[2]
EXPORTS = ["plc_project/plcopen/arm_controller.xml",
           "plc_project/codesys/arm_controller_codesys.xml"]


pytest.importorskip("plcopen", reason="the plcopen package (dev extra) is not installed")

# Loads the XML on stdin strictly and prints what the tests compare, or the error's class.
_LOADER = """
import json, sys
from plcopen import Project
from xsdata.formats.dataclass.context import XmlContext
from xsdata.formats.dataclass.parsers import XmlParser
from xsdata.formats.dataclass.parsers.config import ParserConfig
parser = XmlParser(context=XmlContext(), config=ParserConfig(
    fail_on_unknown_properties=True, fail_on_unknown_attributes=True,
    fail_on_converter_warnings=True))
try:
    project = parser.from_string(sys.stdin.read(), Project)
except Exception as exc:
    print(json.dumps({"error": type(exc).__name__, "message": str(exc)[:300]}))
    raise SystemExit(0)
(config,) = project.instances.configurations.configuration
(resource,) = config.resource
(task,) = resource.task
print(json.dumps({
    "pous": [p.name for p in project.types.pous.pou],
    "types": [t.name for t in project.types.data_types.data_type],
    "task": [config.name, resource.name, task.name, task.interval],
    "instances": [[i.name, i.type_name] for i in task.pou_instance],
}))
"""


def strict_load(xml: str) -> dict[str, Any]:
    """The strict load of ``xml`` in a fresh interpreter: its names, or {"error": class}."""
    run = subprocess.run([sys.executable, "-c", _LOADER], input=xml, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    result: dict[str, Any] = json.loads(run.stdout)
    return result


def source_names() -> tuple[set[str], set[str]]:
    """POU and data type names of the controller as exported: its own sources and what they
    use of the library, read by our parser from the OpenPLC upload (the ST export made from
    the same selection as the XML ones)."""
    upload = REPO / "plc_project" / "openplc" / "arm_controller.st"
    diags = Diagnostics()
    parsed = parse_text(str(upload), upload.read_text(encoding="utf-8"), diags)
    check_syntax(parsed, diags)  # the nesting guard before lowering, as the compiler does
    unit = lower(parsed, diags)
    assert not diags.has_errors, diags.sorted()
    own = {p.name for f in Project(REPO).components() for p in _pous(f)}
    pous = {p.name for p in unit.pous}
    assert own <= pous, f"controller blocks missing from the upload: {sorted(own - pous)}"
    return pous, {t.name for t in unit.types}


def _pous(path: Path) -> list[Any]:
    diags = Diagnostics()
    parsed = parse_text(str(path), path.read_text(encoding="utf-8"), diags)
    check_syntax(parsed, diags)
    return list(lower(parsed, diags).pous)


@pytest.mark.parametrize("rel", EXPORTS)
def test_export_loads_strictly(rel: str) -> None:
    loaded = strict_load((REPO / rel).read_text(encoding="utf-8"))
    assert "error" not in loaded, loaded
    pous, types = source_names()
    assert set(loaded["pous"]) == pous
    assert set(loaded["types"]) == types
    assert loaded["task"] == ["Config0", "Res0", "MainTask", "T#10ms"]
    assert loaded["instances"] == [["ArmCtl", "ArmController"]]


@pytest.mark.parametrize("change", [
    ('pouType="function"', 'pouType="function" colour="red"'),  # unknown attribute
    ("<interface>", "<interface><bogus/>"),                     # unknown element
    ('priority="0"', 'priority="high"'),                        # not an int
], ids=["attribute", "element", "value"])
def test_strict_load_refuses_what_the_schema_does_not_have(change: tuple[str, str]) -> None:
    xml = (REPO / EXPORTS[0]).read_text(encoding="utf-8")
    assert change[0] in xml
    assert strict_load(xml.replace(*change, 1)).get("error") == "ParserError"
