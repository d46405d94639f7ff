"""Syntax errors in a CONFIGURATION: a message that says what is out of place and shows the
right form, in the file's own names where it declares them (E0111).

The grammar's error alone names only the text it did not expect ("unexpected 'WITH Main'"),
which does not tell someone writing their first CONFIGURATION where WITH goes. The common
slips each get their own message: WITH on the TASK line, on a line of its own or after the
PROGRAM type; a PROGRAM instance without its TASK or its type; a TASK without its INTERVAL or
`:=`; a TASK after the PROGRAM instances; TASK and PROGRAM lines outside a RESOURCE or outside
any CONFIGURATION; `RESOURCE Res0` without `ON PLC`; a missing END_RESOURCE or ';'. Anything
else inside a CONFIGURATION gets the grammar's text and the whole form.

Only the lines of the error are read (a bounded number of them), so a file with thousands of
syntax errors is still read in linear time.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import tree_sitter as ts


class ParsedFile(Protocol):
    """What the hints read of parse.ParsedFile (a protocol: parse imports this module)."""

    text: str
    data: bytes
    tree: ts.Tree
    line_starts: list[int]

    def text_of(self, node: ts.Node) -> str: ...

CONFIGURATION = "configuration_declaration"
RESOURCE = "resource_declaration"


def task_form(task: str = "MainTask") -> str:
    """A periodic TASK's declaration."""
    return f"TASK {task}(INTERVAL := T#10ms, PRIORITY := 0);"


def instance_form(inst: str = "Inst", task: str | None = None, prog: str | None = None) -> str:
    """A PROGRAM instance's line: the instance, WITH its TASK, ':' and the PROGRAM it runs."""
    return f"PROGRAM {inst} WITH {task or 'MainTask'} : {prog or 'Main'};"


def configuration_form(prog: str | None = None, task: str | None = None) -> str:
    """The whole CONFIGURATION on one line (valid ST as it stands)."""
    return (f"CONFIGURATION Config0 RESOURCE Res0 ON PLC {task_form(task or 'MainTask')} "
            f"{instance_form('Inst', task, prog)} END_RESOURCE END_CONFIGURATION")


_MAX_LINES = 40  # lines of one error read for a hint
_MAX_BYTES = 8192  # of them: a 100,000-term line with many errors is not read once per error

_ID = r"[A-Za-z_]\w*"
_TASK_WITH = re.compile(rf"^\s*TASK\s+({_ID})(.*?)\bWITH\s+({_ID})", re.I)
_WITH_LINE = re.compile(rf"^\s*WITH\s+({_ID})", re.I)
_TYPE_THEN_WITH = re.compile(rf"^\s*PROGRAM\s+({_ID})\s*:\s*({_ID})\s+WITH\s+({_ID})", re.I)
_WITH_NO_TYPE = re.compile(rf"^\s*PROGRAM\s+({_ID})\s+WITH\s+({_ID})\s*;?\s*$", re.I)
_INSTANCE = re.compile(rf"^\s*PROGRAM\s+({_ID})\s*(?:WITH\s+({_ID})\s*)?:\s*({_ID})", re.I)
_INSTANCE_NO_SEMI = re.compile(rf"^\s*PROGRAM\s+{_ID}\s+WITH\s+{_ID}\s*:\s*{_ID}\s*(\(\s*\))?\s*$",
                               re.I)
_TASK_BARE = re.compile(rf"^\s*TASK\s+({_ID})\s*;?\s*$", re.I)
_TASK = re.compile(rf"^\s*TASK\s+({_ID})", re.I)
_TASK_COMPLETE = re.compile(rf"^\s*TASK\s+{_ID}\s*\(.*\bINTERVAL\s*:=.*\)\s*;", re.I)
_TASK_NO_SEMI = re.compile(rf"^\s*TASK\s+{_ID}\s*\(.*\)\s*$", re.I)
_RESOURCE_NO_ON = re.compile(rf"^\s*RESOURCE\s+({_ID})\s*$", re.I)
_RESOURCE = re.compile(r"^\s*RESOURCE\b", re.I)
_CONFIGURATION = re.compile(r"^\s*CONFIGURATION\b", re.I)
_PROGRAM_LINE = re.compile(r"^\s*PROGRAM\b", re.I)
_INSTANCES = re.compile(_INSTANCE.pattern, re.I | re.M)
_DECLARED_TASK = re.compile(rf"^\s*TASK\s+({_ID})\s*\(", re.I | re.M)
# The first line of an error outside any configuration that was meant to be in one.
_MEANT_FOR_CONFIGURATION = re.compile(
    rf"^\s*(?:(?:CONFIGURATION|RESOURCE|TASK|WITH)\b|PROGRAM\s+{_ID}\s*(?:WITH\b|:))", re.I)


