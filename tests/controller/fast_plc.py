"""The fast-clock soft PLC the controller tests share (the fixture is in conftest.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from armbench.softplc.scan import SoftPlc


@dataclass
class FastPlc:
    plc: SoftPlc  # in-process: a test may write the inputs a real PLC's I/O layer writes
    address: tuple[str, int]  # its Modbus server
    # called in the scan thread before every scan (e.g. the IMU plant writing one sample per
    # scan, as the PSM does on a Pi); a test sets it and clears it when done
    before_scan: list[Callable[[], None]] = field(default_factory=list)
