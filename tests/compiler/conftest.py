"""Fixtures shared by the compiler suites."""

from __future__ import annotations

import pytest
from st_corpus import MATIEC_HELP, Matiec, find_matiec


@pytest.fixture(scope="module")
def matiec() -> Matiec:
    """The real MatIEC (see st_corpus.find_matiec), or skip with how to provide it."""
    m = find_matiec()
    if m is None:
        pytest.skip(MATIEC_HELP)
    return m
