"""Fixtures of the closed-loop tests: a scripted motion, and one tiny workspace with every stage
run, shared by the evaluation and environment tests."""

from __future__ import annotations

import pytest

from rapomdp.config import Config, config_from_dict
from rapomdp.experiment.episode import Motion
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Workspace
from tests.conftest import SMALL_SPLIT, TEST_CONTEXT, TINY_PIPELINE
from tests.experiment.scripted import scripted_motion

METHODS = ["static", "random", "vptree", "classifier", "ra"]
#: Three classes, 16 test viewpoints (the Panda reaches some of them only), every method.
TINY = {
    **TINY_PIPELINE,
    "seed": 5,
    "dataset": {"classes": ["cup", "bicycle", "teapot"], "split": SMALL_SPLIT},
    "viewpoints": {"count": 16},
    "solve": {"timeout_s": 2.0},
    "evaluate": {"methods": METHODS, "starts_per_model": 3, "max_moves": 6,
                 "lambdas": [1.0, 2.0, 6.0], "random_thresholds": [0.6]},
}


@pytest.fixture
def motion() -> Motion:
    return scripted_motion()


@pytest.fixture(scope="session")
def pipeline_workspace(tmp_path_factory: pytest.TempPathFactory) -> tuple[Workspace, Config]:
    """Every stage of :data:`TINY`, run once per session (``W/config.yaml`` recorded with the
    artefacts, as the CLI does)."""
    config = config_from_dict(TINY)
    ws = Workspace(tmp_path_factory.mktemp("pipeline"))
    run_pipeline(config, ws, context=TEST_CONTEXT)
    return ws, config


#: :data:`TINY` with the learned baseline: a few hundred PPO steps per λ (four λ: Table 1's 8
#: and the sweep's 1, 2, 6).
LEARNED_TIMESTEPS = 256
LEARNED_TINY = {**TINY,
                "evaluate": {**TINY["evaluate"], "methods": [*METHODS, "learned"]},
                "learn": {"timesteps": LEARNED_TIMESTEPS, "envs": 2, "rollout_steps": 32,
                          "batch_size": 32, "hidden": [16]}}


@pytest.fixture(scope="session")
def learned_workspace(pipeline_workspace, tmp_path_factory: pytest.TempPathFactory
                      ) -> tuple[Workspace, Config]:
    """:data:`LEARNED_TINY` run to the end, every stage before ``learn`` taken from
    :func:`pipeline_workspace` (same keys): only learn, evaluate and report run."""
    source, _ = pipeline_workspace
    config = config_from_dict(LEARNED_TINY)
    ws = Workspace(tmp_path_factory.mktemp("learned"))
    run_pipeline(config, ws, context=TEST_CONTEXT, share_from=[source])
    return ws, config
