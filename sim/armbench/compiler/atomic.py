"""Writing a cache or build file so that concurrent processes (pytest-xdist workers building the
same program) never see half of it: a temporary name in the same folder, then a rename."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_atomic(path: Path, data: bytes | str, suffix: str = ".tmp") -> None:
    """Write ``data`` to ``path`` whole or not at all; OSError as from open/write."""
    fd, tmp = tempfile.mkstemp(suffix=suffix, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
