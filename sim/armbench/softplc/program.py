"""The contract between the soft PLC and a compiled ST program (delivered by the compiler).

The soft PLC only schedules and reports; everything a scan does happens behind
:meth:`CompiledProgram.run_task`, which works directly on the shared :class:`ProcessImage`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from .image import ProcessImage


@dataclass(frozen=True)
class TaskSpec:
    """One periodic TASK of the CONFIGURATION's RESOURCE.

    ``priority`` follows IEC 61131-3: 0 is the most urgent; among tasks released at the same
    instant the lower number runs first.
    """

    name: str
    interval_ns: int
    priority: int
    instances: tuple[str, ...]


class PlcFault(Exception):
    """A run-time error inside a scan (division by zero, bounds, watchdog), with the ST source
    position where it happened (``file.st:12:5``).

    When this escapes :meth:`CompiledProgram.run_task`, the C side has already put the image
    outputs back to their values from before the faulted scan.
    """

    def __init__(self, message: str, location: str) -> None:
        super().__init__(f"{location}: {message}")
        self.message = message
        self.location = location


class CompiledProgram(Protocol):
    """What the soft PLC needs from a compiled program."""

    @property
    def image(self) -> ProcessImage: ...

    @property
    def tasks(self) -> Sequence[TaskSpec]: ...

    def run_task(self, task: str, now_ns: int) -> None:
        """Run one scan of every program instance of ``task``; raise :class:`PlcFault`."""
        ...

    def instance_vars(self, instance: str) -> dict[str, object]:
        """JSON-able values of a program instance's variables."""
        ...
