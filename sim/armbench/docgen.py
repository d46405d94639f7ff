"""Block reference pages (Markdown) generated from the header comments of st/*.st.

Each FUNCTION / FUNCTION_BLOCK gets ``docs/reference/<Name>.md`` with its header comment and
its interface table (inputs, in-outs, outputs, with the declarations' trailing comments); each
ST file gets a ``types-<File>.md`` page with its file header and TYPE declarations; an
``index.md`` lists them all. The pages are derived data: edit the ST headers, then run

    python -m armbench.docgen            # (re)write docs/reference/
    python -m armbench.docgen --check    # exit 1 when the pages are stale

This is a light line-based reader for the library's own house style (one declaration per
line, ``(* ... *)`` comments), not a general ST parser.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .locate import LocateError, find_checkout

# Inside the checkout the pages are generated for (armbench.locate.find_checkout).
ST_DIR = Path("st")
OUT_DIR = Path("docs") / "reference"

_POU_RE = re.compile(r"^(FUNCTION_BLOCK|FUNCTION)\s+(\w+)(?:\s*:\s*(\w+))?", re.IGNORECASE)
_END_POU_RE = re.compile(r"^END_(FUNCTION_BLOCK|FUNCTION)\b", re.IGNORECASE)
_SECTION_RE = re.compile(r"^(VAR_INPUT|VAR_OUTPUT|VAR_IN_OUT)\b", re.IGNORECASE)
_DECL_RE = re.compile(
    r"^(\w+)\s*:\s*([^;:=]+?)\s*(?::=\s*([^;]+?))?\s*;\s*(?:\(\*\s*(.*?)\s*\*\))?\s*$"
)
_TYPE_HEAD_RE = re.compile(r"^(\w+)\s*:\s*(STRUCT\b|[^;]+;)", re.IGNORECASE)
_RULE_RE = re.compile(r"^\s*[-=]{10,}\s*$")

SECTION_TITLES = {
    "VAR_INPUT": "Inputs",
    "VAR_IN_OUT": "In-outs (VAR_IN_OUT)",
    "VAR_OUTPUT": "Outputs",
}


@dataclass
class Decl:
    """One declared variable or struct field."""

    name: str
    type_name: str
    init: str
    comment: str


@dataclass
class Pou:
    """A FUNCTION or FUNCTION_BLOCK with its header comment and interface."""

    kind: str
    name: str
    result: str
    header: str
    source: str
    sections: dict[str, list[Decl]] = field(default_factory=dict)


@dataclass
class TypeDecl:
    """A data type from a TYPE block: a STRUCT with fields, or a one-line declaration."""

    name: str
    definition: str
    comment: str
    fields: list[Decl] = field(default_factory=list)


@dataclass
class StFile:
    """What the generator read from one ST file."""

    path: Path
    header: str
    pous: list[Pou]
    types: list[TypeDecl]


def _clean_comment(text: str) -> str:
    """The inside of a ``(* ... *)`` block without ruler lines and common indentation."""
    lines = [ln for ln in text.splitlines() if not _RULE_RE.match(ln)]
    while lines and not lines[0].strip():
        lines.pop(0)
    while lines and not lines[-1].strip():
        lines.pop()
    indents = [len(ln) - len(ln.lstrip()) for ln in lines[1:] if ln.strip()]
    cut = min(indents) if indents else 0
    out = [lines[0].strip()] if lines else []
    out += [ln[cut:].rstrip() for ln in lines[1:]]
    return "\n".join(out).strip()


def _comment_before(text: str, pos: int) -> str:
    """The ``(* *)`` comment that ends right before ``pos`` (only whitespace between)."""
    before = text[:pos].rstrip()
    if not before.endswith("*)"):
        return ""
    start = before.rfind("(*")
    return _clean_comment(before[start + 2 : -2]) if start >= 0 else ""


def _parse_decl(line: str) -> Decl | None:
    match = _DECL_RE.match(line.strip())
    if match is None:
        return None
    name, type_name, init, comment = match.groups()
    return Decl(name, type_name.strip(), (init or "").strip(), (comment or "").strip())


def read_st(path: Path) -> StFile:
    """Read the header comment, POUs and TYPE declarations of one ST file."""
    text = path.read_text(encoding="utf-8")
    first = re.match(r"\s*\(\*(.*?)\*\)", text, re.DOTALL)
    header = _clean_comment(first.group(1)) if first else ""
    pous: list[Pou] = []
    types: list[TypeDecl] = []
    lines = text.splitlines(keepends=True)
    offsets = [0]
    for ln in lines:
        offsets.append(offsets[-1] + len(ln))
    index = 0
    in_type = False
    current_struct: TypeDecl | None = None
    while index < len(lines):
        stripped = lines[index].strip()
        upper = stripped.upper()
        if upper.startswith("TYPE") and not in_type and _POU_RE.match(stripped) is None:
            in_type = upper == "TYPE" or upper.startswith("TYPE ")
        elif in_type and upper.startswith("END_TYPE"):
            in_type = False
        elif in_type and current_struct is not None:
            if upper.startswith("END_STRUCT"):
                current_struct = None
            else:
                decl = _parse_decl(stripped)
                if decl is not None:
                    current_struct.fields.append(decl)
        elif in_type:
            match = _TYPE_HEAD_RE.match(stripped)
            if match is not None:
                pos = offsets[index] + len(lines[index]) - len(lines[index].lstrip())
                definition = match.group(2).rstrip(";").strip()
                tdecl = TypeDecl(match.group(1), definition, _comment_before(text, pos))
                types.append(tdecl)
                if definition.upper() == "STRUCT":
                    current_struct = tdecl
        else:
            match = _POU_RE.match(stripped)
            if match is not None:
                index = _read_pou(text, lines, offsets, index, match, pous)
        index += 1
    return StFile(path, header, pous, types)


def _read_pou(
    text: str,
    lines: list[str],
    offsets: list[int],
    index: int,
    match: re.Match[str],
    pous: list[Pou],
) -> int:
    """Read one POU starting at ``lines[index]``; returns the index of its END line."""
    kind, name, result = match.group(1).upper(), match.group(2), match.group(3) or ""
    pou = Pou(kind, name, result, _comment_before(text, offsets[index]), "")
    section: str | None = None
    start = index
    while index < len(lines):
        stripped = lines[index].strip()
        if _END_POU_RE.match(stripped):
            break
        sec = _SECTION_RE.match(stripped)
        if sec is not None:
            section = sec.group(1).upper()
            pou.sections.setdefault(section, [])
        elif stripped.upper().startswith("END_VAR"):
            section = None
        elif section is not None:
            decl = _parse_decl(stripped)
            if decl is not None:
                pou.sections[section].append(decl)
        index += 1
    pou.source = f"{lines[start].strip()} (line {start + 1})"
    pous.append(pou)
    return index


def _decl_table(decls: Sequence[Decl], with_init: bool = True) -> list[str]:
    head = "| Name | Type | Default | Notes |" if with_init else "| Name | Type | Notes |"
    rule = "|---|---|---|---|" if with_init else "|---|---|---|"
    out = [head, rule]
    for d in decls:
        note = d.comment.replace("|", "\\|")
        if with_init:
            init = f"`{d.init}`" if d.init else ""
            out.append(f"| `{d.name}` | `{d.type_name}` | {init} | {note} |")
        else:
            out.append(f"| `{d.name}` | `{d.type_name}` | {note} |")
    return out


def render_pou(pou: Pou, st: StFile) -> str:
    """Markdown page of one POU."""
    kind = "Function block" if pou.kind == "FUNCTION_BLOCK" else "Function"
    out = [f"# {pou.name}", ""]
    out.append(
        f"{kind} in `st/{st.path.name}`" + (f", returns `{pou.result}`." if pou.result else ".")
    )
    out += ["", "<!-- generated by sim/armbench/docgen.py from the ST header: do not edit -->", ""]
    out += ["```text", pou.header or "(no header comment)", "```", ""]
    for key in ("VAR_INPUT", "VAR_IN_OUT", "VAR_OUTPUT"):
        decls = pou.sections.get(key)
        if decls:
            out += [f"## {SECTION_TITLES[key]}", "", *_decl_table(decls), ""]
    if pou.result:
        out += ["## Result", "", f"`{pou.result}` (see the header above).", ""]
    return "\n".join(out).rstrip() + "\n"


def render_types(st: StFile) -> str:
    """Markdown page of one ST file's header and data types."""
    out = [f"# st/{st.path.name}", ""]
    out += ["<!-- generated by sim/armbench/docgen.py from the ST header: do not edit -->", ""]
    out += ["```text", st.header or "(no file header)", "```", ""]
    if st.types:
        out += ["## Data types", ""]
    for t in st.types:
        out += [f"### {t.name}", ""]
        if t.comment:
            out += [t.comment.replace("\n", " "), ""]
        if t.fields:
            out += ["`STRUCT`", "", *_decl_table(t.fields), ""]
        else:
            out += [f"`{t.definition}`", ""]
    if st.pous:
        out += ["## Blocks", ""]
        out += [f"- [{p.name}]({p.name}.md)" for p in st.pous]
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _summary(pou: Pou) -> str:
    """The header's first sentence, without the leading ``Name --``."""
    words: list[str] = []
    for line in pou.header.splitlines():
        if not line.strip():
            break
        words.append(line.strip())
        if line.rstrip().endswith("."):
            break
    text = " ".join(words)
    prefix = f"{pou.name} -- "
    return text[len(prefix) :] if text.startswith(prefix) else text


