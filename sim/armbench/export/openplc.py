"""The OpenPLC Runtime upload file: one .st with program, configuration and what the program
uses of the library.

Needs: the export Sources in dependency-safe order (``sources.dependency_order``) and the
CheckedProgram for the contents list of the header. The program's text is copied, its located
declarations one per line (:func:`.sttext.monitor_friendly`); of a library file, the used
declarations' text as written; ``(* *)`` comments are added (a generated header and one
separator per source file), so the file passes the same checker and MatIEC as its sources.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

from ..compiler import ast as A
from ..compiler.symbols import CheckedProgram
from .sources import Source
from .sttext import SourceText, declaration_span, monitor_friendly

RULE = "=" * 76
THIN = "-" * 75


def _names(label: str, names: Sequence[str]) -> list[str]:
    if not names:
        return []
    return textwrap.wrap(", ".join(names), width=78, initial_indent=f"     {label:<16}",
                         subsequent_indent=" " * 21, break_on_hyphens=False)


def contents_lines(prog: CheckedProgram, sources: Sequence[Source]) -> list[str]:
    """What the export holds, by kind, in source order (for the header comments)."""
    types = [t.name for s in sources for t in s.unit.types]
    by_kind: dict[str, list[str]] = {"FUNCTION": [], "FUNCTION_BLOCK": [], "PROGRAM": []}
    for s in sources:
        for p in s.unit.pous:
            by_kind[p.kind.upper()].append(p.name)
    lines = [*_names("types", types), *_names("functions", by_kind["FUNCTION"]),
             *_names("function blocks", by_kind["FUNCTION_BLOCK"]),
             *_names("programs", by_kind["PROGRAM"])]
    cfg = prog.config
    if cfg is not None:
        tasks = ", ".join(f"{t.name} ({t.interval_ns / 1e6:g} ms, priority {t.priority})"
                          for t in cfg.tasks)
        insts = ", ".join(f"{i.name} : {i.pou.name}" + (f" WITH {i.task}" if i.task else "")
                          for i in cfg.instances)
        lines += _names("configuration", [f"{cfg.name} / resource {cfg.resource}"])
        lines += _names("tasks", [tasks]) + _names("instances", [insts])
    return lines


def upload_text(src: Source) -> str:
    """A source's text in the upload: of a library file only the declarations the program
    uses, each as written with its header comment (TYPE definitions in one TYPE block); of
    the program's own files the whole text, located declarations laid out for the OpenPLC
    Monitoring page (:func:`.sttext.monitor_friendly`)."""
    st = SourceText(src.text)
    if not src.library:
        return monitor_friendly(st, [n for n in A.walk(src.unit)
                                     if isinstance(n, A.VarDecl) and n.address is not None])
    parts: list[str] = []
    if src.unit.types:
        body = "\n".join(st.text[slice(*declaration_span(st, t))] for t in src.unit.types)
        parts.append(f"TYPE\n{body}\nEND_TYPE\n")
    parts += [st.text[slice(*declaration_span(st, p))] + "\n" for p in src.unit.pous]
    return "\n".join(parts)


def render_st(prog: CheckedProgram, sources: Sequence[Source], *, file_name: str,
              version: str, what: str, xml_file: str) -> str:
    """The upload file's text; ``what`` it is the upload of (\"the arm controller\")."""
    out = [
        f"(* {RULE}",
        f"   {file_name} -- OpenPLC Runtime upload file of {what}",
        f"   {RULE}",
        f"   GENERATED FILE, do not edit: produced by `armbench export` (armbench {version})",
        "   from these sources, in this dependency-safe order (of the armbench library only",
        "   the declarations the program uses; located variables one per line, for the",
        "   Monitoring page):",
        *(f"     {s.name}" for s in sources),
        "   Regenerate with `armbench export` (docs/exports.md); its --check option (and a",
        "   test) fail when this file is stale. PLCopen XML of the same code:",
        f"   plcopen/{xml_file}.",
        "",
        "   Contents:",
        *contents_lines(prog, sources),
        "",
        "   Upload: OpenPLC Runtime web page, Programs -> Upload Program (docs/exports.md).",
        f"   {RULE} *)",
    ]
    for s in sources:
        label = f"{s.name} (what the program uses of it)" if s.library else s.name
        out += ["", f"(* {THIN}", f"   source: {label}", f"   {THIN} *)"]
        text = upload_text(s)
        out.append(text if text.endswith("\n") else text + "\n")
    text = "\n".join(out)
    return text if text.endswith("\n") else text + "\n"
