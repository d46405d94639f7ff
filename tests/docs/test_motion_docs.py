"""docs/motion.md shows exactly the figures armbench.plots.motion writes, and the script
writes them (tests/docs/test_figure_scripts.py; it runs the ST motion blocks through the
compiler)."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "motion.md"


def test_motion_page_shows_the_motion_figures() -> None:
    from armbench.plots import motion

    shown = set(re.findall(r"!\[[^\]]*\]\(figures/(motion-[^)]+\.png)\)",
                           PAGE.read_text(encoding="utf-8")))
    assert shown == set(motion.FIGURES)
    for name in shown:
        assert (REPO / "docs" / "figures" / name).is_file(), name
