"""The figures of docs/fixed-point.md (003 line) and docs/orientation-ik.md come from the
script that the pages name, and the pages show them."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_script_writes_the_figures_the_pages_show(tmp_path: Path) -> None:
    from armbench.plots import chains_orientation

    assert chains_orientation.main(["--out", str(tmp_path), "--repo", str(REPO)]) == 0
    pages = (REPO / "docs" / "fixed-point.md").read_text(encoding="utf-8") + (
        REPO / "docs" / "orientation-ik.md").read_text(encoding="utf-8")
    for name in chains_orientation.FIGURES:
        png = tmp_path / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert png.stat().st_size > 10_000, name
        assert f"figures/{name}" in pages, f"{name} is shown on no page"
        assert (REPO / "docs" / "figures" / name).is_file(), name
