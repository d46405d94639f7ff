"""PLCopen TC6 XML v2.01 (CODESYS, OpenPLC Editor / Beremiz) from the checked program.

Needs: a CheckedProgram (``driver.analyse``) without errors and the export Sources in their
dependency-safe order. Declarations come from the AST (one ``<localVars>`` etc. per VAR block,
in source order, ``constant="true"`` for VAR CONSTANT, ``address`` for located variables),
type names are resolved through the program's type table (declared spelling), initial values
are the initialisers' ST text. POU bodies are the source text between the last END_VAR and
END_<kind>, unchanged, in ``<ST><xhtml:p><![CDATA[...]]></xhtml:p></ST>``; the header comment
before a POU and a declaration's trailing comment become ``<documentation>``.

The output is deterministic (fixed header date, stable element order), so a test can compare
the committed file with a fresh export.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from lxml import etree

from ..compiler import ast as A
from ..compiler.source import SourcePos
from ..compiler.symbols import CheckedProgram
from ..compiler.types import ELEMENTARY
from .sources import Source
from .sttext import SourceText, expr_text

NS = "http://www.plcopen.org/xml/tc6_0201"
XHTML = "http://www.w3.org/1999/xhtml"
# A fixed stamp: the schema requires a creation date, a real one would make every export
# differ from the committed file.
FIXED_DATETIME = "2000-01-01T00:00:00"

_Element = Any  # lxml ships no type information

POU_TYPES = {"FUNCTION": "function", "FUNCTION_BLOCK": "functionBlock", "PROGRAM": "program"}
VAR_LISTS = {
    A.VAR: "localVars", A.VAR_TEMP: "tempVars", A.VAR_INPUT: "inputVars",
    A.VAR_OUTPUT: "outputVars", A.VAR_IN_OUT: "inOutVars", A.VAR_EXTERNAL: "externalVars",
    A.VAR_GLOBAL: "globalVars",
}
_ELEMENTARY_TAGS = set(ELEMENTARY) | {"DATE", "DT", "TOD"}
_TYPE_ALIASES = {"DATE_AND_TIME": "DT", "TIME_OF_DAY": "TOD", "STRING": "string",
                 "WSTRING": "wstring"}
_UNSIGNED = {"USINT", "UINT", "UDINT", "ULINT", "BYTE", "WORD", "DWORD", "LWORD"}


def _sub(parent: _Element, tag: str, **attrs: str) -> _Element:
    return etree.SubElement(parent, f"{{{NS}}}{tag}", attrs)


def _text_block(parent: _Element, tag: str, text: str) -> None:
    """<tag><xhtml:p><![CDATA[text]]></xhtml:p></tag> (escaped text if it holds ']]>')."""
    p = etree.SubElement(_sub(parent, tag), f"{{{XHTML}}}p")
    p.text = etree.CDATA(text) if "]]>" not in text else text


class _Builder:
    def __init__(self, prog: CheckedProgram, sources: Sequence[Source],
                 addresses: Mapping[int, str] | None = None) -> None:
        self.prog = prog
        self.sources = sources
        # id(VarDecl) -> the address written instead of the source's (the CODESYS variant)
        self.addresses = dict(addresses or {})
        self.texts = {s.unit.pos.file: SourceText(s.text) for s in sources}

    # ---------------------------------------------------------------- types and values
    def type_name(self, name: str) -> str:
        t = self.prog.types.get(name.upper())
        return t.name if t is not None else name

    def data_type(self, parent: _Element, tref: A.TypeRef) -> None:
        """The ppx:dataType choice for a type reference, inside parent."""
        if isinstance(tref, A.NamedTypeRef):
            up = tref.name.upper()
            if up in _TYPE_ALIASES:
                _sub(parent, _TYPE_ALIASES[up])
            elif up in _ELEMENTARY_TAGS:
                _sub(parent, up)
            else:
                _sub(parent, "derived", name=self.type_name(tref.name))
        elif isinstance(tref, A.ArrayTypeRef):
            arr = _sub(parent, "array")
            for lo, hi in tref.ranges:
                _sub(arr, "dimension", lower=expr_text(lo), upper=expr_text(hi))
            self.data_type(_sub(arr, "baseType"), tref.element)
        elif isinstance(tref, A.StructTypeRef):
            st = _sub(parent, "struct")
            for f in tref.fields:
                self.variable(st, f.name, f.type, f.init, None, f.pos)
        elif isinstance(tref, A.EnumTypeRef):
            values = _sub(_sub(parent, "enum"), "values")
            for v in tref.values:
                attrs = {"name": v.name}
                if v.value is not None:
                    attrs["value"] = expr_text(v.value)
                _sub(values, "value", **attrs)
        elif isinstance(tref, A.SubrangeTypeRef):
            signed = "subrangeUnsigned" if tref.base.upper() in _UNSIGNED else "subrangeSigned"
            sr = _sub(parent, signed)
            _sub(sr, "range", lower=expr_text(tref.low), upper=expr_text(tref.high))
            self.data_type(_sub(sr, "baseType"), A.NamedTypeRef(tref.pos, tref.base))
        else:
            raise TypeError(f"{tref.pos}: cannot export {type(tref).__name__}")

    def value(self, parent: _Element, init: A.Init) -> None:
        """The ppx:value choice for an initialiser, inside parent."""
        if isinstance(init, A.ArrayInit):
            arr = _sub(parent, "arrayValue")
            for count, item in init.items:
                v = _sub(arr, "value")
                if count is not None:
                    v.set("repetitionValue", expr_text(count))
                self.value(v, item)
        elif isinstance(init, A.StructInit):
            st = _sub(parent, "structValue")
            for member, item in init.fields:
                self.value(_sub(st, "value", member=member), item)
        else:
            _sub(parent, "simpleValue", value=expr_text(init))

    def variable(self, parent: _Element, name: str, tref: A.TypeRef, init: A.Init | None,
                 address: str | None, pos: SourcePos) -> None:
        attrs = {"name": name}
        if address:
            attrs["address"] = address
        var = _sub(parent, "variable", **attrs)
        self.data_type(_sub(var, "type"), tref)
        if init is not None:
            self.value(_sub(var, "initialValue"), init)
        doc = self.texts[pos.file].trailing_comment(pos)
        if doc:
            _text_block(var, "documentation", doc)

    def var_list(self, parent: _Element, block: A.VarBlock) -> None:
        lst = _sub(parent, VAR_LISTS[block.kind])
        if block.constant:
            lst.set("constant", "true")
        for d in block.decls:
            address = self.addresses.get(id(d), d.address) if d.address else None
            self.variable(lst, d.name, d.type, d.init, address, d.pos)

    # ---------------------------------------------------------------- sections
    def data_types(self, parent: _Element) -> None:
        dts = _sub(parent, "dataTypes")
        for src in self.sources:
            for td in src.unit.types:
                dt = _sub(dts, "dataType", name=td.name)
                self.data_type(_sub(dt, "baseType"), td.definition)
                if td.init is not None:
                    self.value(_sub(dt, "initialValue"), td.init)
                doc = self.texts[td.pos.file].leading_comment(td.pos)
                if doc:
                    _text_block(dt, "documentation", doc)

    def pous(self, parent: _Element) -> None:
        pous = _sub(parent, "pous")
        for src in self.sources:
            text = self.texts[src.unit.pos.file]
            for pou in src.unit.pous:
                el = _sub(pous, "pou", name=pou.name, pouType=POU_TYPES[pou.kind.upper()])
                iface = _sub(el, "interface")
                if pou.return_type is not None:
                    self.data_type(_sub(iface, "returnType"), pou.return_type)
                for block in pou.blocks:
                    self.var_list(iface, block)
                body = _sub(el, "body")
                _text_block(body, "ST", text.pou_body(pou))
                doc = text.leading_comment(pou.pos)
                if doc:
                    _text_block(el, "documentation", doc)

    def instances(self, parent: _Element) -> None:
        configs = _sub(_sub(parent, "instances"), "configurations")
        for src in self.sources:
            for cfg in src.unit.configs:
                c = _sub(configs, "configuration", name=cfg.name)
                for res in cfg.resources:
                    r = _sub(c, "resource", name=res.name)
                    for task in res.tasks:
                        attrs = {"name": task.name}
                        for key, attr in (("SINGLE", "single"), ("INTERVAL", "interval")):
                            if key in task.params:
                                attrs[attr] = expr_text(task.params[key])
                        prio = task.params.get("PRIORITY")
                        attrs["priority"] = expr_text(prio) if prio is not None else "0"
                        t = _sub(r, "task", **attrs)
                        for inst in res.programs:
                            if inst.task is not None and inst.task.upper() == task.name.upper():
                                _sub(t, "pouInstance", name=inst.name,
                                     typeName=self.type_name(inst.type_name))
                    for block in res.globals:
                        self.var_list(r, block)
                    for inst in res.programs:
                        if inst.task is None:
                            _sub(r, "pouInstance", name=inst.name,
                                 typeName=self.type_name(inst.type_name))
                for block in cfg.globals:
                    self.var_list(c, block)


def build_xml(prog: CheckedProgram, sources: Sequence[Source], *, title: str, version: str,
              comment: str, addresses: Mapping[int, str] | None = None) -> bytes:
    """The PLCopen XML document for the sources (UTF-8, with XML declaration);
    ``addresses`` (id of a located VarDecl -> address) relocates variables."""
    b = _Builder(prog, sources, addresses)
    root = etree.Element(f"{{{NS}}}project", nsmap={None: NS, "xhtml": XHTML})
    _sub(root, "fileHeader", companyName="armbench", productName="armbench export",
         productVersion=version, creationDateTime=FIXED_DATETIME,
         contentDescription=comment.split("\n", 1)[0])
    header = _sub(root, "contentHeader", name=title, modificationDateTime=FIXED_DATETIME)
    _sub(header, "Comment").text = comment
    coord = _sub(header, "coordinateInfo")
    for lang in ("fbd", "ld", "sfc"):
        _sub(_sub(coord, lang), "scaling", x="1", y="1")
    types = _sub(root, "types")
    b.data_types(types)
    b.pous(types)
    b.instances(root)
    etree.indent(root, space="  ")
    out: bytes = etree.tostring(root, xml_declaration=False, encoding="UTF-8")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + out + b"\n"
