"""Load plc_project/psm/arm_io_psm.py the way OpenPLC runs it: as a file, not from a package."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

PSM_PATH = Path(__file__).resolve().parents[1] / "plc_project" / "psm" / "arm_io_psm.py"


def load_psm_script(module_name: str) -> ModuleType:
    """A fresh copy of the PSM script as module ``module_name`` (no psm/smbus2 needed)."""
    spec = importlib.util.spec_from_file_location(module_name, PSM_PATH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while building
    spec.loader.exec_module(module)
    return module
