"""The evaluate stage end to end on a tiny three-class workspace."""

from __future__ import annotations

import csv
import dataclasses
import re

import numpy as np
import pytest

from rapomdp.context import RunContext
from rapomdp.experiment import evaluation
from rapomdp.experiment.episode import run_episode
from rapomdp.experiment.episode_table import EpisodeTable
from rapomdp.experiment.evaluation import ClosedLoop, start_viewpoints
from rapomdp.io import read_json
from rapomdp.workspace import StageInputs, Workspace
from tests.conftest import TEST_CONTEXT, remote_references
from tests.experiment.conftest import METHODS


@pytest.fixture(scope="module")
def workspace(pipeline_workspace):
    return pipeline_workspace


def _inputs(ws: Workspace) -> StageInputs:
    from rapomdp.pipeline import get_stage

    return ws.inputs(get_stage("evaluate"))


def test_table1_has_every_method_and_consistent_episodes(workspace) -> None:
    ws, config = workspace
    out = ws.require("evaluate")
    table = EpisodeTable.load(out / "episodes.npz")
    assert table.methods == METHODS
    assert table.method.size == 3 * 3 * len(METHODS)  # classes x starts x methods
    lines = [line for line in (out / "table1.md").read_text().splitlines()
             if line.startswith("|")]
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


def test_every_method_runs_from_the_same_pairs_and_table1_pairs_them(workspace) -> None:
    ws, _ = workspace
    out = ws.require("evaluate")
    table = EpisodeTable.load(out / "episodes.npz")
    pairs = {m: sorted(zip(table.model[table.method == m], table.start[table.method == m],
                           strict=True)) for m in METHODS}
    assert all(pairs[m] == pairs["static"] for m in METHODS)
    assert len(set(pairs["static"])) == 3 * 3  # distinct (test model, start) pairs
    rows = (out / "paired.csv").read_text().splitlines()
    assert rows[0].startswith("method,reference,accuracy_difference")
    ra = table.correct[table.method == "ra"].mean()
    for row in rows[1:]:
        method, reference, diff, low, high, n, models = row.split(",")
        assert reference == "ra" and int(n) == 9 and int(models) == 3
        assert float(diff) == pytest.approx(table.correct[table.method == method].mean() - ra,
                                            abs=1e-5)
        assert float(low) <= float(diff) + 1e-9 <= float(high) + 2e-9
    assert [r.split(",")[0] for r in rows[1:]] == ["static", "random", "vptree", "classifier"]
    assert "Δ accuracy vs RA-POMDP" in (out / "table1.md").read_text()


def test_the_sweep_writes_one_curve_per_method_with_one_point_per_setting(workspace) -> None:
    ws, config = workspace
    out = ws.require("evaluate")
    with open(out / "tradeoff.csv") as handle:
        rows = list(csv.DictReader(handle))
    curves: dict[str, list[float]] = {}
    for row in rows:
        curves.setdefault(row["method"], []).append(float(row["value"]))
    assert list(curves) == METHODS
    assert curves["static"] == [0.0]
    assert curves["random"] == [0.6, 0.9]  # the sweep's stop belief and Table 1's
    for method in ("vptree", "classifier", "ra"):
        assert curves[method] == [1.0, 2.0, 6.0, 8.0]  # one point per λ and Table 1's (8)
        assert (out / "sweep" / "lambda_6" / f"policy_{method}.npz").exists()
    assert not (out / "sweep" / "lambda_8").exists()  # Table 1's policies are the solve stage's
    # Table 1's points are its rows; every point ran from all (test model, start) pairs
    with open(out / "table1.csv") as handle:
        table = {r["method"]: r for r in csv.DictReader(handle)}
    for row in rows:
        assert int(row["episodes"]) == 9
        if row["configured"] == "1":
            assert row["accuracy"] == table[row["method"]]["accuracy"]
            assert row["energy"] == table[row["method"]]["energy"]
    assert sum(r["configured"] == "1" for r in rows) == len(METHODS)
    assert (out / "tradeoff.png").stat().st_size > 0
    assert "λ = 6 m" in (out / "tradeoff.md").read_text()


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


