"""The command-line options of ``armbench demo`` and ``armbench demo-imu``.

Kept apart from the demos themselves: ``armbench`` builds its whole command line on every
start, and the demos import the controller client, the plant models and numpy, which a
``check`` or ``run`` of the user's own program must not wait for.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from . import argtypes

DEFAULT_OUT = Path("out") / "demo"


def imu_rate(text: str) -> float:
    """An IMU rate the 10 ms scan can write: 100 Hz divided by a whole number."""
    from .follow_demo import imu_rate as follow_rate  # only when the option is given

    return follow_rate(text)


def add_demo_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--points", type=argtypes.positive_count, default=360,
                   help="points on the circle (360)")
    p.add_argument("--radius", type=argtypes.positive_length, default=40.0, help="mm (40)")
    p.add_argument("--plane", choices=("xy", "xz"), default="xy",
                   help="xy horizontal (default) or xz vertical, centre (150, 0, 120) mm")
    p.add_argument("--out", default=str(DEFAULT_OUT),
                   help="folder for the PNG plots (out/demo, git-ignored)")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--poll-ms", type=argtypes.seconds, default=0.5,
                   help="sleep between answer polls in ms (0.5; 0 = busy loop)")


def add_follow_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seconds", type=argtypes.float_between(1.0, 600.0, "s"), default=20.0,
                   help="follow time, s (default 20)")
    p.add_argument("--heading", type=argtypes.float_between(-360.0, 360.0, "deg"),
                   default=10.0,
                   help="the arm's X axis from magnetic north, deg (default 10)")
    p.add_argument("--flange-fixed", action="store_true",
                   help="hold the flange point instead of the tool tip")
    p.add_argument("--seed", type=argtypes.count, default=5,
                   help="noise seed of the simulated IMU (default 5)")
    p.add_argument("--rate", type=imu_rate, default=100.0,
                   help="IMU sample rate, Hz: 100 divided by a whole number (default 100)")
