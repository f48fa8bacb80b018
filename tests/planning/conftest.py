"""Shared fixtures for the planning tests: the classic ``.pomdp`` problems they read."""

from __future__ import annotations

from pathlib import Path

import pytest

#: Tiger, Hallway and Hallway2, kept in the repository (their origin and licence:
#: ``data/README.md``), so that the tests that read them run on a fresh clone.
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def benchmarks() -> Path:
    """The folder of the classic ``.pomdp`` problems (:data:`DATA`)."""
    return DATA
