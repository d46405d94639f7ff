"""MkDocs hooks for the documentation site (``mkdocs.yml`` names this file).

The site must work offline, opened from disk: no script or style sheet from the network. So
formulas are turned into MathML when the site is built (``$...$`` inline, ``$$...$$`` on lines
of their own, the syntax GitHub also renders), which browsers draw without JavaScript, and code
is coloured by Pygments at build time instead of by highlight.js from a CDN.

Two things in docs/ are written for reading on GitHub and in an editor, and are adapted here:

* fence info strings carry test marks (```` ```st fail E0106 ````, see
  tests/docs/test_teaching_docs.py); Python-Markdown wants the language alone, so the marks are
  dropped from the site's copy;
* links to files outside docs/ (the README, a test, a bench script) are not pages of the site.
  They must exist (a missing one fails the build), and they keep their relative target, which
  resolves to the checkout's file when the site is built into ``site/`` beside ``docs/`` (the
  default of ``mkdocs.yml``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from latex2mathml.converter import convert as latex_to_mathml
from markdown import Extension, Markdown
from markdown.inlinepatterns import InlineProcessor

# An inline formula may not start or end with a space nor hold a "$" or a line break, so
# "costs $5 and $6" stays text (the rule of Pandoc and GitHub).
_INLINE = r"(?<![\\$\w])\$(?![\s$])([^$\n]+?)(?<![\s\\])\$(?![\w$])"
_DISPLAY = r"(?<!\\)\$\$(.+?)\$\$"
_FENCE_OPEN = re.compile(r"^(\s*)(```+|~~~+)[ \t]*([A-Za-z0-9_+-]+)[^\n`]*$", re.M)
_LINK = re.compile(r"(!?\[[^\]]*\]\()([^)\s]+)((?:\s+\"[^\"]*\")?\))")
_OUTSIDE = "armbench-outside:"  # marks a link to a file outside docs/ between two hooks


class FormulaError(ValueError):
    """A formula that latex2mathml cannot convert: the page names it so it can be fixed."""


# latex2mathml turns aligned (the environment GitHub and MathJax accept inside $$) into one
# run of text with the '&' as a letter and '\\' as a line break that browsers ignore, but
# align* into a table with right/left columns: the same equations, drawn.
_ALIGNED = re.compile(r"\\(begin|end)\{aligned\}")
# What is left of '&' and '\\' when latex2mathml did not put them into a table cell.
_AS_TEXT = re.compile(r">&<|linebreak=\"newline\"")
# TeX sets a thin space around a function name (\cos p, a \cos p) but not before its
# parenthesis; latex2mathml writes the name as a plain <mi>, which browsers set tight:
# "acosp". The spaces are added where TeX has them.
_FUNCTIONS = "sin|cos|tan|cot|sec|csc|arcsin|arccos|arctan|sinh|cosh|tanh|ln|log|exp"
_THIN = '<mspace width="0.167em" />'
_NAME_AFTER = re.compile(rf"(<mi>(?:{_FUNCTIONS})</mi>)"
                         r"(?!<mo stretchy=\"false\">&#x00028;)(?=<[^/])")
_NAME_BEFORE = re.compile(rf"(</mi>|</mn>|</msub>|</msup>|</msubsup>|</mrow>|</mfrac>)"
                          rf"(<mi>(?:{_FUNCTIONS})</mi>)")


def mathml(tex: str, display: bool) -> str:
    """MathML for one TeX formula; raises FormulaError with the formula on failure, or when
    its '&' or '\\' would be drawn as text (an environment latex2mathml does not lay out)."""
    try:
        out = str(latex_to_mathml(_ALIGNED.sub(r"\\\1{align*}", tex.strip()),
                                  display="block" if display else "inline"))
    except Exception as exc:  # latex2mathml raises several unrelated types
        raise FormulaError(f"cannot render the formula ${tex}$: {exc}") from exc
    if _AS_TEXT.search(out):
        raise FormulaError(f"the formula ${tex}$ would show its '&' or '\\\\' as text: "
                           "put rows in aligned, pmatrix, array or cases")
    out = _NAME_BEFORE.sub(rf"\1{_THIN}\2", out)
    return _NAME_AFTER.sub(rf"\1{_THIN}", out)


class _MathPattern(InlineProcessor):  # type: ignore[misc]
    def __init__(self, pattern: str, md: Markdown, display: bool) -> None:
        super().__init__(pattern, md)
        self.display = display

    def handleMatch(self, m: re.Match[str], data: str) -> tuple[str, int, int]:  # noqa: N802
        out = mathml(m.group(1), self.display)
        if self.display:
            out = f'<div class="formula">{out}</div>'
        return self.md.htmlStash.store(out), m.start(0), m.end(0)


class MathExtension(Extension):  # type: ignore[misc]
    """``$$...$$`` and ``$...$`` as MathML; runs before backslash escapes, after code spans."""

    def extendMarkdown(self, md: Markdown) -> None:  # noqa: N802
        # Priorities: backticks are 190 (code stays code), escapes 180 (TeX keeps its '\').
        md.inlinePatterns.register(_MathPattern(_DISPLAY, md, True), "math_display", 186)
        md.inlinePatterns.register(_MathPattern(_INLINE, md, False), "math_inline", 185)


def strip_fence_marks(markdown: str) -> str:
    """```` ```st fail E0106 ```` -> ```` ```st ````: the test marks are not a language."""
    return _FENCE_OPEN.sub(lambda m: f"{m.group(1)}{m.group(2)}{m.group(3)}", markdown)


def mark_outside_links(markdown: str, page_src: Path, docs_dir: Path) -> str:
    """Links that leave docs/ are checked here and hidden from MkDocs' page-link validation.

    Raises FileNotFoundError naming the page and the link when the target does not exist.
    """
    fences = [(m.start(), m.end()) for m in
              re.finditer(r"^(```+|~~~+).*?^\1\s*$", markdown, re.S | re.M)]

    def in_code(pos: int) -> bool:
        return any(a <= pos < b for a, b in fences)

    def repl(m: re.Match[str]) -> str:
        target = m.group(2)
        if in_code(m.start()) or re.match(r"^[a-z][a-z0-9+.-]*:|^#|^/", target):
            return m.group(0)
        path = target.split("#", 1)[0]
        resolved = (page_src.parent / path).resolve()
        if resolved.is_relative_to(docs_dir.resolve()):
            return m.group(0)  # a page or image of the site: MkDocs checks it
        if not resolved.exists():
            raise FileNotFoundError(
                f"{page_src.relative_to(docs_dir)}: link to {target}, which does not exist")
        return f"{m.group(1)}{_OUTSIDE}{target}{m.group(3)}"

    return _LINK.sub(repl, markdown)


def restore_outside_links(page_html: str) -> str:
    """Puts the relative targets back unchanged: with use_directory_urls off, site/x.html sits
    at the same depth as its Markdown page under docs, so the target reaches the same file of
    the checkout."""
    return page_html.replace(_OUTSIDE, "")


# ----------------------------------------------------------------------------- MkDocs hooks

def on_config(config: Any) -> Any:
    config.markdown_extensions.append(MathExtension())
    return config


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    docs_dir = Path(config.docs_dir)
    text = strip_fence_marks(markdown)
    return mark_outside_links(text, Path(page.file.abs_src_path), docs_dir)


def on_page_content(html_text: str, page: Any, config: Any, files: Any) -> str:
    return restore_outside_links(html_text)


def on_post_build(config: Any) -> None:
    # Code colours: Pygments' classes (from the codehilite extension), styled by a sheet
    # written here so that no style sheet is fetched from a CDN.
    from pygments.formatters import HtmlFormatter

    css = HtmlFormatter(style="default").get_style_defs(".codehilite")
    (Path(config.site_dir) / "css" / "pygments.css").write_text(css + _SITE_CSS, encoding="utf-8")


# The theme styles only tables that carry its own class; Markdown tables carry none. Wide
# formulas and tables scroll instead of overflowing the column. Formulas take an OpenType math
# font installed on the reader's machine if there is one (Chromium's default font draws a
# square root's sign unstretched beside its argument). Chromium's MathML ignores
# columnalign and columnspacing, which latex2mathml writes for aligned equations: the rules
# on mtd line the equations up at their '=' as the attributes ask.
_SITE_CSS = """
table { border-collapse: collapse; margin: 0 0 1em; display: block; overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; vertical-align: top; }
thead th { background: #f2f2f2; }
div.formula { overflow-x: auto; margin: 0.6em 0 1em; }
math { font-size: 1.08em; font-family: "Latin Modern Math", "STIX Two Math",
       "DejaVu Math TeX Gyre", "Cambria Math", math; }
math mtd[columnalign="left"] { text-align: left; }
math mtd[columnalign="right"] { text-align: right; }
math mtable[displaystyle="true"] > mtr > mtd { padding-left: 0; padding-right: 0; }
math mtable[displaystyle="true"] > mtr > mtd[columnalign="left"] + mtd { padding-left: 2em; }
"""
