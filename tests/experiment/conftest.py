"""One tiny workspace with every stage run, shared by the evaluation and environment tests."""

from __future__ import annotations

import pytest

from rapomdp import parallel
from rapomdp.config import Config, config_from_dict
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Workspace
from tests.conftest import TINY_PIPELINE

METHODS = ["static", "random", "vptree", "classifier", "ra"]
#: Three classes, 16 test viewpoints (the Panda reaches some of them only), every method.
TINY = {
    **TINY_PIPELINE,
    "seed": 5,
    "dataset": {"classes": ["cup", "bicycle", "teapot"]},
    "viewpoints": {"count": 16},
    "solve": {"timeout_s": 2.0},
    "evaluate": {"methods": METHODS, "starts_per_model": 3, "max_moves": 6},
}


@pytest.fixture(scope="session")
def pipeline_workspace(tmp_path_factory: pytest.TempPathFactory) -> tuple[Workspace, Config]:
    """Every stage of :data:`TINY`, run once per session (with ``W/config.yaml``, as the CLI
    writes it)."""
    import torch

    from rapomdp.progress import set_progress
    from rapomdp.recognition import stage

    set_progress(False)
    torch.set_num_threads(1)
    previous, stage.threads = stage.threads, 1
    parallel.workers = 1
    config = config_from_dict(TINY)
    ws = Workspace(tmp_path_factory.mktemp("pipeline"))
    run_pipeline(config, ws)
    (ws.root / "config.yaml").write_text(config.to_yaml())
    yield ws, config
    stage.threads = previous
    parallel.workers = None
