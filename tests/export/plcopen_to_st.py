"""PLCopen TC6 XML -> ST text, for the round-trip tests.

Rebuilds a compilable ST file from nothing but the XML (data types, POU interfaces, ST bodies,
configuration), so a test can show that the XML carries the complete program. It reads only
what the exporter writes (ST bodies; no graphical languages).
"""

from __future__ import annotations

from lxml import etree

NS = "http://www.plcopen.org/xml/tc6_0201"
XHTML = "http://www.w3.org/1999/xhtml"
N = {"p": NS, "x": XHTML}

VAR_KEYWORDS = {
    "localVars": "VAR", "tempVars": "VAR_TEMP", "inputVars": "VAR_INPUT",
    "outputVars": "VAR_OUTPUT", "inOutVars": "VAR_IN_OUT", "externalVars": "VAR_EXTERNAL",
    "globalVars": "VAR_GLOBAL",
}
POU_KEYWORDS = {"function": "FUNCTION", "functionBlock": "FUNCTION_BLOCK", "program": "PROGRAM"}


def local(el: etree._Element) -> str:
    return etree.QName(el).localname


def type_text(container: etree._Element, indent: str = "  ") -> str:
    """ST text of the ppx:dataType inside container (<type>, <baseType>, <returnType>)."""
    (el,) = list(container)
    tag = local(el)
    if tag == "derived":
        return str(el.get("name"))
    if tag == "array":
        dims = ", ".join(f"{d.get('lower')}..{d.get('upper')}"
                         for d in el.findall("p:dimension", N))
        return f"ARRAY[{dims}] OF {type_text(el.find('p:baseType', N))}"
    if tag == "struct":
        fields = "".join(f"{indent}  {var_text(v)}\n" for v in el.findall("p:variable", N))
        return f"STRUCT\n{fields}{indent}END_STRUCT"
    if tag == "enum":
        vals = [(v.get("name") + (f" := {v.get('value')}" if v.get("value") else ""))
                for v in el.findall("p:values/p:value", N)]
        return "(" + ", ".join(vals) + ")"
    if tag in ("subrangeSigned", "subrangeUnsigned"):
        rng = el.find("p:range", N)
        return f"{type_text(el.find('p:baseType', N))} ({rng.get('lower')}..{rng.get('upper')})"
    if tag in ("string", "wstring"):
        return tag.upper()
    return tag  # elementary: <REAL/>, <DINT/>, ...


def value_text(container: etree._Element) -> str:
    """ST text of the ppx:value inside container (<initialValue> or a nested <value>)."""
    (el,) = [c for c in container if local(c) in ("simpleValue", "arrayValue", "structValue")]
    tag = local(el)
    if tag == "simpleValue":
        return str(el.get("value"))
    if tag == "arrayValue":
        items = []
        for v in el.findall("p:value", N):
            rep = v.get("repetitionValue")
            items.append(f"{rep}({value_text(v)})" if rep is not None else value_text(v))
        return "[" + ", ".join(items) + "]"
    return "(" + ", ".join(f"{v.get('member')} := {value_text(v)}"
                           for v in el.findall("p:value", N)) + ")"


def var_text(v: etree._Element) -> str:
    addr = f" AT {v.get('address')}" if v.get("address") else ""
    init = v.find("p:initialValue", N)
    tail = f" := {value_text(init)}" if init is not None else ""
    return f"{v.get('name')}{addr} : {type_text(v.find('p:type', N), '    ')}{tail};"


def var_block_text(lst: etree._Element, indent: str = "  ") -> str:
    kw = VAR_KEYWORDS[local(lst)] + (" CONSTANT" if lst.get("constant") == "true" else "")
    body = "".join(f"{indent}  {var_text(v)}\n" for v in lst.findall("p:variable", N))
    return f"{indent}{kw}\n{body}{indent}END_VAR\n"


def st_of(formatted: etree._Element) -> str:
    return str(formatted.find("x:p", N).text)


def xml_to_st(data: bytes) -> str:
    root = etree.fromstring(data)
    out: list[str] = []
    dts = root.findall("p:types/p:dataTypes/p:dataType", N)
    if dts:
        out.append("TYPE")
        for dt in dts:
            init = dt.find("p:initialValue", N)
            tail = f" := {value_text(init)}" if init is not None else ""
            out.append(f"  {dt.get('name')} : {type_text(dt.find('p:baseType', N))}{tail};")
        out.append("END_TYPE\n")
    for pou in root.findall("p:types/p:pous/p:pou", N):
        kw = POU_KEYWORDS[str(pou.get("pouType"))]
        iface = pou.find("p:interface", N)
        ret = iface.find("p:returnType", N) if iface is not None else None
        head = f"{kw} {pou.get('name')}" + (f" : {type_text(ret)}" if ret is not None else "")
        out.append(head)
        for lst in (iface if iface is not None else []):
            if local(lst) in VAR_KEYWORDS:
                out.append(var_block_text(lst).rstrip("\n"))
        out.append(st_of(pou.find("p:body/p:ST", N)))
        out.append(f"END_{kw}\n")
    for cfg in root.findall("p:instances/p:configurations/p:configuration", N):
        out.append(f"CONFIGURATION {cfg.get('name')}")
        for lst in cfg.findall("p:globalVars", N):
            out.append(var_block_text(lst).rstrip("\n"))
        for res in cfg.findall("p:resource", N):
            out.append(f"  RESOURCE {res.get('name')} ON PLC")
            for lst in res.findall("p:globalVars", N):
                out.append(var_block_text(lst, "    ").rstrip("\n"))
            progs = []
            for task in res.findall("p:task", N):
                params = [f"{k.upper()} := {task.get(k)}" for k in ("single", "interval")
                          if task.get(k) is not None]
                params.append(f"PRIORITY := {task.get('priority')}")
                out.append(f"    TASK {task.get('name')}({', '.join(params)});")
                progs += [f"    PROGRAM {i.get('name')} WITH {task.get('name')} : "
                          f"{i.get('typeName')};" for i in task.findall("p:pouInstance", N)]
            progs += [f"    PROGRAM {i.get('name')} : {i.get('typeName')};"
                      for i in res.findall("p:pouInstance", N)]
            out += progs
            out.append("  END_RESOURCE")
        out.append("END_CONFIGURATION\n")
    return "\n".join(out)
