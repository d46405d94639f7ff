"""Load plc_project/psm/arm_io_psm.py the way OpenPLC runs it: as a file, not from a package;
and the two things the script talks to, on the bench: an smbus2-shaped bus in front of the
PCA9685 model (SimBus) and OpenPLC's psm.get_var/set_var over the soft PLC's process image
(ImageVars)."""

from __future__ import annotations

import importlib.util
import re
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

from armbench.plant.pca9685 import PCA9685
from armbench.softplc.image import ProcessImage

PSM_PATH = Path(__file__).resolve().parents[1] / "plc_project" / "psm" / "arm_io_psm.py"


def load_psm_script(module_name: str) -> ModuleType:
    """A fresh copy of the PSM script as module ``module_name`` (no psm/smbus2 needed)."""
    spec = importlib.util.spec_from_file_location(module_name, PSM_PATH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while building
    spec.loader.exec_module(module)
    return module


@dataclass
class SimBus:
    """smbus2-shaped adapter that forwards block writes to the PCA9685 model."""

    chip: PCA9685
    log: list[tuple[int, int, bytes]] = field(default_factory=list)
    fail_next: int = 0

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int]) -> None:
        assert len(data) <= 32, "SMBus block writes carry at most 32 bytes"
        if self.fail_next:
            self.fail_next -= 1
            raise OSError(121, "Remote I/O error")
        self.log.append((i2c_addr, register, bytes(data)))
        self.chip.write(i2c_addr, register, bytes(data))


@dataclass
class ImageVars:
    """OpenPLC's psm.get_var/set_var over the soft PLC's process image (the runtime's
    buffers), under the scan lock: the runtime copies the PSM's words between two scans."""

    image: ProcessImage
    lock: threading.Lock

    def _slot(self, name: str) -> tuple[str, int]:
        m = re.fullmatch(r"([IQ])([XW])(\d+)(?:\.(\d))?", name)
        assert m, name
        kind = m.group(1).lower() + m.group(2).lower()
        index = int(m.group(3)) if m.group(2) == "W" else 8 * int(m.group(3)) + int(m.group(4))
        return kind, index

    def get_var(self, name: str) -> object:
        kind, index = self._slot(name)
        with self.lock:
            value = int(getattr(self.image, kind)[index])
        return bool(value) if kind.endswith("x") else value

    def set_var(self, name: str, value: object) -> object:
        kind, index = self._slot(name)
        # a list fills consecutive words in one step, as pymodbus' setValues does
        values = value if isinstance(value, list) else [value]
        with self.lock:
            for i, v in enumerate(values):
                getattr(self.image, kind)[index + i] = int(bool(v)) if kind.endswith("x") \
                    else int(v)
        return None
