"""OpenPLC v4 editor project folder: ``project.json`` plus one ST file per POU.

Needs: a CheckedProgram without errors and the export Sources in dependency-safe order (as
for :mod:`.plcopen`). Writes the layout the v4 editor (Autonomy-Logic/openplc-editor) opens
with File > Open: ``project.json`` holds the data types, the one configuration (tasks,
program instances, global variables) and no POUs; each POU is ``pous/programs/``,
``pous/functions/`` or ``pous/function-blocks/`` ``<Name>.st``. The editor keeps neither
``devices/`` file from us: it fills in its own defaults on open.

The POU files are written the way the editor itself saves them (its pou-text-serializer:
``(* documentation *)``, the header line, the variable blocks grouped by class, the body,
the END keyword), because its loader reads variables line by line with regular expressions:
one declaration per line, ``Name : Type [AT %addr] [:= init];`` with at most one trailing
comment, which becomes the variable's documentation. Comments standing alone in a VAR block
are not kept (the loader refuses such a line), and a ``VAR CONSTANT`` block loads as a plain
``VAR`` (the editor has no constant flag). Data types go into ``project.json`` as the editor's
structure / array / enumeration records; what it has no record for (subranges, aliases,
enumerations with explicit values) is refused with a message. An inline array the loader
cannot read (more than one dimension: editor 4.1 reads only one inline, later versions read
both; a negative bound) is declared through a generated named type. The output is
deterministic.

``project.json`` also carries one Modbus TCP server (the editor's ``data.servers``, what its
Modbus server screen edits): without one the editor's upload carries no
``conf/modbus_slave.json`` and the runtime disables its Modbus plugin. Its buffer mapping is
v3's map (the editor's and the plugin's defaults), each segment grown to the program's located
variables (:func:`modbus_server`).
"""

from __future__ import annotations

import json
import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..compiler import ast as A
from ..compiler.symbols import CheckedProgram
from ..softplc.openplc_v4 import DEFAULT_COUNTS, SEGMENT_TABLES, image_floor
from .sources import Source
from .sttext import SourceText, expr_text

V4_DIR = Path("openplc-v4")

# the editor's base types (open-plc.ts, baseTypeSchema), spelled as its schema lists them
BASE_TYPES = ("bool", "sint", "int", "dint", "lint", "usint", "uint", "udint", "ulint",
              "real", "lreal", "time", "date", "tod", "dt", "string", "byte", "word",
              "dword", "lword")
_BASE_ALIASES = {"TIME_OF_DAY": "tod", "DATE_AND_TIME": "dt"}

POU_FOLDERS = {"PROGRAM": "programs", "FUNCTION": "functions",
               "FUNCTION_BLOCK": "function-blocks"}
# VAR block kind -> the editor's variable class, and the order its serializer writes them in
CLASSES = {A.VAR_GLOBAL: "global", A.VAR_EXTERNAL: "external", A.VAR_INPUT: "input",
           A.VAR_OUTPUT: "output", A.VAR_IN_OUT: "inOut", A.VAR: "local", A.VAR_TEMP: "temp"}
CLASS_ORDER = ("global", "external", "input", "output", "inOut", "local", "temp")
BLOCK_OF_CLASS = {c: k for k, c in CLASSES.items()}


MODBUS_SERVER_NAME = "ModbusServer"
MODBUS_PORT = 502
# the editor's bufferMapping record (open-plc.ts ModbusSlaveBufferMappingSchema) -> the
# plugin's count it becomes in conf/modbus_slave.json (generate-modbus-slave-config.ts)
BUFFER_MAPPING_FIELDS = (("holdingRegisters", "qwCount", "qw_count"),
                         ("holdingRegisters", "mwCount", "mw_count"),
                         ("holdingRegisters", "mdCount", "md_count"),
                         ("holdingRegisters", "mlCount", "ml_count"),
                         ("coils", "qxBits", "qx_bits"), ("coils", "mxBits", "mx_bits"),
                         ("discreteInputs", "ixBits", "ix_bits"),
                         ("inputRegisters", "iwCount", "iw_count"))


