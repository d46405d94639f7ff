"""`armbench export`: the OpenPLC v4 editor project folder (openplc-v4/NAME/).

Without outside tools: the committed folder equals a fresh export (no file missing, none
left over), and what v4 cannot represent costs the v4 folder only, with a warning.

With the v4 editor's own code (``OPENPLC_EDITOR``: a checkout of Autonomy-Logic/openplc-editor,
esbuild, zod and xmlbuilder2 installed beside it; docs/exports.md): project.json passes the
editor's zod schema, and the editor's loader opens the folder with every POU parsed in full
(none falling back to raw text), each POU, variable, data type, task and instance as the
sources declare them. With xml2st as well (``XML2ST``, the editor's ST generator, and
``XML2ST_PYTHON``) and STruC++ (``STRUCPP``, tests/strucpp_tool.py): the ST the editor's build
makes of the loaded project (its XML generator, then xml2st) compiles with STruC++ and the C++
with g++, as OpenPLC v4 builds it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from armbench.cli import main
from armbench.compiler import ast as A
from armbench.compiler import check_files
from armbench.export import generate
from armbench.export.openplc_v4 import CLASSES, POU_FOLDERS, _init_text, project_dir
from armbench.export.sttext import expr_text
from armbench.registermap import controller_map
from strucpp_tool import SKIP_REASON, find_strucpp

REPO = Path(__file__).resolve().parents[2]
OUT_DIR = REPO / "plc_project"
V4_PROJECT = OUT_DIR / project_dir("arm_controller")
EDITOR_SCRIPT = Path(__file__).with_name("openplc_v4_editor.mjs")

EDITOR_SKIP = ("OPENPLC_EDITOR not set: point it at a checkout of Autonomy-Logic/openplc-editor "
               "with esbuild, zod@3 and xmlbuilder2@3 installed in the folder above it "
               "(docs/exports.md says how)")
XML2ST_SKIP = ("XML2ST not set: point it at a checkout of Autonomy-Logic/xml2st, and "
               "XML2ST_PYTHON at a Python with lxml, jinja2 and pyserial (docs/exports.md)")

BLINK = """\
PROGRAM Blink
  VAR
    Lamp AT %QX0.0 : BOOL;  (* the lamp *)
    Phase AT %MD0 : REAL := 0.5;
  END_VAR
  VAR
    Angle : REAL;
  END_VAR
  Angle := DegToRad(Phase);
  Lamp := Angle > 0.0;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK Fast(INTERVAL := T#20ms, PRIORITY := 1);
    PROGRAM Blinker WITH Fast : Blink;
  END_RESOURCE
END_CONFIGURATION
"""


def v4_files(exp_files: dict[Path, bytes], name: str) -> dict[Path, bytes]:
    root = project_dir(name)
    return {p: d for p, d in exp_files.items() if root in p.parents}


# ---------------------------------------------------------------- without outside tools
def test_committed_v4_project_is_current() -> None:
    exp = generate()
    want = v4_files(exp.files, "arm_controller")
    assert want, "the arm controller has no v4 project: " + "; ".join(exp.warnings)
    for rel, data in want.items():
        path = OUT_DIR / rel
        assert path.is_file(), f"{path} missing: run `armbench export --regenerate`"
        assert path.read_bytes() == data, f"{path} is stale: run `armbench export --regenerate`"
    extra = exp.extra(OUT_DIR)
    assert not extra, f"{extra} not in the export: run `armbench export --regenerate`"


def test_every_pou_has_its_file_and_the_configuration_is_in_project_json() -> None:
    exp = generate()
    pous = [p for s in exp.sources for p in s.unit.pous]
    files = {p.relative_to(project_dir("arm_controller")).as_posix()
             for p in v4_files(exp.files, "arm_controller")}
    assert files == {"project.json"} | {
        f"pous/{POU_FOLDERS[p.kind.upper()]}/{p.name}.st" for p in pous}
    project = json.loads((V4_PROJECT / "project.json").read_text("utf-8"))
    assert project["meta"] == {"name": "arm_controller", "type": "plc-project"}
    assert project["data"]["configuration"]["resource"] == {
        "tasks": [{"name": "MainTask", "triggering": "Cyclic", "interval": "T#10ms",
                   "priority": 0}],
        "instances": [{"name": "ArmCtl", "task": "MainTask", "program": "ArmController"}],
        "globalVariables": []}
    names = [t["name"] for t in project["data"]["dataTypes"]]
    declared = [t.name for s in exp.sources for t in s.unit.types]
    # no inline array needs a generated type (E0511 keeps 2-D arrays out of blocks' state;
    # test_inline_arrays_the_editor_cannot_read_get_a_named_type covers those types)
    assert names == declared
    text = (V4_PROJECT / "pous/function-blocks/MotionLinear.st").read_text("utf-8")
    assert ("\tSampleTab : ARRAY[0..64] OF MotionLineSample; (* deg, joints 1..3 at the "
            "samples *)") in text
    program = (V4_PROJECT / "pous/programs/ArmController.st").read_text("utf-8")
    assert "\tScanCount : UDINT AT %MD0;" in program


def test_check_finds_a_left_over_pou_file_and_write_removes_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    work = tmp_path / "work"
    work.mkdir()
    (work / "Blink.st").write_text(BLINK)
    out = tmp_path / "out"
    assert main(["export", str(work / "Blink.st"), "--out", str(out)]) == 0
    root = out / project_dir("Blink")
    assert sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()) == \
        ["pous/functions/DegToRad.st", "pous/programs/Blink.st", "project.json"]
    left_over = root / "pous" / "functions" / "Removed.st"
    left_over.write_text("FUNCTION Removed : BOOL\nEND_FUNCTION\n")
    capsys.readouterr()
    assert main(["export", str(work / "Blink.st"), "--out", str(out), "--check"]) == 1
    assert "Removed.st (not in the export)" in capsys.readouterr().out
    assert main(["export", str(work / "Blink.st"), "--out", str(out)]) == 0
    assert not left_over.exists()
    assert main(["export", str(work / "Blink.st"), "--out", str(out), "--check"]) == 0


def test_what_v4_cannot_represent_costs_only_the_v4_project(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "Ranged.st"
    src.write_text("TYPE\n  Percent : INT (0..100);\nEND_TYPE\n\n"
                   + BLINK.replace("Angle : REAL;", "Angle : REAL;\n    Level : Percent;"))
    out = tmp_path / "out"
    assert main(["export", str(src), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "no OpenPLC v4 project (openplc-v4/Blink/)" in err
    assert "Ranged.st:2: type Percent is a subrange" in err
    assert (out / "openplc" / "Blink.st").is_file() and not (out / "openplc-v4").exists()


def test_v4_program_file_is_laid_out_as_the_editor_saves_it(tmp_path: Path) -> None:
    (tmp_path / "Blink.st").write_text(BLINK)
    assert main(["export", str(tmp_path / "Blink.st"), "--out", str(tmp_path / "out")]) == 0
    root = tmp_path / "out" / project_dir("Blink")
    # one VAR block per class, as the editor writes it back (its build splits located and
    # plain variables again); the library function used comes along in its own file
    assert (root / "pous/programs/Blink.st").read_text("utf-8") == (
        "PROGRAM Blink\nVAR\n\tLamp : BOOL AT %QX0.0; (* the lamp *)\n"
        "\tPhase : REAL AT %MD0 := 0.5;\n\tAngle : REAL;\nEND_VAR\n\n"
        "Angle := DegToRad(Phase);\nLamp := Angle > 0.0;\n\nEND_PROGRAM")
    assert (root / "pous/functions/DegToRad.st").read_text("utf-8").startswith("(* ")
    project = json.loads((root / "project.json").read_text("utf-8"))
    assert project["data"]["configuration"]["resource"] == {
        "tasks": [{"name": "Fast", "triggering": "Cyclic", "interval": "T#20ms",
                   "priority": 1}],
        "instances": [{"name": "Blinker", "task": "Fast", "program": "Blink"}],
        "globalVariables": []}


# the holding block of v4's Modbus plugin lays %QW, %MW, %MD (2 registers each) and %ML
# (4 each) head to tail (simple_modbus.py of Autonomy-Logic/openplc-runtime)
HOLDING_SEGMENTS = (("%QW", "qwCount", 1), ("%MW", "mwCount", 1), ("%MD", "mdCount", 2),
                    ("%ML", "mlCount", 4))
V3_MAP = {"holdingRegisters": {"qwCount": 1024, "mwCount": 1024, "mdCount": 1024,
                               "mlCount": 1024},
          "coils": {"qxBits": 8192, "mxBits": 0}, "discreteInputs": {"ixBits": 8192},
          "inputRegisters": {"iwCount": 1024}}


def modbus_server_record(project: dict[str, Any]) -> dict[str, Any]:
    servers = project["data"]["servers"]
    assert len(servers) == 1 and servers[0]["protocol"] == "modbus-tcp", servers
    record: dict[str, Any] = servers[0]
    return record


def v4_holding_address(location: str, counts: dict[str, int]) -> tuple[int, bool]:
    """Where v4's plugin serves a %QW/%MW/%MD/%ML variable with these segment counts, and
    whether its segment reaches it."""
    start = 0
    for prefix, key, width in HOLDING_SEGMENTS:
        if location.startswith(prefix):
            index = int(location[3:])
            return start + index * width, index < counts[key]
        start += counts[key] * width
    raise ValueError(location)


def test_the_v4_project_carries_a_modbus_server_that_keeps_the_register_map() -> None:
    """The controller's project holds an enabled Modbus TCP server on port 502 whose segment
    counts put every holding register of the register map (derived from Controller.st) where
    v3 serves it, and cover its coils, discrete inputs and input registers."""
    project = json.loads((V4_PROJECT / "project.json").read_text("utf-8"))
    server = modbus_server_record(project)["modbusSlaveConfig"]
    assert (server["enabled"], server["networkInterface"], server["port"]) == \
        (True, "0.0.0.0", 502)
    mapping = server["bufferMapping"]
    regs = list(controller_map().values())
    holding = [r for r in regs if r.table == "holding"]
    assert {r.location[:3] for r in holding} >= {"%QW", "%MW", "%MD"}
    for reg in holding:
        assert v4_holding_address(reg.location, mapping["holdingRegisters"]) == \
            (reg.address, True), reg
    tops = {"coil": ("coils", "qxBits"), "discrete": ("discreteInputs", "ixBits"),
            "input": ("inputRegisters", "iwCount")}
    for reg in regs:
        if reg.table in tops:
            group, key = tops[reg.table]
            assert reg.address + reg.count <= mapping[group][key], reg


def test_the_modbus_server_grows_to_a_programs_addresses(tmp_path: Path) -> None:
    """Counts come from the program's addresses: a segment v3's map leaves empty (%MX, whose
    coils the plugin puts after %QX) grows to the program's, and a program within v3's map
    gets v3's map."""
    src = tmp_path / "Blink.st"
    src.write_text(BLINK.replace("Phase AT %MD0 : REAL := 0.5;",
                                 "Phase AT %MD0 : REAL := 0.5;\n    Flag AT %MX3.1 : BOOL;"))
    assert main(["export", str(src), "--out", str(tmp_path / "out")]) == 0
    project = json.loads((tmp_path / "out" / project_dir("Blink") / "project.json")
                         .read_text("utf-8"))
    mapping = modbus_server_record(project)["modbusSlaveConfig"]["bufferMapping"]
    assert mapping == {**V3_MAP, "coils": {"qxBits": 8192, "mxBits": 32}}
    (tmp_path / "Plain.st").write_text(BLINK)
    assert main(["export", str(tmp_path / "Plain.st"), "--out", str(tmp_path / "plain")]) == 0
    plain = json.loads((tmp_path / "plain" / project_dir("Blink") / "project.json")
                       .read_text("utf-8"))
    assert modbus_server_record(plain)["modbusSlaveConfig"]["bufferMapping"] == V3_MAP


# ---------------------------------------------------------------- the editor's own code
def editor_checkout() -> Path:
    named = os.environ.get("OPENPLC_EDITOR", "")
    if not named:
        pytest.skip(EDITOR_SKIP)
    path = Path(named)
    if not (path / "src" / "types" / "PLC" / "open-plc.ts").is_file():
        pytest.fail(f"OPENPLC_EDITOR={named} holds no src/types/PLC/open-plc.ts: point it at a "
                    "checkout of Autonomy-Logic/openplc-editor")
    if shutil.which("node") is None:
        pytest.fail("OPENPLC_EDITOR is set but no node is on the PATH")
    return path


def run_editor(command: str, project: Path) -> str:
    proc = subprocess.run(["node", str(EDITOR_SCRIPT), str(editor_checkout()), command,
                           str(project)], capture_output=True, text=True, timeout=600,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


@pytest.fixture(scope="module")
def loaded() -> dict[str, Any]:
    out: dict[str, Any] = json.loads(run_editor("load", V4_PROJECT))
    return out


def test_project_json_passes_the_editors_schema(loaded: dict[str, Any]) -> None:
    assert loaded["schema"] == {"success": True}


def expected_variables(exp_pou: A.Pou) -> list[tuple[str, str, str]]:
    """(name, class, location) of a POU's declarations, in the order the editor keeps."""
    order = ("global", "external", "input", "output", "inOut", "local", "temp")
    decls = [(CLASSES[b.kind], d) for b in exp_pou.blocks for d in b.decls]
    return [(d.name, cls, d.address or "") for c in order for cls, d in decls if cls == c]


def test_the_editor_opens_every_pou_in_full(loaded: dict[str, Any]) -> None:
    result = loaded["loaded"]
    assert result["success"], result
    exp = generate()
    pous = {p.name: p for s in exp.sources for p in s.unit.pous}
    got = {p["data"]["name"]: p for p in result["data"]["pous"]}
    assert sorted(got) == sorted(pous)
    kinds = {"PROGRAM": "program", "FUNCTION": "function", "FUNCTION_BLOCK": "function-block"}
    for name, pou in pous.items():
        data = got[name]["data"]
        # a declaration the loader cannot read makes it keep the POU as raw text
        assert "variablesText" not in data, f"{name}: the editor fell back to raw text"
        assert got[name]["type"] == kinds[pou.kind.upper()]
        assert data["language"] == "st" and data["body"]["language"] == "st"
        assert [(v["name"], v["class"], v["location"]) for v in data["variables"]] == \
            expected_variables(pou), name
        decls = {d.name: d for b in pou.blocks for d in b.decls}
        for v in data["variables"]:
            d = decls[v["name"]]
            # nothing of a declaration line lost: the type and the initial value whole
            assert v["initialValue"] == (None if d.init is None else _init_text(d.init)), \
                (name, v["name"])
            if isinstance(d.type, A.NamedTypeRef):
                assert v["type"]["value"].upper() == d.type.name.upper(), (name, v["name"])
            else:
                assert isinstance(d.type, A.ArrayTypeRef)
                dims = [f"{expr_text(lo)}..{expr_text(hi)}" for lo, hi in d.type.ranges]
                got_dims = ([x["dimension"] for x in v["type"]["data"]["dimensions"]]
                            if v["type"]["definition"] == "array" else None)
                assert got_dims == dims or (len(dims) > 1 and v["type"]["value"] ==
                                            f"{name}_{d.name}"), (name, v["name"])
        if pou.return_type is not None:
            assert isinstance(pou.return_type, A.NamedTypeRef)
            assert data["returnType"].upper() == pou.return_type.name.upper()
        assert data["body"]["value"].strip(), name


def test_the_editor_keeps_every_data_type_and_the_configuration(
        loaded: dict[str, Any]) -> None:
    project = loaded["loaded"]["data"]["project"]
    committed = json.loads((V4_PROJECT / "project.json").read_text("utf-8"))
    assert project["data"]["dataTypes"] == committed["data"]["dataTypes"]
    assert project["data"]["configuration"] == committed["data"]["configuration"]
    assert project["meta"] == committed["meta"]


def test_the_editor_opens_a_user_programs_project(tmp_path: Path) -> None:
    editor_checkout()
    (tmp_path / "Blink.st").write_text(BLINK)
    out = tmp_path / "out"
    assert main(["export", str(tmp_path / "Blink.st"), "--out", str(out)]) == 0
    got = json.loads(run_editor("load", out / project_dir("Blink")))
    assert got["schema"] == {"success": True}
    pous = {p["data"]["name"]: p["data"] for p in got["loaded"]["data"]["pous"]}
    assert sorted(pous) == ["Blink", "DegToRad"]
    lamp = pous["Blink"]["variables"][0]
    assert (lamp["name"], lamp["location"], lamp["documentation"]) == ("Lamp", "%QX0.0",
                                                                       "the lamp")
    assert "variablesText" not in pous["Blink"] and "variablesText" not in pous["DegToRad"]


def test_the_editors_build_writes_the_modbus_segment_counts(tmp_path: Path) -> None:
    """conf/modbus_slave.json, as the editor's build for OpenPLC Runtime v4 writes it from the
    opened project, asks v4's Modbus plugin for the project's counts; a project without the
    server gets none, so the runtime would disable its Modbus plugin at the upload."""
    project = json.loads((V4_PROJECT / "project.json").read_text("utf-8"))
    mapping = modbus_server_record(project)["modbusSlaveConfig"]["bufferMapping"]
    conf = json.loads(run_editor("modbus", V4_PROJECT))
    assert conf["network_configuration"] == {"host": "0.0.0.0", "port": 502}
    h = mapping["holdingRegisters"]
    assert conf["buffer_mapping"] == {
        "holding_registers": {"qw_count": h["qwCount"], "mw_count": h["mwCount"],
                              "md_count": h["mdCount"], "ml_count": h["mlCount"]},
        "coils": {"qx_bits": mapping["coils"]["qxBits"], "mx_bits": mapping["coils"]["mxBits"]},
        "discrete_inputs": {"ix_bits": mapping["discreteInputs"]["ixBits"]},
        "input_registers": {"iw_count": mapping["inputRegisters"]["iwCount"]}}
    assert (h["qwCount"], h["mwCount"]) == (1024, 1024)
    bare = tmp_path / "bare"
    shutil.copytree(V4_PROJECT, bare)
    del project["data"]["servers"]
    (bare / "project.json").write_text(json.dumps(project, indent=2), "utf-8")
    assert run_editor("modbus", bare) == "null"


# ---------------------------------------------------------------- the editor's build
@pytest.fixture(scope="module")
def built_st(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """program.st as the editor's build makes it of the loaded project: its XML generator
    (run by openplc_v4_editor.mjs), then xml2st's ST generation (stage 1; the stage after it
    rewrites structures for MatIEC, which the STruC++ build no longer does)."""
    xml2st = os.environ.get("XML2ST", "")
    if not xml2st:
        pytest.skip(XML2ST_SKIP)
    work = tmp_path_factory.mktemp("v4build")
    (work / "plc.xml").write_text(run_editor("xml", V4_PROJECT), "utf-8")
    python = os.environ.get("XML2ST_PYTHON", sys.executable)
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import xml2st\n"
              "text = xml2st.compile_xml_to_st(sys.argv[2])\n"
              "assert text, 'xml2st generated no ST'\n"
              "open(sys.argv[3], 'w', encoding='utf-8').write(text)\n")
    proc = subprocess.run([python, "-c", script, xml2st, str(work / "plc.xml"),
                           str(work / "program.st")], capture_output=True, text=True,
                          timeout=600, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return work / "program.st"


def test_the_editors_st_passes_the_checker(built_st: Path) -> None:
    assert check_files([built_st]) == []


def test_the_editors_st_compiles_with_strucpp_and_gxx(built_st: Path) -> None:
    tool = find_strucpp()
    if tool is None:
        pytest.skip(SKIP_REASON)
    cpp = built_st.with_suffix(".cpp")
    res = tool.compile(built_st, cpp)
    assert res.ok, res.output[-4000:]
    obj = built_st.with_suffix(".o")
    res = tool.cxx("-O1", "-c", str(cpp), "-o", str(obj))
    assert res.ok, res.output[-4000:]
    assert obj.is_file()


def test_inline_arrays_the_editor_cannot_read_get_a_named_type(tmp_path: Path) -> None:
    src = tmp_path / "Tables.st"
    src.write_text(BLINK.replace("Angle : REAL;", "Angle : REAL;\n    Grid : ARRAY[1..2, 1..3] "
                                 "OF INT;\n    Offsets : ARRAY[-2..2] OF REAL;\n"
                                 "    Row : ARRAY[0..4] OF DINT := [5(7)];"))
    assert main(["export", str(src), "--out", str(tmp_path / "out")]) == 0
    root = tmp_path / "out" / project_dir("Blink")
    text = (root / "pous/programs/Blink.st").read_text("utf-8")
    assert "\tGrid : Blink_Grid;\n\tOffsets : Blink_Offsets;\n" \
        "\tRow : ARRAY[0..4] OF DINT := [5(7)];\n" in text
    types = json.loads((root / "project.json").read_text("utf-8"))["data"]["dataTypes"]
    assert types == [
        {"name": "Blink_Grid", "derivation": "array",
         "baseType": {"definition": "base-type", "value": "int"},
         "dimensions": [{"dimension": "1..2"}, {"dimension": "1..3"}]},
        {"name": "Blink_Offsets", "derivation": "array",
         "baseType": {"definition": "base-type", "value": "real"},
         "dimensions": [{"dimension": "-2..2"}]}]
