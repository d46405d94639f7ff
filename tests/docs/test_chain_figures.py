"""The chain chapters' figures: armbench.plots.chains writes them, the pages show them."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
PAGES = [DOCS / "frames-dh.md", DOCS / "jacobians.md"]


def test_chain_figures_are_shown_and_committed() -> None:
    from armbench.plots import chains

    text = "".join(p.read_text(encoding="utf-8") for p in PAGES)
    for name in chains.FIGURES:
        assert f"(figures/{name})" in text, f"{name} is written but shown on no chain page"
        assert (DOCS / "figures" / name).is_file(), name


def test_chain_figure_script_writes_its_figures(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from armbench.plots import chains

    assert chains.main(["--out", str(tmp_path), "--repo", str(REPO)]) == 0
    for name in chains.FIGURES:
        png = tmp_path / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert png.stat().st_size > 10_000, name
