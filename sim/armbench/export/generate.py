"""Run an export: check the sources, order them, render both files, write or compare.

Needs: nothing before it; it runs the checker itself and refuses to export (CompileFailed)
when the sources have errors.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from ..compiler.diagnostics import CompileFailed
from ..compiler.driver import analyse_program, expand
from ..compiler.source import read_source
from ..compiler.symbols import CheckedProgram
from ..compiler.targets import OPENPLC_ONLY
from ..locate import Project, default_project
from .codesys import layout, render_register_map
from .openplc import contents_lines, render_st
from .openplc_v4 import V4ExportError, build_project, project_dir
from .plcopen import build_xml
from .sources import Source, dependency_order, display_name

TITLE = "arm_controller"  # the project's own exports: the arm controller
OPENPLC_FILE = Path("openplc") / f"{TITLE}.st"
PLCOPEN_FILE = Path("plcopen") / f"{TITLE}.xml"
CODESYS_FILE = Path("codesys") / f"{TITLE}_codesys.xml"
CODESYS_MAP_FILE = Path("codesys") / "register-map.md"
LIBRARY_TITLE = "armbench_library"


def export_paths(name: str) -> tuple[Path, Path, Path, Path]:
    """The OpenPLC upload, PLCopen XML, CODESYS XML and register map of an export ``name``."""
    return (Path("openplc") / f"{name}.st", Path("plcopen") / f"{name}.xml",
            Path("codesys") / f"{name}_codesys.xml", CODESYS_MAP_FILE)


def _version() -> str:
    try:
        return metadata.version("armbench")
    except metadata.PackageNotFoundError:  # running from a source tree without install
        return "0"


@dataclass(frozen=True)
class Export:
    """The generated files, keyed by their path relative to the output folder; ``folders``
    are written whole: a file in one that the export does not hold is stale (a v4 project
    folder: the editor would load a POU file left over from a POU since removed)."""

    program: CheckedProgram
    sources: list[Source]
    files: dict[Path, bytes]
    folders: tuple[Path, ...] = ()
    warnings: tuple[str, ...] = ()  # what was left out, and why

    def extra(self, out_dir: Path) -> list[Path]:
        """Files in the export's folders under out_dir that the export does not hold."""
        return sorted(p for d in self.folders if (out_dir / d).is_dir()
                      for p in (out_dir / d).rglob("*")
                      if p.is_file() and p.relative_to(out_dir) not in self.files)

    def write(self, out_dir: Path) -> list[Path]:
        for path in self.extra(out_dir):
            path.unlink()
        written = []
        for rel, data in self.files.items():
            path = out_dir / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            written.append(path)
        return written

    def stale(self, out_dir: Path) -> list[tuple[Path, str]]:
        """(path, "missing" | "differs") for every file in out_dir not equal to the export."""
        bad = []
        for rel, data in self.files.items():
            path = out_dir / rel
            if not path.exists():
                bad.append((path, "missing"))
            elif path.read_bytes() != data:
                bad.append((path, "differs"))
        return bad + [(path, "not in the export") for path in self.extra(out_dir)]


def _shown(paths: Sequence[Path], most: int = 3) -> str:
    """Paths as the user gave them, the first few."""
    names = [p.as_posix() for p in paths]
    return ", ".join(names) if len(names) <= most else \
        f"{', '.join(names[:most])} and {len(names) - most} more"


def load_sources(paths: Sequence[str | Path] | None = None, project: Project | None = None,
                 *, library: Sequence[str | Path] | None = None, need_config: bool = True
                 ) -> tuple[CheckedProgram, list[Source]]:
    """Check the program ``paths`` with the declarations of ``library`` it uses (default:
    the controller of ``project`` -- itself by default the files the tools use -- with its
    st/*.st) and return the program with the sources in dependency-safe order, library
    sources holding only the declarations used. Raises CompileFailed on any error,
    ValueError when ``need_config`` and the program has no CONFIGURATION (an OpenPLC upload
    without one does nothing)."""
    project = project or default_project()
    if paths is None:
        files = [*project.components(), project.controller]
        lib_files = project.library() if library is None else expand(library)
    else:
        files = expand(paths)
        lib_files = expand(library or [])
    # what OpenPLC builds, as before targets existed; `armbench check` checks the others
    analysis = analyse_program(files, lib_files, OPENPLC_ONLY)
    prog = analysis.program
    if prog is None:
        raise CompileFailed(analysis.diagnostics.sorted())
    if need_config and prog.config is None:
        raise ValueError(
            f"nothing to export: {_shown(files)} declare{'s' if len(files) == 1 else ''} no "
            "CONFIGURATION; the OpenPLC Runtime "
            "runs only a CONFIGURATION (CONFIGURATION Config0 / RESOURCE Res0 ON PLC / TASK ... "
            "/ PROGRAM inst WITH task : YourProgram; see the arm controller's Controller.st), "
            "or export blocks and types alone with --library-only")
    library_files = set(analysis.library.files)
    sources = []
    # the library's declarations ahead of the program's, as a reader expects them
    for unit in sorted(prog.units, key=lambda u: u.pos.file not in library_files):
        f = Path(unit.pos.file)
        sources.append(Source(f, display_name(f, project), read_source(f).text, unit,
                              library=unit.pos.file in library_files))
    order = dependency_order([s.unit for s in sources])
    return prog, [sources[i] for i in order]


