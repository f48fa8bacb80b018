"""A tiny finished workspace whose RA-POMDP moves (two volume and two test models a class, a
classifier between chance and perfect), and its headroom decomposition, built once a session."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapomdp.config import Config, config_from_dict
from rapomdp.pipeline import run_pipeline
from rapomdp.study.headroom import HeadroomResult, run_headroom
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT, TINY_PIPELINE

#: Three classes, 2 volume models a class (a held-out temperature), 2 test models a class (a
#: cross-object split), only RA-POMDP evaluated.
TINY_STUDY = {
    **TINY_PIPELINE,
    "seed": 5,
    "dataset": {"classes": ["cup", "bicycle", "teapot"],
                "split": {"train": 3, "volume": 2, "test": 2}},
    "train": {**TINY_PIPELINE["train"], "epochs": 3},
    "viewpoints": {"count": 16},
    "solve": {"timeout_s": 2.0, "models": ["ra"]},
    "evaluate": {"methods": ["ra"], "starts_per_model": 3, "max_moves": 6, "lambdas": []},
}


def _files(root: Path, skip: str) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` but ``skip``: (size, mtime in ns) by relative path."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.is_file() and skip not in p.relative_to(root).parts}


@pytest.fixture(scope="session")
def headroom_run(tmp_path_factory: pytest.TempPathFactory
                 ) -> tuple[Workspace, Config, HeadroomResult, dict[str, tuple[int, int]],
                            dict[str, tuple[int, int]]]:
    """The workspace, its configuration, the decomposition into ``W/headroom/`` and the
    workspace's other files before and after it."""
    config = config_from_dict(TINY_STUDY)
    ws = Workspace(tmp_path_factory.mktemp("study"))
    run_pipeline(config, ws, context=TEST_CONTEXT)
    before = _files(ws.root, "headroom")
    result = run_headroom(ws, context=TEST_CONTEXT)
    return ws, config, result, before, _files(ws.root, "headroom")
