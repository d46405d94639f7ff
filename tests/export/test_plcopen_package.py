"""The committed PLCopen XML exports load, strictly, into the class model of the PyPI package
`plcopen` (generated from the TC6 XML schema with xsdata, with CODESYS's additions): an
unknown element or attribute, or a value its type cannot take, is an error, not skipped.
A reading independent of our exporter and of lxml's schema validation (test_export.py).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from plcopen import Project as PlcopenProject
from xsdata.exceptions import ParserError
from xsdata.formats.dataclass.context import XmlContext
from xsdata.formats.dataclass.parsers import XmlParser
from xsdata.formats.dataclass.parsers.config import ParserConfig

from armbench.compiler.diagnostics import Diagnostics
from armbench.compiler.frontend import check_syntax
from armbench.compiler.lower import lower
from armbench.compiler.parse import parse_text
from armbench.locate import Project

REPO = Path(__file__).resolve().parents[2]
EXPORTS = ["plc_project/plcopen/arm_controller.xml",
           "plc_project/codesys/arm_controller_codesys.xml"]


def strict_parser() -> XmlParser:
    return XmlParser(context=XmlContext(), config=ParserConfig(
        fail_on_unknown_properties=True, fail_on_unknown_attributes=True,
        fail_on_converter_warnings=True))


def source_names() -> tuple[set[str], set[str]]:
    """POU and data type names of the sources, from our parser."""
    pous: set[str] = set()
    types: set[str] = set()
    for f in Project(REPO).sources():
        diags = Diagnostics()
        parsed = parse_text(str(f), f.read_text(encoding="utf-8"), diags)
        check_syntax(parsed, diags)  # the nesting guard lower() requires
        unit = lower(parsed, diags)
        assert not diags.has_errors, diags.sorted()
        pous |= {p.name for p in unit.pous}
        types |= {t.name for t in unit.types}
    return pous, types


@pytest.mark.parametrize("rel", EXPORTS)
def test_export_loads_strictly(rel: str) -> None:
    project = strict_parser().from_bytes((REPO / rel).read_bytes(), PlcopenProject)
    assert project.types is not None and project.instances is not None
    assert project.types.pous is not None and project.types.data_types is not None
    pous, types = source_names()
    assert {p.name for p in project.types.pous.pou} == pous
    assert {t.name for t in project.types.data_types.data_type} == types
    assert project.instances.configurations is not None
    (config,) = project.instances.configurations.configuration
    (resource,) = config.resource
    (task,) = resource.task
    assert (config.name, resource.name, task.name, task.interval) == \
        ("Config0", "Res0", "MainTask", "T#10ms")
    assert [(i.name, i.type_name) for i in task.pou_instance] == [("ArmCtl", "ArmController")]


@pytest.mark.parametrize("change", [
    ('pouType="function"', 'pouType="function" colour="red"'),  # unknown attribute
    ("<interface>", "<interface><bogus/>"),                     # unknown element
    ('priority="0"', 'priority="high"'),                        # not an int
], ids=["attribute", "element", "value"])
def test_strict_load_refuses_what_the_schema_does_not_have(change: tuple[str, str]) -> None:
    xml = (REPO / EXPORTS[0]).read_text(encoding="utf-8")
    assert change[0] in xml
    with pytest.raises(ParserError):
        strict_parser().from_string(xml.replace(*change, 1), PlcopenProject)
