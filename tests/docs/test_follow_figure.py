"""The figure of docs/orientation.md section 11 comes from ``armbench.plots.follow`` (the soft
PLC following the simulated hand), and the page shows it."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_script_writes_the_figure_the_page_shows(tmp_path: Path) -> None:
    from armbench.plots import follow

    assert follow.main(["--out", str(tmp_path), "--repo", str(REPO)]) == 0
    page = (REPO / "docs" / "orientation.md").read_text(encoding="utf-8")
    png = tmp_path / follow.FIGURE
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 10_000
    assert f"figures/{follow.FIGURE}" in page
    assert "python -m armbench.plots.follow" in page
    assert (REPO / "docs" / "figures" / follow.FIGURE).is_file()