@dataclass(frozen=True)
class _Names:
    """The names the right form is written with: the file's own where it has them."""

    tasks: tuple[str, ...]  # TASKs the file declares with parameters
    programs: tuple[str, ...]  # PROGRAMs the file declares
    instances: tuple[tuple[str, str], ...]  # (instance, PROGRAM) of the file's PROGRAM lines

    @property
    def task(self) -> str:
        return self.tasks[0] if self.tasks else "MainTask"

    @property
    def program(self) -> str:
        return self.programs[0] if self.programs else "Main"

    def is_program(self, name: str) -> bool:
        return name.upper() in (p.upper() for p in self.programs)

    def is_task(self, name: str) -> bool:
        return name.upper() in (t.upper() for t in self.tasks)

    def instance(self, inst: str | None = None, task: str | None = None,
                 prog: str | None = None) -> str:
        """A PROGRAM instance's line; without ``inst``, the name the file gives an instance of
        that PROGRAM on a line of its own (else Inst)."""
        prog = prog or self.program
        if inst is None:
            inst = next((i for i, p in self.instances if p.upper() == prog.upper()), "Inst")
        return instance_form(inst, task or self.task, prog)

    def task_line(self, task: str | None = None) -> str:
        return task_form(task or self.task)

    def form(self) -> str:
        return configuration_form(self.program, self.task)


class ConfigurationHints:
    """The E0111 messages of one file's syntax errors; the names it declares are read once,
    at its first error in a CONFIGURATION."""

    def __init__(self, pf: ParsedFile) -> None:
        self.pf = pf

    @cached_property
    def names(self) -> _Names:
        programs = []
        for child in self.pf.tree.root_node.children:  # top level only: cheap
            if child.type == "program_declaration":
                name = child.child_by_field_name("name")
                if name is not None:
                    programs.append(self.pf.text_of(name))
        tasks = tuple(dict.fromkeys(_DECLARED_TASK.findall(self.pf.text)))
        instances = tuple((m.group(1), m.group(3)) for m in _INSTANCES.finditer(self.pf.text))
        return _Names(tasks, tuple(programs), instances)

    def hint(self, node: ts.Node, context: str | None) -> str | None:
        """The message for the syntax error ``node`` (an ERROR or a missing token) when it is
        in a CONFIGURATION or looks meant for one, else None. ``context``: the innermost of
        CONFIGURATION and RESOURCE that holds the node (None: neither)."""
        if node.is_missing:
            return _missing(node, self.names) if context is not None else None
        pf = self.pf
        if context is None and not _MEANT_FOR_CONFIGURATION.match(_head(pf, node)):
            return None  # the common case outside a configuration: a short look at its line
        lines = _lines(pf, node)
        names = self.names
        where = context
        for i, line in enumerate(lines):
            if _CONFIGURATION.match(line):
                where = CONFIGURATION
                continue
            if where is None and i > 0:
                break  # outside a configuration only the error's first line is read
            message = _line_hint(line, lines[i - 1] if i else _line_before(pf, node), where,
                                 names)
            if message is not None:
                return message
            if _RESOURCE.match(line):
                where = RESOURCE
        if context is None and where is None:
            return None
        return (f"syntax error in the CONFIGURATION: unexpected '{_first(lines)}'; the form "
                f"is `{names.form()}`")


def _line_hint(line: str, before: str, where: str | None, names: _Names) -> str | None:
    """The message for one line of an error, or None when the line shows nothing known."""
    m = _TASK_WITH.match(line)
    if m:
        task, params, with_name = m.group(1), m.group(2).strip(), m.group(3)
        task_line = f"TASK {task}{params};" if "(" in params else names.task_line(task)
        prog = with_name if names.is_program(with_name) else None
        return (f"WITH goes on the PROGRAM instance's line, not on the TASK's: write "
                f"`{task_line}` and then `{names.instance(task=task, prog=prog)}`")
    m = _WITH_LINE.match(line)
    if m:
        prev = _INSTANCE.match(before)
        inst, prog = (prev.group(1), prev.group(3)) if prev else (None, None)
        return (f"WITH belongs on the PROGRAM instance's line, between the instance name and "
                f"':': `{names.instance(inst, m.group(1), prog)}`")
    m = _TYPE_THEN_WITH.match(line)
    if m:
        return (f"WITH and its TASK come before the ':' and the PROGRAM type: "
                f"`{names.instance(m.group(1), m.group(3), m.group(2))}`")
    m = _WITH_NO_TYPE.match(line)
    if m:
        return _instance_without_type(m.group(1), m.group(2), names)
    if _INSTANCE_NO_SEMI.match(line):
        return f"missing ';' at the end of the PROGRAM instance's line: `{line.strip()};`"
    if _PROGRAM_LINE.match(line) and _INSTANCE.match(line):
        if where is None:
            return _outside("a PROGRAM instance", names)
        if where == CONFIGURATION:
            return _outside_resource("a PROGRAM instance", names)
    m = _TASK.match(line)
    if m:
        return _task_hint(line, m.group(1), where, names)
    m = _RESOURCE_NO_ON.match(line)
    if m:
        return (f"a RESOURCE names the PLC it runs on: `RESOURCE {m.group(1)} ON PLC` (then its "
                f"TASKs and PROGRAM instances, then END_RESOURCE)")
    if _RESOURCE.match(line) and where is None:
        return _outside("a RESOURCE", names)
    return None


