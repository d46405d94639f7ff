"""The contract between the soft PLC and a compiled ST program (delivered by the compiler).

The soft PLC only schedules and reports; everything a scan does happens behind
:meth:`CompiledProgram.run_task`, which works directly on the shared :class:`ProcessImage`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from ..faults import PlcFault
from .image import ProcessImage

__all__ = ["CompiledProgram", "PlcFault", "TaskSpec"]


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
