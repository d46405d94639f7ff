"""Load ST files into something the soft PLC can run: a compiled Module behind CompiledProgram."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..compiler import compile_files
from ..compiler.ffi import Module
from .image import ProcessImage
from .program import TaskSpec


class LoadedProgram:
    """A compiled CONFIGURATION: its tasks, its process image, one scan per run_task call."""

    def __init__(self, module: Module) -> None:
        cfg = module.program.config
        if cfg is None:
            raise ValueError("the sources have no CONFIGURATION: the soft PLC needs "
                             "CONFIGURATION Config0 / RESOURCE Res0 / TASK / PROGRAM ... WITH")
        self.module = module
        self._task_index = {t.name.upper(): i for i, t in enumerate(cfg.tasks)}
        self._tasks = tuple(
            TaskSpec(t.name, t.interval_ns, t.priority,
                     tuple(i.name for i in cfg.instances
                           if (i.task or "").upper() == t.name.upper()))
            for t in cfg.tasks)
        self._image = ProcessImage.from_buffer(module.image_buffer())
        module.config_init()

    @property
    def image(self) -> ProcessImage:
        return self._image

    @property
    def tasks(self) -> Sequence[TaskSpec]:
        return self._tasks

    def run_task(self, task: str, now_ns: int) -> None:
        self.module.run_task_index(self._task_index[task.upper()], now_ns)

    def instance_vars(self, instance: str) -> dict[str, object]:
        return self.module.instance(instance).vars()

    def instance_names(self) -> list[str]:
        return [i for t in self._tasks for i in t.instances]


def load_program(paths: Sequence[str | Path]) -> LoadedProgram:
    return LoadedProgram(compile_files(paths))
