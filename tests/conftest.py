"""Shared fixtures: a quiet single-threaded run context, one PyTorch thread, tiny configs."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from rapomdp.config import Config, config_from_dict
from rapomdp.context import QUIET, RunContext

#: The context of every test's stages: no progress bars, one thread, no worker processes (the
#: machine has 2 shared cores; the tests that check parallel runs ask for processes explicitly).
TEST_CONTEXT: RunContext = QUIET


@pytest.fixture(autouse=True)
def _single_torch_thread() -> None:
    """One PyTorch thread in every test, whatever an earlier test's classifier set."""
    torch.set_num_threads(1)


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
}


@pytest.fixture
def config() -> Config:
    return tiny_config()


@pytest.fixture
def workspace_dir(tmp_path: Path) -> Path:
    return tmp_path / "ws"


def remote_references(page: str) -> list[str]:
    """The ``src``/``href`` values of an HTML page's tags that point off the machine (a scheme
    such as http: or a protocol-relative //host). Script bodies are skipped: an embedded
    library's code holds URLs in strings that nothing fetches."""
    import re

    tags = re.sub(r"(<script\b[^>]*>).*?</script>", r"\1", page, flags=re.S | re.I)
    values = re.findall(r"""\b(?:src|href)\s*=\s*["']?([^"'\s>]+)""", tags, flags=re.I)
    return [v for v in values if re.match(r"^(?:[a-z][a-z0-9+.-]*:|//)", v, flags=re.I)
            and not v.lower().startswith(("data:", "#"))]
