"""Shared fixtures: one thread and no progress bars in every awareness test."""

from __future__ import annotations

import pytest
import torch

from rapomdp.progress import set_progress


@pytest.fixture(autouse=True)
def _quiet_single_thread():
    set_progress(False)
    torch.set_num_threads(1)
    yield
    set_progress(True)
