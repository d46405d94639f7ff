"""The OpenPLC Runtime's Monitoring page lists every located variable of our uploads.

The page lists what ``parse_st`` in the runtime's webserver/monitoring.py finds in the uploaded
file: a line is a variable only when it has `` AT `` (not at its start) and ``%``, and neither
``(*`` nor ``*)``; its space-separated fields are then name, AT, address, colon and
``TYPE;``; %ML1024 and up are left out. The rule is re-implemented here from reading that
file, and with OPENPLC_SRC (the runtime's source tree, e.g. /opt/realplc/src) its own
``parse_st`` runs too. The reference is the checker's reading of the sources the upload is
made from: every located variable with its declared type.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

from armbench.compiler import ast as A
from armbench.compiler.ast import walk
from armbench.compiler.driver import analyse_program
from armbench.export import OPENPLC_FILE, generate
from armbench.locate import default_project

REPO = Path(__file__).resolve().parents[2]
COMMITTED_ST = REPO / "plc_project" / OPENPLC_FILE

USER_PROGRAM = """\
(* A small user program: counts scans, converts an angle with the library. *)
PROGRAM Blink
  VAR
    Count AT %MD0 : DINT;   (* scans since start *)
    Lamp AT %QX0.0 : BOOL;  (* toggles every 10 scans *)
    Angle   AT  %MD1:REAL := 0.5;(* rad *)
  END_VAR
  VAR
    Plain : INT;
  END_VAR
  VAR Level AT %IW3 : INT; Speed AT %MW7 : INT; END_VAR
  Count := Count + 1;
  Lamp := (Count MOD 20) < 10;
  Angle := DegToRad(90.0);
  Plain := Level + Speed;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK Main(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM Inst0 WITH Main : Blink;
  END_RESOURCE
END_CONFIGURATION
"""


def monitor_rule(text: str) -> list[tuple[str, str, str]]:
    """(name, location, type) as OpenPLC's parse_st reads them (re-implemented)."""
    found = []
    for line in text.splitlines(keepends=True):
        if line.find(" AT ") > 0 and line.find("%") > 0 and "(*" not in line \
                and "*)" not in line:
            fields = line.strip().split(" ")
            name, location, typ = fields[0], fields[2], fields[4].split(";")[0]
            if "ML" in location[1:] and int(location.split("%ML")[1]) >= 1024:
                continue
            found.append((name, location, typ))
    return sorted(found)


def openplc_parse_st(src: Path, upload: Path, tmp: Path) -> list[tuple[str, str, str]]:
    """OpenPLC's own parse_st (and its debug_var class) from webserver/monitoring.py, run on
    the upload; only those two definitions are taken, not the file's Modbus imports."""
    module = ast.parse((src / "webserver" / "monitoring.py").read_text())
    keep: list[ast.stmt] = [n for n in module.body
                            if isinstance(n, ast.ClassDef | ast.FunctionDef)
                            and n.name in ("debug_var", "parse_st")]
    assert len(keep) == 2, "monitoring.py no longer defines debug_var and parse_st"
    space: dict[str, object] = {"debug_vars": []}
    exec(compile(ast.Module(keep, []), "monitoring.py", "exec"), space)  # noqa: S102
    (tmp / "st_files").mkdir(parents=True)
    (tmp / "st_files" / "upload.st").write_bytes(upload.read_bytes())
    cwd = Path.cwd()
    os.chdir(tmp)
    try:
        space["parse_st"]("upload.st")  # type: ignore[operator]
    finally:
        os.chdir(cwd)
    return sorted((v.name, v.location, v.type)
                  for v in space["debug_vars"])  # type: ignore[attr-defined]


def located(files: list[Path], library: list[Path]) -> list[tuple[str, str, str]]:
    """Every located variable of the program with its declared type, as the checker reads
    the sources."""
    analysis = analyse_program(files, library)
    assert analysis.program is not None
    return sorted((d.name, d.address or "", d.type.name)
                  for unit in analysis.program.units for d in walk(unit)
                  if isinstance(d, A.VarDecl) and d.address is not None
                  and isinstance(d.type, A.NamedTypeRef))


@pytest.fixture(scope="module")
def user_upload(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    folder = tmp_path_factory.mktemp("user")
    src = folder / "Blink.st"
    src.write_text(USER_PROGRAM)
    lib = default_project().library()
    exp = generate([src], library=lib)
    # the OpenPLC upload, not the v4 project's POU files
    (upload,) = [p for p in exp.write(folder) if p.suffix == ".st" and p.parent.name == "openplc"]
    return upload, [src]


def test_user_upload_lists_every_located_variable(
        user_upload: tuple[Path, list[Path]]) -> None:
    upload, files = user_upload
    want = located(files, default_project().library())
    assert sorted(v[0] for v in want) == ["Angle", "Count", "Lamp", "Level", "Speed"]
    assert monitor_rule(upload.read_text()) == want


def test_controller_upload_lists_every_located_variable() -> None:
    project = default_project()
    want = located([*project.components(), project.controller], project.library())
    assert len(want) > 700
    assert monitor_rule(COMMITTED_ST.read_text()) == want


OPENPLC_SRC = os.environ.get("OPENPLC_SRC", "")


@pytest.mark.skipif(not (Path(OPENPLC_SRC) / "webserver" / "monitoring.py").is_file(),
                    reason="OPENPLC_SRC (the OpenPLC Runtime's source tree) not set")
def test_openplc_own_parser_lists_every_located_variable(
        user_upload: tuple[Path, list[Path]], tmp_path: Path) -> None:
    project = default_project()
    upload, files = user_upload
    assert openplc_parse_st(Path(OPENPLC_SRC), upload, tmp_path / "user") == \
        located(files, project.library())
    assert openplc_parse_st(Path(OPENPLC_SRC), COMMITTED_ST, tmp_path / "ctl") == \
        located([*project.components(), project.controller], project.library())