def test_stored_outputs_give_the_episodes_of_a_render_and_classify_per_look(
        workspace) -> None:
    ws, config = workspace
    assert not config.render.noise.enabled  # the stage then reads the stored X_rho outputs
    loop = ClosedLoop.load(config, _inputs(ws))
    assert loop.stored is not None and set(loop.stored) == {"cnn", "vptree"}
    for model in loop.dataset.with_role("test")[:2]:
        scene = loop.scene(model)
        records = loop.run_model(model)
        assert len(records) == 3 * len(loop.methods)
        for record in records:
            method = loop.methods[record.method]
            # every output is the one classifier_eval (CNN) or vptree stored for that view
            stored = loop.stored[method.recogniser].of(model)
            assert np.array_equal(record.episode.outputs, stored[record.episode.viewpoints])
            rng = evaluation.episode_rng(config.seed, model, record.start, record.method)
            alone = run_episode(scene, loop.recognisers[method.recogniser], method, loop.motion,
                                record.start, config.evaluate.max_moves, rng)
            # the same moves and declaration as rendering and classifying one image per look;
            # a batch of images rounds the CNN's output differently in the last bits only
            for name in ("viewpoints", "move_energy"):
                assert np.array_equal(getattr(alone, name), getattr(record.episode, name))
            assert alone.declared == record.episode.declared
            for name in ("outputs", "beliefs"):
                np.testing.assert_allclose(getattr(alone, name),
                                           getattr(record.episode, name), atol=1e-5)
            if method.recogniser == "vptree":  # the VP-tree's output is the same bits
                assert np.array_equal(alone.outputs, record.episode.outputs)


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


def test_the_pomdp_methods_look_ahead_over_the_reachable_viewpoints(workspace) -> None:
    from rapomdp.experiment.methods import POMDPPolicy

    ws, config = workspace
    reachable = np.load(ws.require("robot") / "robot.npz")["reachable"]
    assert 0 < reachable.sum() < reachable.size
    loop = ClosedLoop.load(config, _inputs(ws))
    pomdps = [k for k, m in loop.methods.items() if isinstance(m, POMDPPolicy)]
    assert sorted(pomdps) == ["classifier", "ra", "vptree"]
    for key in pomdps:
        assert np.array_equal(loop.methods[key].lookahead_over, reachable)


def test_same_seed_same_table_and_workers_do_not_matter(workspace, tmp_path) -> None:
    ws, config = workspace
    first = (ws.require("evaluate") / "table1.md").read_text()
    records, dataset = evaluation.run_episodes(config, _inputs(ws),
                                             RunContext(workers=2, progress=False))
    again = EpisodeTable.from_records(records, dataset, METHODS)
    saved = EpisodeTable.load(ws.require("evaluate") / "episodes.npz")
    assert np.array_equal(again.step_viewpoints, saved.step_viewpoints)
    assert np.array_equal(again.correct, saved.correct)
    ws.run(evaluation_stage(), config, force=True, context=TEST_CONTEXT)
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
    assert "Table 1 (closed-loop episodes on the test models)" in result.output
    rows = [line.split()[0] for line in result.output.splitlines() if line.strip()]
    assert {"Static", "RA-POMDP"} <= set(rows)  # Table 1's rows, a table on the console
    bad = tmp_path / "bad.yaml"
    bad.write_text("evaluate: {methods: [static, oracle]}\n")
    result = CliRunner().invoke(app, ["evaluate", "-w", str(ws.root), "-c", str(bad)])
    assert result.exit_code == 2 and "unknown method(s) ['oracle']" in result.output