class V4ExportError(ValueError):
    """The program holds something the OpenPLC v4 editor cannot represent."""


def project_dir(name: str) -> Path:
    """The folder of the v4 project of an export ``name``, relative to the output folder."""
    return V4_DIR / name


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _init_text(init: A.Init) -> str:
    """ST text of an initialiser, on one line."""
    if isinstance(init, A.ArrayInit):
        items = [(f"{expr_text(count)}({_init_text(item)})" if count is not None
                  else _init_text(item)) for count, item in init.items]
        return "[" + ", ".join(items) + "]"
    if isinstance(init, A.StructInit):
        return "(" + ", ".join(f"{m} := {_init_text(v)}" for m, v in init.fields) + ")"
    return _one_line(expr_text(init))


@dataclass
class _Builder:
    prog: CheckedProgram
    sources: Sequence[Source]
    texts: dict[str, SourceText] = field(init=False)
    # names of data types generated for inline multi-dimensional arrays, with their records
    hoisted: list[dict[str, Any]] = field(default_factory=list)
    taken: set[str] = field(init=False)

    def __post_init__(self) -> None:
        self.texts = {s.unit.pos.file: SourceText(s.text) for s in self.sources}
        self.taken = set(self.prog.types) | set(self.prog.pous)

    # ------------------------------------------------------------------ types
    def _where(self, node: A.Node) -> str:
        src = next((s.name for s in self.sources if s.unit.pos.file == node.pos.file),
                   node.pos.file)
        return f"{src}:{node.pos.line}"

    @staticmethod
    def elementary(name: str) -> str | None:
        """The editor's spelling of an elementary type, None for any other name."""
        base = _BASE_ALIASES.get(name.upper(), name.lower())
        return base if base in BASE_TYPES else None

    def spelled(self, name: str) -> str:
        """A type name as the declarations write it: elementary types in upper case, data
        types and function blocks as declared."""
        if self.elementary(name) is not None:
            return name.upper()
        t = self.prog.types.get(name.upper())
        pou = self.prog.pous.get(name.upper())
        return t.name if t is not None else pou.name if pou is not None else name

    def leaf(self, name: str) -> dict[str, str]:
        """An array element or base type: elementary or a user data type."""
        base = self.elementary(name)
        if base is not None:
            return {"definition": "base-type", "value": base}
        return {"definition": "user-data-type", "value": self.spelled(name)}

    def dimensions(self, tref: A.ArrayTypeRef) -> list[dict[str, str]]:
        return [{"dimension": f"{expr_text(lo)}..{expr_text(hi)}"} for lo, hi in tref.ranges]

    def array_text(self, tref: A.ArrayTypeRef) -> str:
        element = self.element_name(tref)
        return f"ARRAY[{', '.join(d['dimension'] for d in self.dimensions(tref))}] OF {element}"

    def element_name(self, tref: A.ArrayTypeRef) -> str:
        if not isinstance(tref.element, A.NamedTypeRef):
            raise V4ExportError(
                f"{self._where(tref)}: an array of an anonymous type has no form in the "
                "OpenPLC v4 editor: declare the element type as a named TYPE")
        return self.spelled(tref.element.name)

    def type_record(self, tref: A.TypeRef) -> dict[str, Any]:
        """The editor's record of a variable's or field's type."""
        if isinstance(tref, A.NamedTypeRef):
            if self.elementary(tref.name) is not None:
                return self.leaf(tref.name)
            # a function block instance is "derived", a data type "user-data-type"
            kind = "derived" if tref.name.upper() in self.prog.pous else "user-data-type"
            return {"definition": kind, "value": self.spelled(tref.name)}
        if isinstance(tref, A.ArrayTypeRef):
            return {"definition": "array", "value": self.array_text(tref),
                    "data": {"baseType": self.leaf(self.element_name(tref)),
                             "dimensions": self.dimensions(tref)}}
        raise V4ExportError(f"{self._where(tref)}: the OpenPLC v4 editor has no inline "
                            f"{type(tref).__name__}: declare it as a named TYPE")

    def data_type(self, td: A.TypeDecl) -> dict[str, Any]:
        d = td.definition
        if isinstance(d, A.StructTypeRef):
            fields = []
            for f in d.fields:
                rec: dict[str, Any] = {"name": f.name, "type": self.type_record(f.type)}
                if f.init is not None:
                    rec["initialValue"] = {"simpleValue": {"value": _init_text(f.init)}}
                fields.append(rec)
            return {"name": td.name, "derivation": "structure", "variable": fields}
        if isinstance(d, A.ArrayTypeRef):
            rec = {"name": td.name, "derivation": "array",
                   "baseType": self.leaf(self.element_name(d))}
            if td.init is not None:
                rec["initialValue"] = _init_text(td.init)
            rec["dimensions"] = self.dimensions(d)
            return rec
        if isinstance(d, A.EnumTypeRef):
            if any(v.value is not None for v in d.values):
                raise V4ExportError(
                    f"{self._where(td)}: enumeration {td.name} gives its values numbers; the "
                    "OpenPLC v4 editor keeps only the names: drop the numbers")
            rec = {"name": td.name, "derivation": "enumerated"}
            if td.init is not None:
                rec["initialValue"] = _init_text(td.init)
            rec["values"] = [{"description": v.name} for v in d.values]
            return rec
        what = "subrange" if isinstance(d, A.SubrangeTypeRef) else "alias of another type"
        raise V4ExportError(
            f"{self._where(td)}: type {td.name} is a {what}; the OpenPLC v4 editor has data "
            "types of three kinds only (structure, array, enumeration): use the base type")

    def inline_ok(self, tref: A.ArrayTypeRef) -> bool:
        """Whether the editor's loader reads this array type inline: one dimension whose
        bounds are words and digits (its type pattern has no comma in 4.1, no minus sign)."""
        return len(tref.ranges) == 1 and all(
            re.fullmatch(r"[\w.]+", d["dimension"]) for d in self.dimensions(tref))

    def declared_type(self, owner: str, decl: A.VarDecl) -> str:
        """The type text of a declaration line; an inline array the editor's loader cannot
        read (several dimensions, a negative bound) becomes a generated named type."""
        t = decl.type
        if isinstance(t, A.NamedTypeRef):
            return self.spelled(t.name)
        if isinstance(t, A.ArrayTypeRef):
            if self.inline_ok(t):
                return self.array_text(t)
            name = f"{owner}_{decl.name}"
            while name.upper() in self.taken:
                name += "_T"
            self.taken.add(name.upper())
            self.hoisted.append({"name": name, "derivation": "array",
                                 "baseType": self.leaf(self.element_name(t)),
                                 "dimensions": self.dimensions(t)})
            return name
        raise V4ExportError(f"{self._where(decl)}: {owner}.{decl.name}: the OpenPLC v4 editor "
                            f"has no inline {type(t).__name__}: declare it as a named TYPE")

    # ------------------------------------------------------------------ variables
    def doc(self, decl: A.VarDecl) -> str:
        text = self.texts[decl.pos.file].trailing_comment(decl.pos)
        return _one_line(text) if text else ""

    def line(self, owner: str, decl: A.VarDecl) -> str:
        text = f"\t{decl.name} : {self.declared_type(owner, decl)}"
        if decl.address:
            text += f" AT {decl.address}"
        if decl.init is not None:
            text += f" := {_init_text(decl.init)}"
        text += ";"
        doc = self.doc(decl)
        return text + (f" (* {doc} *)" if doc else "")

    def variables_text(self, owner: str, blocks: Sequence[A.VarBlock]) -> str:
        """The VAR blocks as the editor's serializer writes them (generate-iec-variables-
        to-string): grouped by class in its order, one tab-indented declaration a line."""
        grouped: dict[str, list[A.VarDecl]] = {}
        for block in blocks:
            grouped.setdefault(CLASSES[block.kind], []).extend(block.decls)
        out = []
        for cls in CLASS_ORDER:
            if grouped.get(cls):
                lines = [self.line(owner, d) for d in grouped[cls]]
                out.append(BLOCK_OF_CLASS[cls] + "\n" + "\n".join(lines) + "\nEND_VAR")
        return "\n\n".join(out)

    def global_record(self, decl: A.VarDecl) -> dict[str, Any]:
        """A configuration global as project.json keeps it (a record, so any array type
        stays inline)."""
        rec: dict[str, Any] = {"name": decl.name, "type": self.type_record(decl.type),
                               "location": decl.address or ""}
        if decl.init is not None:
            rec["initialValue"] = _init_text(decl.init)
        rec["documentation"] = self.doc(decl)
        return rec

    # ------------------------------------------------------------------ POUs
    def pou_file(self, pou: A.Pou) -> str:
        """A POU's file, as the editor's pou-text-serializer writes an ST POU."""
        text = self.texts[pou.pos.file]
        if not any(b.decls for b in pou.blocks):
            raise V4ExportError(
                f"{self._where(pou)}: {pou.name} declares no variables; the OpenPLC v4 "
                "editor's code generator refuses a POU without any")
        body = textwrap.dedent(text.pou_body(pou)).strip("\n")
        end_kw = "END_" + pou.kind.upper()
        clash = re.search(rf"\b(END_VAR|{end_kw})\b", body, re.IGNORECASE)
        if clash:
            raise V4ExportError(
                f"{self._where(pou)}: the body of {pou.name} contains the word "
                f"{clash.group(1)} (a comment?), where the OpenPLC v4 editor's loader would "
                "cut the POU: reword it")
        doc = text.leading_comment(pou.pos) or ""
        out = f"(* {doc.strip()} *)\n\n" if doc.strip() else ""
        header = f"{pou.kind.upper()} {pou.name}"
        if pou.return_type is not None:
            if not isinstance(pou.return_type, A.NamedTypeRef):
                raise V4ExportError(f"{self._where(pou)}: the return type of {pou.name} must be "
                                    "a named type for the OpenPLC v4 editor")
            header += f" : {self.spelled(pou.return_type.name)}"
        out += header + "\n" + self.variables_text(pou.name, pou.blocks) + "\n\n"
        return out + body + "\n\n" + end_kw

    # ------------------------------------------------------------------ configuration
    def configuration(self) -> dict[str, Any]:
        tasks: list[dict[str, Any]] = []
        instances: list[dict[str, str]] = []
        globals_: list[dict[str, Any]] = []
        configs = [c for s in self.sources for c in s.unit.configs]
        if len(configs) > 1 or any(len(c.resources) > 1 for c in configs):
            raise V4ExportError("the OpenPLC v4 editor holds one configuration with one "
                                "resource; the program declares more: merge them")
        for cfg in configs:
            blocks = [*cfg.globals, *(b for r in cfg.resources for b in r.globals)]
            globals_ += [self.global_record(d) for b in blocks for d in b.decls]
            for res in cfg.resources:
                for task in res.tasks:
                    prio = task.params.get("PRIORITY")
                    rec: dict[str, Any] = {"name": task.name}
                    if "INTERVAL" in task.params:
                        rec |= {"triggering": "Cyclic",
                                "interval": expr_text(task.params["INTERVAL"])}
                    else:
                        rec |= {"triggering": "Interrupt",
                                "interval": expr_text(task.params["SINGLE"])
                                if "SINGLE" in task.params else ""}
                    rec["priority"] = int(expr_text(prio)) if prio is not None else 0
                    tasks.append(rec)
                for inst in res.programs:
                    task_name = next((t.name for t in res.tasks if inst.task is not None
                                      and t.name.upper() == inst.task.upper()), "")
                    pou = self.prog.pous.get(inst.type_name.upper())
                    instances.append({"name": inst.name, "task": task_name,
                                      "program": pou.name if pou else inst.type_name})
        return {"resource": {"tasks": tasks, "instances": instances,
                             "globalVariables": globals_}}


