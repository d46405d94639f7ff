"""The command line every figure script shares: where the checkout is and where figures go."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from ..locate import LocateError, Project, find_checkout

FIGURES_DIR = Path("docs") / "figures"  # inside the checkout


def figure_target(prog: str, argv: Sequence[str] | None) -> tuple[Project, Path]:
    """Parse ``--out``/``--repo`` of ``python -m <prog>``; returns the checkout and the output
    folder (created). A checkout that cannot be found is a usage error naming why, and
    matplotlib draws off-screen (the scripts run on headless machines and in CI)."""
    parser = argparse.ArgumentParser(prog=f"python -m {prog}")
    parser.add_argument("--out", type=Path, default=None,
                        help="default: docs/figures/ of the checkout")
    parser.add_argument("--repo", type=Path, default=None,
                        help="the checkout (default: found from the current directory)")
    args = parser.parse_args(argv)
    try:
        checkout = find_checkout(args.repo)
    except LocateError as exc:
        parser.error(str(exc))
    out: Path = args.out or checkout.root / FIGURES_DIR
    out.mkdir(parents=True, exist_ok=True)

    import matplotlib

    matplotlib.use("Agg")
    return checkout, out
