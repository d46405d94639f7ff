"""Fixtures for the ST block tests: the library st/*.st compiled once per session."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
ST_DIR = REPO / "st"


@pytest.fixture(scope="session")
def st_module() -> Any:
    """The whole ST library (st/*.st) compiled by the bench's compiler, once per session.

    A compile error fails every test that uses it, with the compiler's diagnostics.
    """
    compiler = pytest.importorskip("armbench.compiler")
    paths = sorted(ST_DIR.glob("*.st"))
    assert paths, f"no ST sources in {ST_DIR}"
    try:
        return compiler.compile_files(paths)
    except compiler.CompileFailed as exc:  # pragma: no cover - reported as a failure
        pytest.fail(f"st/*.st does not compile:\n{exc}", pytrace=False)
