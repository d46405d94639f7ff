"""Lab handouts as PDF: each lab page of the built documentation site, printed by Chromium.

Offline, with what the developer set-up installs: Debian's chromium (scripts/setup.sh) driven
by Playwright (the dev extra), the same pair the site's browser test uses. The formulas are
MathML in the pages already (armbench.docsite), so the PDF draws them as the browser does,
without a network and without TeX. ``bash scripts/handouts.sh`` builds the site and prints
every lab into handouts/; ``python -m armbench.handouts --site site --out handouts`` prints
from a site built before.

For print the site's navigation bar, table of contents, search dialogs and footer are hidden,
the page column takes the whole width, and a code block, table or formula is not split
between two sheets when it fits on one.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # Playwright is a dev dependency: imported when a handout is printed
    from playwright.sync_api import Browser

PRINT_CSS = """
.navbar, .bs-sidebar, .col-md-3, footer, .modal { display: none !important; }
body { padding-top: 0 !important; }
.container { max-width: none !important; width: auto !important; }
.col-md-9 { flex: 0 0 100% !important; max-width: 100% !important; }
pre, table, div.formula, img { break-inside: avoid; }
h1, h2, h3 { break-after: avoid; }
div.formula, table { overflow: visible !important; }
"""
PAPER = "A4"
MARGIN = "15mm"
# Skia writes every page object of the PDF as plain text: "/Type /Page" (not "/Pages").
_PAGE_OBJECT = re.compile(rb"/Type\s*/Page(?![s\w])")


class HandoutError(RuntimeError):
    """A handout cannot be printed: the message says what is missing and how to get it."""


@dataclass(frozen=True)
class Handout:
    source: Path   # the lab's page in the built site
    pdf: Path
    sheets: int    # pages of the PDF


def lab_pages(site: Path) -> list[Path]:
    """The labs of a built site (site/labs/lab*.html), in lab order."""
    pages = sorted((site / "labs").glob("lab*.html"),
                   key=lambda p: int(m.group(1)) if (m := re.match(r"lab(\d+)", p.name)) else 0)
    if not pages:
        raise HandoutError(f"no lab pages in {site / 'labs'}: build the site first "
                           "(bash scripts/docs.sh)")
    return pages


def sheets(pdf: bytes) -> int:
    """Pages of a PDF that Chromium wrote."""
    return len(_PAGE_OBJECT.findall(pdf))


def print_handouts(browser: Browser, pages: Sequence[Path], out: Path) -> list[Handout]:
    """Prints each page to out/<page name>.pdf with the print style above."""
    out.mkdir(parents=True, exist_ok=True)
    made = []
    for page in pages:
        tab = browser.new_page()
        try:
            tab.goto(page.resolve().as_uri(), wait_until="load")
            tab.emulate_media(media="print")
            tab.add_style_tag(content=PRINT_CSS)
            pdf = tab.pdf(format=PAPER, print_background=False,
                          margin={"top": MARGIN, "bottom": MARGIN, "left": MARGIN,
                                  "right": MARGIN})
        finally:
            tab.close()
        target = out / page.with_suffix(".pdf").name
        target.write_bytes(pdf)
        made.append(Handout(page, target, sheets(pdf)))
    return made


def find_chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    raise HandoutError("chromium is not installed: scripts/setup.sh installs it with apt-get "
                       "(Debian package chromium)")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m armbench.handouts", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--site", type=Path, default=Path("site"),
                        help="the built site (default: site)")
    parser.add_argument("--out", type=Path, default=Path("handouts"),
                        help="where the PDFs go (default: handouts)")
    args = parser.parse_args(argv)
    try:
        pages = lab_pages(args.site)
        chromium = find_chromium()
        try:
            from playwright.sync_api import sync_playwright
        except ImportError as exc:
            raise HandoutError("Playwright is missing: pip install -e '.[dev]' "
                               "(scripts/setup.sh does)") from exc
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
            try:
                made = print_handouts(browser, pages, args.out)
            finally:
                browser.close()
    except HandoutError as exc:
        print(f"handouts: {exc}", file=sys.stderr)
        return 1
    for h in made:
        print(f"{h.pdf}: {h.sheets} page{'s' if h.sheets != 1 else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
