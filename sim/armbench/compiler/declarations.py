"""The C declarations of a library for cffi, parsed once: when the library is built, cffi
parses them (cdef) and they are written as cffi's out-of-line module, which loading the
library (ffi.Module) runs instead of parsing C again: a large program's declarations take
cffi a tenth of a second or more to parse, the module a few milliseconds to run.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import _cffi_backend
import cffi
import cffi.recompiler

# the name cffi gives the declarations (it appears in its error messages only)
_DECLARATIONS_NAME = "armbench_plc"


def write_declarations(decls: str, path: Path) -> None:
    """Parse ``decls`` (C declarations) and write them to ``path`` as cffi's out-of-line
    module, under a temporary name first: a concurrent reader never sees half a file."""
    ffi = cffi.FFI()
    ffi.cdef(decls)
    # cffi before 2.0 writes only to a file name, not to a file object
    with tempfile.TemporaryDirectory(dir=path.parent) as folder:
        module = Path(folder) / path.name
        cffi.recompiler.make_py_source(ffi, _DECLARATIONS_NAME, str(module))
        os.replace(module, path)


def load_declarations(path: Path, decls: str) -> Any:
    """The cffi FFI object of the declarations module at ``path``; written anew from
    ``decls`` when it is missing or cannot be run (truncated, edited, from another cffi)."""
    try:
        return _run_declarations(path)
    except Exception:  # noqa: BLE001 - any unusable module is rewritten
        write_declarations(decls, path)
        return _run_declarations(path)


def _run_declarations(path: Path) -> Any:
    namespace: dict[str, Any] = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    ffi = namespace.get("ffi")
    if not isinstance(ffi, _cffi_backend.FFI):
        raise ValueError(f"{path} defines no cffi FFI object")
    return ffi