def _task_hint(line: str, task: str, where: str | None, names: _Names) -> str:
    if where is None:
        return _outside("a TASK", names)
    if where == CONFIGURATION:
        return _outside_resource("a TASK", names)
    form = names.task_line(task)
    if _TASK_BARE.match(line):
        return f"a TASK needs its period: `{form}` (the bench and OpenPLC run periodic tasks)"
    if _TASK_COMPLETE.match(line):
        return (f"the TASKs come first in a RESOURCE, before the PROGRAM instances that name "
                f"them: move `{line.strip()}` above them")
    if _TASK_NO_SEMI.match(line):
        return f"missing ';' at the end of the TASK's line: `{line.strip()};`"
    if "(" in line and ":=" not in line:
        return f"a TASK's parameters are set with ':=': `{form}`"
    return f"a TASK reads `{form}`"


def _instance_without_type(first: str, second: str, names: _Names) -> str:
    """`PROGRAM a WITH b;`: the instance line lacks ': Type' (or a TASK to name)."""
    if names.is_task(second):
        prog = first if names.is_program(first) else None
        inst = "Inst" if prog is not None else first
        return (f"a PROGRAM instance names the instance, WITH its TASK, then ':' and the "
                f"PROGRAM it runs: `{names.instance(inst, second, prog)}`"
                + (" (Inst: a name of your choice)" if inst == "Inst" else ""))
    prog = second if names.is_program(second) else first if names.is_program(first) else None
    inst = first if not names.is_program(first) else "Inst"
    lead = ("WITH names a TASK, and none is declared: declare one first"
            if not names.tasks else f"WITH names a TASK ({', '.join(names.tasks)}), not "
            f"'{second}'")
    return (f"{lead}, then tie the PROGRAM to it: `{names.task_line()}` "
            f"`{names.instance(inst, prog=prog)}`")


def _outside(what: str, names: _Names) -> str:
    inside = "a CONFIGURATION" if what == "a RESOURCE" else "a RESOURCE of a CONFIGURATION"
    return f"{what} goes inside {inside}: `{names.form()}`"


def _outside_resource(what: str, names: _Names) -> str:
    return (f"{what} goes inside a RESOURCE, not directly in the CONFIGURATION: "
            f"`{names.form()}`")


def _missing(node: ts.Node, names: _Names) -> str:
    kind = node.type
    if kind == "END_RESOURCE":
        return ("missing END_RESOURCE: close the RESOURCE after its last PROGRAM instance, "
                f"before END_CONFIGURATION: `{names.form()}`")
    if kind == "END_CONFIGURATION":
        return f"missing END_CONFIGURATION after END_RESOURCE: `{names.form()}`"
    return f"syntax error in the CONFIGURATION: missing '{kind}'; the form is `{names.form()}`"


def _lines(pf: ParsedFile, node: ts.Node) -> list[str]:
    """The whole lines the error spans (at most _MAX_LINES of them), blank ones left out."""
    row = node.start_point.row
    last = min(node.end_point.row, row + _MAX_LINES - 1)
    start = pf.line_starts[row]
    end = pf.line_starts[last + 1] if last + 1 < len(pf.line_starts) else len(pf.data)
    text = pf.data[start:min(end, start + _MAX_BYTES)].decode("utf-8", "replace")
    return [ln for ln in text.splitlines()[:_MAX_LINES] if ln.strip()]


def _head(pf: ParsedFile, node: ts.Node) -> str:
    """The start of the error's first line."""
    start = pf.line_starts[node.start_point.row]
    return pf.data[start:start + 200].decode("utf-8", "replace")


def _line_before(pf: ParsedFile, node: ts.Node) -> str:
    """The last non-blank line above the node's (for WITH on a line of its own)."""
    row = node.start_point.row
    for r in range(row - 1, max(-1, row - 5), -1):
        end = pf.line_starts[r + 1] if r + 1 < len(pf.line_starts) else len(pf.data)
        line = pf.data[pf.line_starts[r]:end].decode("utf-8", "replace")
        if line.strip():
            return line
    return ""


def _first(lines: list[str]) -> str:
    return lines[0].strip()[:40] if lines else ""