def build_project(prog: CheckedProgram, sources: Sequence[Source], *,
                  name: str) -> dict[Path, bytes]:
    """The files of the v4 project folder ``openplc-v4/<name>/``, keyed by their path
    relative to the output folder. Raises V4ExportError for what v4 cannot represent."""
    b = _Builder(prog, sources)
    root = project_dir(name)
    files: dict[Path, bytes] = {}
    for src in sources:
        for pou in src.unit.pous:
            path = root / "pous" / POU_FOLDERS[pou.kind.upper()] / f"{pou.name}.st"
            files[path] = b.pou_file(pou).encode("utf-8")
    configuration = b.configuration()  # before the data types: it may add hoisted ones
    data_types = [b.data_type(td) for src in sources for td in src.unit.types] + b.hoisted
    taken = {n.upper() for n in (*b.taken, *(t["name"] for t in data_types))}
    if MODBUS_SERVER_NAME.upper() in taken:
        raise V4ExportError(f"the program declares {MODBUS_SERVER_NAME}, the name of the "
                            "Modbus server the v4 project carries: rename it")
    project = {"meta": {"name": name, "type": "plc-project"},
               "data": {"dataTypes": data_types, "pous": [], "configuration": configuration,
                        "servers": [modbus_server(located_addresses(sources))]}}
    # JSON.stringify(project, null, 2), as the editor writes it, plus a final newline
    text = json.dumps(project, indent=2, ensure_ascii=False) + "\n"
    return {root / "project.json": text.encode("utf-8"), **dict(sorted(files.items()))}