def test_episodes_on_a_dask_cluster_are_the_local_pools(workspace) -> None:
    """Issue 13.6: the evaluation's tasks on a Dask LocalCluster give identical episodes."""
    distributed = pytest.importorskip("distributed")
    ws, config = workspace
    saved = EpisodeTable.load(ws.require("evaluate") / "episodes.npz")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        on_dask = dataclasses.replace(TEST_CONTEXT, scheduler=cluster.scheduler_address)
        records, dataset = evaluation.run_episodes(config, _inputs(ws), on_dask)
        from typer.testing import CliRunner

        from rapomdp.cli import app

        table = (ws.require("evaluate") / "table1.md").read_text()
        # the CLI's --scheduler: the forced stage on the cluster writes the same table
        result = CliRunner().invoke(app, ["evaluate", "-w", str(ws.root), "--force",
                                          "--scheduler", cluster.scheduler_address])
        assert result.exit_code == 0, result.output
        assert (ws.require("evaluate") / "table1.md").read_text() == table
    remote = EpisodeTable.from_records(records, dataset, METHODS)
    compared = [f.name for f in dataclasses.fields(EpisodeTable) if "seconds" not in f.name]
    assert len(compared) >= 10  # every field but the measured planning time
    for name in compared:
        a, b = getattr(remote, name), getattr(saved, name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
        else:
            assert a == b, name


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


def test_run_and_demo_end_with_the_report_who_won_the_wall_time_and_memory(
        workspace, tmp_path) -> None:
    """`rapomdp run` and `rapomdp demo` (on a copy of the cached tiny workspace) end with the
    report's path, its story of who won and the paired intervals, the wall time and memory."""
    import shutil

    from typer.testing import CliRunner

    from rapomdp.cli import _story, app

    runner = CliRunner()
    ws = Workspace(tmp_path / "ws")
    shutil.copytree(workspace[0].root, ws.root)
    result = runner.invoke(app, ["run", "-w", str(ws.root), "--threads", "1"],
                           env={"COLUMNS": "2000"})
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    tail = lines[lines.index(f"report: {ws.root / 'report' / 'report.html'}"):]
    story, paired, timing = tail[1:]
    assert [story, paired] == _story(ws)
    assert story.startswith("On this run ") and "with 95 % intervals" in story
    assert paired.startswith("accuracy minus RA-POMDP's over the same pairs [95 % interval]: "
                             "Static ")
    assert re.fullmatch(r"wall time \d+\.\d s, peak memory \d+ MB( \(its largest worker "
                        r"process \d+(\.\d)? [MG]B\))?|wall time .*GB.*", timing), timing
    assert "Table 1 (closed-loop episodes on the test models)" in result.output
    demo = runner.invoke(app, ["demo", "-w", str(ws.root), "--threads", "1"],
                         env={"COLUMNS": "2000"})
    assert demo.exit_code == 0, demo.output
    assert f"contact sheet written to {ws.root / 'contact_sheet.png'}" in demo.output
    assert (ws.root / "contact_sheet.png").read_bytes()[:4] == b"\x89PNG"
    assert demo.output.splitlines()[-3:-1] == [story, paired]


def test_calibrated_declarations_change_what_is_reported_and_no_action(workspace,
                                                                       monkeypatch) -> None:
    from rapomdp.experiment.methods import StaticPolicy

    ws, config = workspace
    # one volume model a class: no closed loop to fit on, every method keeps the walks' a
    assert read_json(ws.require("evaluate") / "evaluate.json")["declared_fit"] == {
        "kind": "closed_loop", "closed_loop": {}}
    # every a 1: the belief itself
    monkeypatch.setattr(evaluation, "declared_temperatures",
                        lambda observe, offered, vptree, stop_threshold=None:
                        dict.fromkeys(offered, 1.0))
    plain = ClosedLoop.load(config, _inputs(ws), sweep_dir=ws.require("evaluate") / "sweep")
    fitted = {"classifier": 0.5, "ra": 0.25, "vptree": 0.8}

    def fake(observe, offered, vptree, stop_threshold=None):  # Random: its threshold's a
        return {n: fitted.get(n, 1.0) if stop_threshold is None else stop_threshold / 2
                for n in offered}

    monkeypatch.setattr(evaluation, "declared_temperatures", fake)
    sweep = ws.require("evaluate") / "sweep"
    calibrated = ClosedLoop.load(config, _inputs(ws), sweep_dir=sweep)
    expected = {}
    for key, method in calibrated.methods.items():
        if isinstance(method, StaticPolicy):
            continue
        name = key.split("@")[0]
        expected[key] = (method.belief_threshold / 2 if name == "random" else fitted[name])
        assert method._bayes.declared_temperature == expected[key], key
        assert plain.methods[key]._bayes.declared_temperature == 1.0
    thresholds = {m.belief_threshold for k, m in calibrated.methods.items()
                  if k.startswith("random")}
    assert len(thresholds) == 1 + len(config.evaluate.random_thresholds)  # the sweep's too
    model = plain.dataset.with_role("test")[0]
    for a, b in zip(plain.run_model(model), calibrated.run_model(model), strict=True):
        assert a.method == b.method and a.episode.actions == b.episode.actions
        t = 1.0 if a.method == "static" else expected[a.method]
        tempered = a.episode.beliefs ** t
        assert np.allclose(b.episode.beliefs, tempered / tempered.sum(axis=1, keepdims=True))


def test_sweep_settings_from_the_evaluate_section_alone() -> None:
    from rapomdp.config import EvaluateConfig

    cfg = EvaluateConfig(methods=["static", "random", "ra", "learned"], lambdas=[2.0, 8.0, 2.0],
                         random_thresholds=[0.6, 0.9], random={"belief_threshold": 0.9})
    assert evaluation.sweep_settings(cfg, lambda_=8.0) == [
        ("ra", "lambda", 2.0, "lambda_2"), ("learned", "lambda", 2.0, None),
        ("random", "threshold", 0.6, None)]
    assert evaluation.sweep_settings(EvaluateConfig(methods=["static"]), 8.0) == []
