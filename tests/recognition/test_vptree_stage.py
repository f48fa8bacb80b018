"""The vptree stage: the VP-tree baseline fitted, its observation model and summary, the CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TEST_STREAM
from rapomdp.io import load_npz, read_json
from rapomdp.pipeline import run_pipeline
from rapomdp.recognition.vptree_stage import load_workspace_vptree, xrho_predictions
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT, tiny_config


def test_vptree_stage_writes_a_normalised_observation_model(tmp_path: Path) -> None:
    config = tiny_config(vptree={"branching": 4, "levels": 2})
    workspace = Workspace(tmp_path / "ws")
    results = run_pipeline(config, workspace, until="vptree", context=TEST_CONTEXT)
    assert [r.name for r in results] == ["dataset", "render", "vptree"]
    stage = workspace.root / "vptree"
    model = load_npz(stage / "observation_model.npz")
    classes = ["cup", "mug", "bicycle"]
    assert [str(c) for c in model["classes"]] == classes
    p = model["vptree"]
    assert p.shape == (16, 3, 3) and np.all(p > 0)
    np.testing.assert_allclose(p.sum(axis=2), 1.0, atol=1e-9)
    summary = read_json(stage / "vptree.json")
    assert summary["classes"] == classes and summary["leaves"] == 16
    assert summary["train_images"] == 3 * 3 * 6  # 3 classes x 3 train models x 6 views
    assert 0.0 <= summary["accuracy_test_xrho"] <= 1.0
    assert set(summary["seconds"]) >= {"fit", "observation_model", "test", "total"}
    classifier = load_workspace_vptree(stage)
    assert classifier.classes == classes and classifier.tree.leaves == 16
    # the models at X_rho over two worker processes: the labels of one process
    dataset = load_dataset(workspace.root / "dataset")
    models = dataset.with_role("test") + dataset.with_role("volume")
    alone = xrho_predictions(classifier, dataset, models, config, TEST_STREAM, "", False)
    shared = xrho_predictions(classifier, dataset, models, config, TEST_STREAM, "", False, 2)
    assert alone[1].shape == (len(models), 16)
    assert all(np.array_equal(a, b) for a, b in zip(alone, shared, strict=True))
    # one volume model per class at 16 viewpoints and pseudo-count a: n(c, x) = 1, so each
    # row is (1 + a) / (1 + 3a) on the label seen and a / (1 + 3a) elsewhere
    a = config.vptree.pseudo_count
    np.testing.assert_allclose(p.max(axis=2), (1 + a) / (1 + 3 * a))
    # the command line: cached now, and it prints the accuracy
    config_path = tmp_path / "tiny.yaml"
    config_path.write_text(config.to_yaml())
    result = CliRunner().invoke(app, ["vptree", "-w", str(workspace.root), "-c",
                                      str(config_path)])
    assert result.exit_code == 0, result.output
    assert "vptree" in result.output and "cached" in result.output
    shown = f"test models at X_rho: {summary['accuracy_test_xrho']:.1%}"
    assert shown in " ".join(result.output.split())
