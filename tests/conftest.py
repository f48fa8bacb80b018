"""Shared fixtures: progress bars off, a tiny configuration, a tiny built workspace."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapomdp.config import Config, config_from_dict
from rapomdp.progress import set_progress

set_progress(False)


def tiny_config(**overrides: object) -> Config:
    """Three procedural classes, 5 models each, a handful of small views."""
    data: dict = {
        "seed": 3,
        "dataset": {"classes": ["cup", "mug", "bicycle"]},
        "camera": {"width": 40, "height": 30},
        "render": {"views": 6},
        "viewpoints": {"count": 16},
    }
    for key, value in overrides.items():
        data[key] = value
    return config_from_dict(data)


@pytest.fixture
def config() -> Config:
    return tiny_config()


@pytest.fixture
def workspace_dir(tmp_path: Path) -> Path:
    return tmp_path / "ws"
