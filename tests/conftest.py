"""Shared fixtures: progress bars off and one thread everywhere, a tiny configuration."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from rapomdp import parallel
from rapomdp.config import Config, config_from_dict
from rapomdp.progress import set_progress

set_progress(False)


@pytest.fixture(autouse=True)
def _quiet_single_thread() -> None:
    """No progress bars, one PyTorch thread and no worker processes in every test (the machine
    has 2 shared cores; the tests that check parallel runs ask for processes explicitly)."""
    set_progress(False)
    torch.set_num_threads(1)
    parallel.workers = 1


#: The paper's split (3 train, 1 volume, 1 test): the tests' tiny datasets, 5 models a class.
SMALL_SPLIT: dict = {"train": 3, "volume": 1, "test": 1}


def tiny_config(**overrides: object) -> Config:
    """Three procedural classes, 5 models each, a handful of small views."""
    data: dict = {
        "seed": 3,
        "dataset": {"classes": ["cup", "mug", "bicycle"], "split": SMALL_SPLIT},
        "camera": {"width": 40, "height": 30},
        "render": {"views": 6},
        "viewpoints": {"count": 16},
    }
    for key, value in overrides.items():
        data[key] = value
    return config_from_dict(data)


#: The smallest settings under which every stage, from rendering to the closed loop, still
#: produces meaningful artefacts (a few seconds per stage).
TINY_PIPELINE: dict = {
    "camera": {"width": 64, "height": 48},
    "render": {"views": 12},
    "train": {"width": 0.125, "epochs": 2, "batch_size": 16,
              "preprocess": {"input_size_px": 32}},
    "saliency": {"iterations": 5},
    "volume": {"resolution": 12},
    "vptree": {"branching": 4, "levels": 2},
    "observe": {"crossfit_epochs": 1},
}


@pytest.fixture
def config() -> Config:
    return tiny_config()


@pytest.fixture
def workspace_dir(tmp_path: Path) -> Path:
    return tmp_path / "ws"
