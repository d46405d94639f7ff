"""The chain chapters' figures: armbench.plots.chains writes them
(tests/docs/test_figure_scripts.py), the pages show them."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
PAGES = [DOCS / "frames-dh.md", DOCS / "jacobians.md"]


def test_chain_figures_are_shown_and_committed() -> None:
    from armbench.plots import chains

    text = "".join(p.read_text(encoding="utf-8") for p in PAGES)
    for name in chains.FIGURES:
        assert f"(figures/{name})" in text, f"{name} is written but shown on no chain page"
        assert (DOCS / "figures" / name).is_file(), name
