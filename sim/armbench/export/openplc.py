"""The OpenPLC Runtime upload file: one .st with library, program and configuration.

Needs: the export Sources in dependency-safe order (``sources.dependency_order``) and the
CheckedProgram for the contents list of the header. The sources' text is copied unchanged;
only ``(* *)`` comments are added (a generated header and one separator per source file), so
the file passes the same checker and MatIEC as its sources.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

from ..compiler.symbols import CheckedProgram
from .sources import Source

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


def render_st(prog: CheckedProgram, sources: Sequence[Source], *, file_name: str,
              version: str) -> str:
    """The upload file's text."""
    out = [
        f"(* {RULE}",
        f"   {file_name} -- OpenPLC Runtime upload file for the arm controller",
        f"   {RULE}",
        f"   GENERATED FILE, do not edit: produced by `armbench export` (armbench {version})",
        "   from these sources, copied unchanged in this dependency-safe order:",
        *(f"     {s.name}" for s in sources),
        "   Regenerate with `armbench export` (docs/exports.md); its --check option (and a",
        "   test) fail when this file is stale. PLCopen XML of the same code:",
        "   plcopen/arm_controller.xml.",
        "",
        "   Contents:",
        *contents_lines(prog, sources),
        "",
        "   Upload: OpenPLC Runtime web page, Programs -> Upload Program (docs/exports.md).",
        f"   {RULE} *)",
    ]
    for s in sources:
        out += ["", f"(* {THIN}", f"   source: {s.name}", f"   {THIN} *)"]
        out.append(s.text if s.text.endswith("\n") else s.text + "\n")
    text = "\n".join(out)
    return text if text.endswith("\n") else text + "\n"
