"""The fast-clock soft PLC the controller tests share (the fixture is in conftest.py)."""

from __future__ import annotations

from dataclasses import dataclass

from armbench.softplc.scan import SoftPlc


@dataclass
class FastPlc:
    plc: SoftPlc  # in-process: a test may write the inputs a real PLC's I/O layer writes
    address: tuple[str, int]  # its Modbus server
