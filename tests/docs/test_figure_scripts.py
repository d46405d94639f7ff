"""Every figure script under armbench.plots that the docs pages name: run into a temporary
folder, it writes real PNGs, and each one is shown on its pages, committed under
docs/figures/, and the pages say which command regenerates it. matplotlib is a declared
dependency: a missing one fails here rather than skipping."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class FigureScript:
    module: str  # under armbench.plots
    pages: tuple[str, ...]  # under docs/
    figures: tuple[str, ...] = ()  # empty: the module's FIGURES (or its one FIGURE)


SCRIPTS = [
    FigureScript("chains", ("frames-dh.md", "jacobians.md")),
    FigureScript("chains_orientation", ("fixed-point.md", "orientation-ik.md")),
    FigureScript("follow", ("orientation.md",)),
    FigureScript("motion", ("motion.md",)),
    FigureScript("orientation", ("orientation.md",),
                 ("orientation-error.png", "orientation-follower.png")),
]


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda s: s.module)
def test_script_writes_the_figures_its_pages_show(tmp_path: Path, script: FigureScript) -> None:
    mod = importlib.import_module(f"armbench.plots.{script.module}")
    figures = script.figures or tuple(getattr(mod, "FIGURES", None) or (mod.FIGURE,))
    assert figures, f"armbench.plots.{script.module} names no figure"

    assert mod.main(["--out", str(tmp_path), "--repo", str(REPO)]) == 0
    text = "".join((DOCS / page).read_text(encoding="utf-8") for page in script.pages)
    assert f"python -m armbench.plots.{script.module}" in text, \
        f"{script.pages} do not say how to regenerate their figures"
    for name in figures:
        png = tmp_path / name
        assert png.read_bytes()[:8] == PNG_MAGIC, name
        assert png.stat().st_size > 10_000, name
        assert f"(figures/{name})" in text, f"{name} is written but shown on no page"
        assert (DOCS / "figures" / name).is_file(), name
