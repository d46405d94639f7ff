"""The ST compiler: parse -> lower -> check (resolve, rules) -> emit C -> build -> ffi."""

from __future__ import annotations

from .diagnostics import CompileFailed, Diagnostic
from .driver import check_files, compile_files

__all__ = ["CompileFailed", "Diagnostic", "check_files", "compile_files"]
