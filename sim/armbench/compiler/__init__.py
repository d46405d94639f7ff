"""The ST compiler: parse -> lower -> check (resolve, rules) -> emit C -> build -> ffi."""

from __future__ import annotations

from .diagnostics import CompileFailed, Diagnostic
from .driver import check_files, compile_files
from .targets import Target

__all__ = ["CompileFailed", "Diagnostic", "Target", "check_files", "compile_files"]
