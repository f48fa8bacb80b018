"""The evaluate stage end to end on a tiny three-class workspace."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from rapomdp.experiment import evaluation
from rapomdp.experiment.evaluation import ClosedLoop, EpisodeTable, start_viewpoints
from rapomdp.io import read_json
from rapomdp.workspace import Workspace
from tests.conftest import remote_references
from tests.experiment.conftest import METHODS


@pytest.fixture(scope="module")
def workspace(pipeline_workspace):
    return pipeline_workspace


def _inputs(ws: Workspace) -> dict:
    return {name: ws.require(name) for name in ("dataset", "train", "observe", "vptree", "robot",
                                              "solve")}


def test_table1_has_every_method_and_consistent_episodes(workspace) -> None:
    ws, config = workspace
    out = ws.require("evaluate")
    table = EpisodeTable.load(out / "episodes.npz")
    assert table.methods == METHODS
    assert table.method.size == 3 * 3 * len(METHODS)  # classes x starts x methods
    lines = (out / "table1.md").read_text().strip().splitlines()
    assert [line.split("|")[1].strip() for line in lines[2:]] == [
        "Static", "Random", "VP-tree", "Classifier", "RA-POMDP"]
    robot = np.load(ws.require("robot") / "robot.npz")
    for i in range(table.method.size):
        views = table.viewpoints_of(i)
        assert robot["reachable"][views].all()
        assert table.moves[i] == views.size - 1 <= 6
        assert table.energy[i] == pytest.approx(robot["energy"][views[:-1], views[1:]].sum())
        assert table.correct[i] == (table.declared[i] == table.class_index[i])
        beliefs = table.step_beliefs[table.offsets[i]:table.offsets[i + 1]]
        assert np.allclose(beliefs.sum(axis=1), 1.0)
    assert (table.moves[table.method == "static"] == 0).all()
    info = read_json(out / "evaluate.json")
    assert info["episodes"] == table.method.size and info["images"] == table.offsets[-1]
    assert info["figure_class"] == "bicycle"
    for name in ("fig3.png", "trajectories.png", "per_class.md", "episodes.csv", "table1.csv"):
        assert (out / name).stat().st_size > 0


def test_static_accuracy_is_the_single_view_accuracy_at_the_same_starts(workspace) -> None:
    ws, config = workspace
    loop = ClosedLoop.load(config, _inputs(ws))
    table = EpisodeTable.load(ws.require("evaluate") / "episodes.npz")
    right = []
    for model in loop.dataset.with_role("test"):
        scene = loop.scene(model)
        starts = start_viewpoints(config.seed, model, loop.motion.reachable, 3)
        depth = scene.renderer.render(scene.poses[starts])
        predicted = loop.recognisers["cnn"].predict(depth).argmax(axis=1)
        right.extend(predicted == loop.dataset.label(model))
    static = table.method == "static"
    assert table.correct[static].mean() == pytest.approx(np.mean(right))
    assert table.correct[static].tolist() == right


def test_actions_do_not_depend_on_the_label(workspace) -> None:
    ws, config = workspace
    loop = ClosedLoop.load(config, _inputs(ws))
    model = loop.dataset.with_role("test")[1]
    others = [c for c in loop.dataset.classes if c != model.class_name]
    relabelled = dataclasses.replace(model, class_name=others[0])
    original, permuted = loop.run_model(model), loop.run_model(relabelled)
    for a, b in zip(original, permuted, strict=True):
        assert a.method == b.method and a.start == b.start
        assert a.episode.actions == b.episode.actions
        assert np.array_equal(a.episode.beliefs, b.episode.beliefs)


def test_same_seed_same_table_and_workers_do_not_matter(workspace, tmp_path) -> None:
    ws, config = workspace
    first = (ws.require("evaluate") / "table1.md").read_text()
    records, dataset = evaluation.run_episodes(config, _inputs(ws), processes=2)
    again = EpisodeTable.from_records(records, dataset, METHODS)
    saved = EpisodeTable.load(ws.require("evaluate") / "episodes.npz")
    assert np.array_equal(again.step_viewpoints, saved.step_viewpoints)
    assert np.array_equal(again.correct, saved.correct)
    ws.run(evaluation_stage(), config, force=True)
    assert (ws.require("evaluate") / "table1.md").read_text() == first


def evaluation_stage():
    from rapomdp.pipeline import get_stage

    return get_stage("evaluate")


def test_cli_prints_table1_from_the_cached_stage(workspace, tmp_path) -> None:
    from typer.testing import CliRunner

    from rapomdp.cli import app

    ws, config = workspace
    path = tmp_path / "tiny.yaml"
    path.write_text(config.to_yaml())
    result = CliRunner().invoke(app, ["evaluate", "-w", str(ws.root), "-c", str(path)])
    assert result.exit_code == 0, result.output
    assert "evaluate   cached" in result.output
    assert "| RA-POMDP |" in result.output and "Table 1" in result.output
    bad = tmp_path / "bad.yaml"
    bad.write_text("evaluate: {methods: [static, oracle]}\n")
    result = CliRunner().invoke(app, ["evaluate", "-w", str(ws.root), "-c", str(bad)])
    assert result.exit_code == 2 and "unknown method(s) ['oracle']" in result.output


def test_every_html_the_pipeline_writes_works_offline(workspace) -> None:
    """The whole pipeline (report included) writes HTML that fetches nothing: plotly.js is
    inside each interactive figure, and the report links them by relative path."""
    ws, _ = workspace
    pages = sorted(ws.root.rglob("*.html"))
    names = {p.name for p in pages}
    assert {"report.html", "fig1_bicycle.html"} <= names
    for page in pages:
        text = page.read_text()
        assert remote_references(text) == [], page
        assert not re.search(r"<script[^>]*\bsrc=", text), page
    report = (ws.root / "report" / "report.html").read_text()
    assert '<a href="fig1_bicycle.html">' in report
    assert (ws.root / "report" / "fig1_bicycle.html").stat().st_size > 1_000_000
