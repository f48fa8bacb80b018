"""Shared fixtures for the planning tests: the benchmark folder and the Tiger problem."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def benchmark_dir() -> Path:
    """``../shared/pomdp-benchmarks`` beside the repository, or $RAPOMDP_POMDP_BENCHMARKS."""
    env = os.environ.get("RAPOMDP_POMDP_BENCHMARKS")
    return Path(env) if env else REPO.parent / "shared" / "pomdp-benchmarks"


@pytest.fixture(scope="session")
def benchmarks() -> Path:
    folder = benchmark_dir()
    if not folder.is_dir():
        pytest.skip(f"benchmark problems not found at {folder}")
    return folder
