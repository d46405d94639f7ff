"""STAND-IN, for the tests only, of the OpenPLC v4 runtime's shared/image_sizes.py: the
fourteen table lengths the runtime hands a plugin's ``set_image_sizes`` before init(), in the
runtime's order, kept for SafeBufferAccess to bound each index by its own table."""

from __future__ import annotations

from typing import Any

IMAGE_TABLE_ORDER: list[str] = [
    "bool_input", "bool_output", "byte_input", "byte_output", "int_input", "int_output",
    "dint_input", "dint_output", "lint_input", "lint_output", "int_memory", "dint_memory",
    "lint_memory", "bool_memory",
]

_sizes: dict[str, int] = {}


def set_image_sizes(sizes: Any) -> int:
    _sizes.clear()
    try:
        values = list(sizes)
    except TypeError:
        return -1
    for name, count in zip(IMAGE_TABLE_ORDER, values, strict=False):
        try:
            _sizes[name] = int(count)
        except (TypeError, ValueError):
            return -1
    return 0


def sizes_known() -> bool:
    return bool(_sizes)


def table_capacity(name: str, default: int | None = None) -> int | None:
    return _sizes.get(name, default)