def program_name(prog: CheckedProgram, sources: Sequence[Source]) -> str:
    """What an export is named after: the program's one PROGRAM, else its first file."""
    mine = [s for s in sources if not s.library]
    programs = [p.name for s in mine for p in s.unit.pous if p.kind.upper() == "PROGRAM"]
    if len(programs) == 1:
        return programs[0]
    return mine[0].path.stem if mine else LIBRARY_TITLE


def generate(paths: Sequence[str | Path] | None = None,
             project: Project | None = None, *, library: Sequence[str | Path] | None = None,
             name: str | None = None) -> Export:
    """The exports of the program ``paths`` with what it uses of ``library`` (default: the
    arm controller of ``project`` with its library, named arm_controller), named ``name``
    (default: after the program, :func:`program_name`)."""
    prog, sources = load_sources(paths, project, library=library)
    controller = paths is None
    name = name or (TITLE if controller else program_name(prog, sources))
    what = "the arm controller" if controller else f"the program {name}"
    st_file, xml_file, codesys_file, map_file = export_paths(name)
    version = _version()
    st = render_st(prog, sources, file_name=st_file.name, version=version, what=what,
                   xml_file=xml_file.name)
    comment = "\n".join([
        f"Generated by `armbench export` (armbench {version}) from "
        + ", ".join(s.name for s in sources) + "; do not edit.",
        "Contents:",
        *(ln[5:] for ln in contents_lines(prog, sources)),
    ])
    xml = build_xml(prog, sources, title=name, version=version, comment=comment)
    placed = layout(prog)
    codesys_comment = comment.replace(
        "; do not edit.", "; do not edit.\nCODESYS variant: the located variables sit in %I "
        "(what clients write) and %Q (what the program writes) without overlapping bytes; "
        f"their Modbus registers are in {map_file.as_posix()}.", 1)
    codesys_xml = build_xml(prog, sources, title=f"{name}_codesys", version=version,
                            comment=codesys_comment,
                            addresses={id(p.decl): str(p.codesys) for p in placed})
    codesys_map = render_register_map(placed, name)
    files = {st_file: st.encode("utf-8"), xml_file: xml, codesys_file: codesys_xml,
             map_file: codesys_map.encode("utf-8")}
    # what the v4 editor cannot represent leaves out its project, not the other exports
    try:
        files |= build_project(prog, sources, name=name)
    except V4ExportError as e:
        return Export(prog, sources, files, warnings=(
            f"no OpenPLC v4 project ({project_dir(name).as_posix()}/): {e}",))
    return Export(prog, sources, files, folders=(project_dir(name),))


def generate_library(paths: Sequence[str | Path] | None = None,
                     project: Project | None = None, *,
                     library: Sequence[str | Path] | None = None,
                     name: str | None = None) -> Export:
    """PLCopen XML of blocks and types alone -- no PROGRAM, no CONFIGURATION -- for CODESYS
    (Project > Import PLCopenXML): every declaration of ``paths`` with what they use of
    ``library`` (default: the whole armbench library of ``project``), written to
    codesys/NAME.xml (default: after the first file; the whole library: armbench_library)."""
    project = project or default_project()
    files = expand(paths) if paths else project.library()
    prog, sources = load_sources(files, project, library=library if paths else [],
                                 need_config=False)
    pous = [f"PROGRAM {p.name}" for s in sources for p in s.unit.pous
            if p.kind.upper() == "PROGRAM"]
    if prog.config is not None or pous:
        raise ValueError(
            f"a library-only export holds blocks and types alone, and {_shown(files)} "
            f"declare{'s' if len(files) == 1 else ''} "
            + ", ".join(pous + ([f"CONFIGURATION {prog.config.name}"] if prog.config else []))
            + ": leave those files out, or export the program without --library-only")
    name = name or (files[0].stem if paths else LIBRARY_TITLE)
    version = _version()
    comment = "\n".join([
        f"Generated by `armbench export --library-only` (armbench {version}) from "
        + ", ".join(s.name for s in sources) + "; do not edit. Blocks and types only, for "
        "CODESYS: Project > Import PLCopenXML.",
        "Contents:",
        *(ln[5:] for ln in contents_lines(prog, sources)),
    ])
    xml = build_xml(prog, sources, title=name, version=version, comment=comment)
    return Export(prog, sources, {Path("codesys") / f"{name}.xml": xml})