def located_addresses(sources: Sequence[Source]) -> list[str]:
    """Every direct address the program's declarations give (POUs and configuration)."""
    blocks: list[A.VarBlock] = []
    for src in sources:
        blocks += [b for pou in src.unit.pous for b in pou.blocks]
        blocks += src.unit.stray_globals
        for cfg in src.unit.configs:
            blocks += [*cfg.globals, *(b for r in cfg.resources for b in r.globals)]
    return [d.address for b in blocks for d in b.decls if d.address]


def buffer_counts(addresses: Sequence[str]) -> dict[str, int]:
    """The Modbus plugin's segment counts for a program: v3's map (the defaults of the
    editor's screen and of the plugin), each segment grown to reach the program's highest
    address in it. The holding segments lie head to tail, so keeping %QW and %MW at 1024 (or
    more) is what keeps %MW, %MD and %ML at v3's registers."""
    floor = image_floor(addresses)
    counts = dict(DEFAULT_COUNTS)
    for key in counts:
        need = floor.get(SEGMENT_TABLES[key], 0) * (8 if key.endswith("_bits") else 1)
        counts[key] = max(counts[key], need)
    return counts


def modbus_server(addresses: Sequence[str]) -> dict[str, Any]:
    """The editor's record of an enabled Modbus TCP server on every interface, port 502,
    with :func:`buffer_counts` of the program as its buffer mapping."""
    counts = buffer_counts(addresses)
    mapping: dict[str, dict[str, int]] = {}
    for group, field_name, key in BUFFER_MAPPING_FIELDS:
        mapping.setdefault(group, {})[field_name] = counts[key]
    return {"name": MODBUS_SERVER_NAME, "protocol": "modbus-tcp",
            "modbusSlaveConfig": {"enabled": True, "networkInterface": "0.0.0.0",
                                  "port": MODBUS_PORT, "bufferMapping": mapping}}
