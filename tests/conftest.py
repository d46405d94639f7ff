"""Helpers that test folders share live in tests/ itself (e.g. psm_script.py); appended, not
prepended, to sys.path so that no test folder's name shadows an installed module."""

import sys
from pathlib import Path

_TESTS = str(Path(__file__).resolve().parent)
if _TESTS not in sys.path:
    sys.path.append(_TESTS)