def render_all(st_paths: Sequence[Path]) -> dict[str, str]:
    """File name -> page text for every page of the reference."""
    pages: dict[str, str] = {}
    index = ["# Block reference", ""]
    index += ["<!-- generated by sim/armbench/docgen.py from the ST header: do not edit -->", ""]
    index += ["One page per block, generated from the header comments in `st/*.st`.", ""]
    for path in st_paths:
        st = read_st(path)
        types_page = f"types-{path.stem}.md"
        pages[types_page] = render_types(st)
        index += [f"## st/{path.name}", "", f"- [file header and data types]({types_page})"]
        for pou in st.pous:
            pages[f"{pou.name}.md"] = render_pou(pou, st)
            kind = "FB" if pou.kind == "FUNCTION_BLOCK" else "FUNCTION"
            summary = _summary(pou)
            index.append(f"- [{pou.name}]({pou.name}.md) ({kind}): {summary}")
        index.append("")
    pages["index.md"] = "\n".join(index).rstrip() + "\n"
    return pages


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--repo", type=Path, default=None,
                        help="the checkout (default: found from the current directory)")
    parser.add_argument("--st-dir", type=Path, default=None, help="default: st/ of the checkout")
    parser.add_argument("--out", type=Path, default=None,
                        help="default: docs/reference/ of the checkout")
    parser.add_argument("--check", action="store_true", help="fail when pages are stale")
    args = parser.parse_args(argv)
    if args.st_dir is None or args.out is None:
        try:
            root = find_checkout(args.repo).root
        except LocateError as exc:
            parser.error(str(exc))
        args.st_dir = args.st_dir or root / ST_DIR
        args.out = args.out or root / OUT_DIR
    pages = render_all(sorted(args.st_dir.glob("*.st")))
    stale = [
        name
        for name, text in pages.items()
        if not (args.out / name).is_file() or (args.out / name).read_text(encoding="utf-8") != text
    ]
    if args.check:
        for name in stale:
            print(f"stale: {args.out / name}", file=sys.stderr)
        return 1 if stale else 0
    args.out.mkdir(parents=True, exist_ok=True)
    for name in stale:
        (args.out / name).write_text(pages[name], encoding="utf-8")
    print(f"{len(pages)} pages in {args.out} ({len(stale)} written)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
