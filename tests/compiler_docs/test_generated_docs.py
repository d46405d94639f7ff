"""Generated documentation must match its source of truth."""

from pathlib import Path

from armbench.compiler.diagdoc import render

ROOT = Path(__file__).resolve().parents[2]


def test_diagnostics_page_is_current() -> None:
    page = (ROOT / "docs" / "diagnostics.md").read_text()
    assert page == render(), "docs/diagnostics.md is stale: regenerate it with " \
        "python -m armbench.compiler.diagdoc > docs/diagnostics.md"


def test_block_reference_pages_are_current() -> None:
    from armbench.docgen import main

    assert main(["--check"]) == 0, "docs/reference is stale: run python -m armbench.docgen"
