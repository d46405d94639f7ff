"""Make `armbench` importable when the package is not installed into the venv."""

import sys
from pathlib import Path

try:
    import armbench  # noqa: F401
except ModuleNotFoundError:
    # The repo keeps the package under sim/; without `pip install -e .` pytest cannot see it.
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "sim"))
