"""The documentation site: built from docs/ by MkDocs in strict mode, and read in Chromium.

The build fails on a broken link, a missing figure, a link out of docs/ to a file that does
not exist, or a formula that does not convert. The browser then opens the built pages from
disk and checks what a reader sees: every figure decoded (naturalWidth > 0), every formula
drawn as MathML with a size, no raw TeX left, and nothing requested from the network.

Needs the docs extra (``pip install -e .[docs]``; scripts/test.sh installs it) and, for the
browser part, Debian's chromium (scripts/setup.sh installs it): without them the tests skip
and say which is missing.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from playwright.sync_api import Browser

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
# The pages a student or teacher reads (the ~100 generated block pages are built and link-
# checked by the strict build; they have no figures or formulas).
READ_PAGES = sorted([*DOCS.glob("*.md"), *(DOCS / "labs").glob("*.md")])
_FENCE = re.compile(r"^```.*?^```\s*$", re.S | re.M)
_CODE_SPAN = re.compile(r"`[^`\n]*`")
# Chapters and design notes write their formulas in TeX, which the site draws as MathML; a
# code block is code and names its language. (docs/motion.md is left out while it is being
# rewritten; the labs keep unlabelled blocks for the checker output test_teaching_docs.py
# compares.) Each page here must have formulas, so the browser test below reads them.
TEX_PAGES = sorted(DOCS / name for name in (
    "kinematics.md", "servo-pwm.md", "orientation.md", "frames-dh.md", "jacobians.md",
    "fixed-point.md", "orientation-ik.md"))


def _needs_docs_extra() -> None:
    missing = [m for m in ("mkdocs", "latex2mathml") if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"the docs extra is not installed ({', '.join(missing)} missing): "
                    "pip install -e '.[docs]' (scripts/test.sh installs it)")


def _mkdocs(config: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f",
                           str(config), "-d", str(out)], cwd=config.parent,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    _needs_docs_extra()
    out = tmp_path_factory.mktemp("site")
    t0 = time.perf_counter()
    done = _mkdocs(REPO / "mkdocs.yml", out)
    elapsed = time.perf_counter() - t0
    assert done.returncode == 0, f"mkdocs build --strict failed:\n{done.stdout}\n{done.stderr}"
    print(f"site built in {elapsed:.1f} s")
    return out


def _prose(page: Path) -> str:
    return _CODE_SPAN.sub("", _FENCE.sub("", page.read_text(encoding="utf-8")))


def _formula_count(page: Path) -> int:
    text = _prose(page)
    display = len(re.findall(r"\$\$.+?\$\$", text, re.S))
    inline = len(re.findall(r"(?<![\\$\w])\$(?![\s$])[^$\n]+?(?<![\s\\])\$(?![\w$])",
                            re.sub(r"\$\$.+?\$\$", "", text, flags=re.S)))
    return display + inline


def _html(site: Path, page: Path) -> Path:
    return site / page.relative_to(DOCS).with_suffix(".html")


# --------------------------------------------------------------------------- the build

def test_every_page_is_built(site: Path) -> None:
    for page in sorted(DOCS.rglob("*.md")):
        assert _html(site, page).is_file(), f"{page.relative_to(REPO)} was not built"


def test_nothing_is_loaded_from_the_network(site: Path) -> None:
    remote = re.compile(r"<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)=\"(?:https?:)?//",
                        re.I)
    offenders = [str(p.relative_to(site)) for p in site.rglob("*.html")
                 if remote.search(p.read_text(encoding="utf-8"))]
    assert not offenders, f"pages that load a remote script, style sheet or image: {offenders}"


def test_formulas_become_mathml(site: Path) -> None:
    pages = [p for p in READ_PAGES if _formula_count(p)]
    assert pages, "no page has a formula: the MathML path is untested"
    for page in pages:
        html = _html(site, page).read_text(encoding="utf-8")
        assert html.count("<math ") == _formula_count(page), page.name
        assert "$$" not in re.sub(r"<code.*?</code>", "", html, flags=re.S), page.name


@pytest.mark.parametrize("page", TEX_PAGES, ids=lambda p: p.name)
def test_chapters_write_formulas_in_tex(page: Path) -> None:
    text = page.read_text(encoding="utf-8")
    assert _formula_count(page) > 0, f"{page.name} has no TeX formula"
    unlabelled = [text.count("\n", 0, m.start()) + 1 for m in
                  re.finditer(r"^```([^\n`]*)\n.*?^```\s*$", text, re.S | re.M)
                  if not m.group(1).strip()]
    assert not unlabelled, (f"{page.name}: code blocks without a language at lines "
                            f"{unlabelled}: a formula goes in $$...$$, code names its language")
    indented = [text.count("\n", 0, m.start()) + 2 for m in
                re.finditer(r"\n[ \t]*\n((?: {4}|\t)\S[^\n]*)", _FENCE.sub("", text))
                if not re.match(r"\s*([-*]|\d+\.)\s", m.group(1))]
    assert not indented, f"{page.name}: indented code blocks (formulas?) near lines {indented}"


def test_test_marks_are_not_languages(site: Path) -> None:
    # ```st fail E0106 must render as an ST code block, not as a paragraph of backticks
    html = _html(site, DOCS / "labs" / "lab2-st-portability.md").read_text(encoding="utf-8")
    assert "```" not in html and "fail E0106" not in html


def test_links_out_of_docs_keep_their_target(site: Path) -> None:
    # site/index.html sits where docs/index.md does, so ../README.md reaches the checkout's.
    html = _html(site, DOCS / "index.md").read_text(encoding="utf-8")
    assert 'href="../README.md"' in html


# --------------------------------------------------------------------------- the checks fail

def _tiny_site(tmp_path: Path, index: str) -> Path:
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(index, encoding="utf-8")
    config = tmp_path / "mkdocs.yml"
    config.write_text(
        "site_name: t\nuse_directory_urls: false\ntheme:\n  name: mkdocs\n  highlightjs: false\n"
        f"hooks:\n  - {REPO / 'sim' / 'armbench' / 'docsite.py'}\n"
        "markdown_extensions:\n  - fenced_code\n", encoding="utf-8")
    return config


@pytest.mark.parametrize("index,expected", [
    ("![a figure](figures/none.png)\n", "figures/none.png"),
    ("[a page](nowhere.md)\n", "nowhere.md"),
    ("[the code](../no-such-file.py)\n", "no-such-file.py"),
    ("$$\n\\frac{1}{\n$$\n", "frac"),
])
def test_strict_build_fails_on(tmp_path: Path, index: str, expected: str) -> None:
    _needs_docs_extra()
    done = _mkdocs(_tiny_site(tmp_path, index), tmp_path / "out")
    assert done.returncode != 0
    assert expected in done.stdout + done.stderr


def test_dollar_amounts_are_not_formulas() -> None:
    _needs_docs_extra()
    import markdown

    from armbench.docsite import MathExtension

    html = markdown.markdown("costs $5 and $6, and `$x$` is code; $a_1$ is maths",
                             extensions=[MathExtension()])
    assert html.count("<math") == 1 and "$5 and $6" in html and "<code>$x$</code>" in html


def test_aligned_equations_become_a_table() -> None:
    # latex2mathml draws aligned's '&' as a letter and its '\\' as a line break that
    # browsers ignore: one run-on line reading "r& = ...X& = ...". It must become a table.
    _needs_docs_extra()
    from armbench.docsite import mathml

    out = mathml(r"\begin{aligned} r &= a_2 \\ X &= r \cos\theta_1 \end{aligned}", True)
    assert "<mtable" in out and out.count("<mtr") == 2, out
    assert ">&<" not in out and 'linebreak="newline"' not in out, out


def test_function_names_are_spaced_as_in_tex() -> None:
    # TeX: "a cos p" with thin spaces, "sin(x)" without; browsers set latex2mathml's <mi>
    # tight, "acosp", unless the spaces are written out.
    _needs_docs_extra()
    from armbench.docsite import mathml

    thin = '<mspace width="0.167em" />'
    assert f"</msub>{thin}<mi>cos</mi>{thin}<mi>p</mi>" in mathml(r"a_3 \cos p", False)
    assert f"<mi>sin</mi>{thin}" not in mathml(r"\sin(x)", False)
    assert mathml(r"\cos", False).count(thin) == 0


@pytest.mark.parametrize("tex", [r"\begin{gathered} a \\ b \end{gathered}",
                                 r"a \\ b", r"\begin{eqnarray} a &= b \end{eqnarray}"])
def test_formulas_that_would_draw_markup_as_text_fail(tex: str) -> None:
    _needs_docs_extra()
    from armbench.docsite import FormulaError, mathml

    with pytest.raises(FormulaError, match="aligned"):
        mathml(tex, True)


# --------------------------------------------------------------------------- in the browser

def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    path = _chromium()
    if path is None:
        pytest.skip("chromium is not installed: scripts/setup.sh installs it with apt-get "
                    "(Debian package chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, args=["--no-sandbox"])
        yield b
        b.close()


_MEASURE = r"""() => {
  const main = document.querySelector('div[role=main], .col-md-9');
  const prose = main.cloneNode(true);
  prose.querySelectorAll('code, pre, math').forEach(e => e.remove());
  return {
    images: Array.from(document.querySelectorAll('img')).map(i => ({
      src: i.getAttribute('src'), complete: i.complete, width: i.naturalWidth})),
    formulas: Array.from(document.querySelectorAll('math')).map(m => {
      const r = m.getBoundingClientRect();
      // rows of aligned equations and matrices: each below the one before
      const stacked = Array.from(m.querySelectorAll('mtable')).every(t => {
        const tops = Array.from(t.children).map(row => row.getBoundingClientRect().top);
        return tops.every((top, i) => i === 0 || top > tops[i - 1]);
      });
      // aligned equations (align* tables): the right-hand sides start at one x, the '='
      const starts = Array.from(m.querySelectorAll('mtable[displaystyle=true]')).map(t =>
        Array.from(t.children).filter(row => row.children.length > 1).map(row => {
          const seen = Array.from(row.children[1].children)
            .find(c => c.getBoundingClientRect().width > 0);
          return seen ? seen.getBoundingClientRect().left : null;
        }).filter(x => x !== null));
      const lined = starts.every(xs => xs.every(x => Math.abs(x - xs[0]) < 1));
      return {mathml: m instanceof MathMLElement, width: r.width, height: r.height,
              text: m.textContent, stacked: stacked, lined: lined};
    }),
    // TeX that did not become MathML: $$...$$, or $...$ as the build's inline rule reads it
    rawTex: prose.textContent.includes('$$')
      || /(?<![\\$\w])\$(?![\s$])[^$\n]+?(?<![\s\\])\$(?![\w$])/.test(prose.textContent),
  };
}"""


@pytest.mark.parametrize("page", [p for p in READ_PAGES
                                  if _formula_count(p) or "![" in _prose(p)],
                         ids=lambda p: str(p.relative_to(DOCS)))
def test_page_renders_its_figures_and_formulas(site: Path, browser: Browser,
                                               page: Path) -> None:
    tab = browser.new_page(viewport={"width": 1200, "height": 900})
    remote: list[str] = []
    tab.on("request", lambda r: remote.append(r.url) if not r.url.startswith("file:") else None)
    try:
        tab.goto(_html(site, page).as_uri(), wait_until="load")
        seen: dict[str, Any] = tab.evaluate(_MEASURE)
    finally:
        tab.close()
    assert not remote, f"{page.name} requested {remote}"
    figures = len(re.findall(r"!\[[^\]]*\]\([^)]+\.png\)", _prose(page)))
    shown = [i for i in seen["images"] if i["src"].endswith(".png")]
    assert len(shown) == figures, f"{page.name}: {len(shown)} figures shown, {figures} in docs"
    broken = [i["src"] for i in shown if not (i["complete"] and i["width"] > 0)]
    assert not broken, f"{page.name}: figures that did not load: {broken}"
    assert len(seen["formulas"]) == _formula_count(page), page.name
    flat = [f for f in seen["formulas"] if not (f["mathml"] and f["width"] > 0
                                                 and f["height"] > 0)]
    assert not flat, f"{page.name}: formulas not drawn as MathML: {flat}"
    as_text = [f["text"] for f in seen["formulas"] if re.search(r"[&\\]", f["text"])]
    assert not as_text, f"{page.name}: formulas that show TeX markup as text: {as_text}"
    run_on = [f["text"] for f in seen["formulas"] if not f["stacked"]]
    assert not run_on, f"{page.name}: rows of a formula not drawn one below the other: {run_on}"
    ragged = [f["text"] for f in seen["formulas"] if not f["lined"]]
    assert not ragged, f"{page.name}: aligned equations whose '=' do not line up: {ragged}"
    assert not seen["rawTex"], f"{page.name} shows TeX that did not become MathML"


# --------------------------------------------------------------------------- PDF handouts

def test_lab_handouts_print(site: Path, browser: Browser, tmp_path: Path) -> None:
    # Every lab prints to a PDF of a few A4 sheets; for print the navigation is hidden and the
    # formulas are still drawn (the PDF is what the print view shows).
    from armbench.handouts import PRINT_CSS, lab_pages, print_handouts

    pages = lab_pages(site)
    assert [p.stem for p in pages] == sorted((p.stem for p in (DOCS / "labs").glob("lab*.md")),
                                             key=lambda s: int(s[3:s.index("-")]))
    made = print_handouts(browser, pages, tmp_path)
    for h in made:
        data = h.pdf.read_bytes()
        assert data.startswith(b"%PDF-") and data.rstrip().endswith(b"%%EOF"), h.pdf.name
        assert 1 <= h.sheets <= 12, (h.pdf.name, h.sheets)
    tab = browser.new_page()
    try:
        tab.goto(pages[5].as_uri(), wait_until="load")  # Lab 6: inline and display formulas
        tab.emulate_media(media="print")
        tab.add_style_tag(content=PRINT_CSS)
        shown: dict[str, Any] = tab.evaluate("""() => ({
          nav: Array.from(document.querySelectorAll('.navbar, .bs-sidebar, footer'))
                 .some(e => e.getBoundingClientRect().height > 0),
          formulas: Array.from(document.querySelectorAll('math'))
                      .filter(m => m.getBoundingClientRect().width > 0).length})""")
    finally:
        tab.close()
    assert not shown["nav"], "the site's navigation is printed"
    assert shown["formulas"] == _formula_count(DOCS / "labs" / "lab6-motion.md")
