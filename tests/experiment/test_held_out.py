"""The held-out closed loop and the declared confidence fitted at its stops, on a tiny
three-class workspace with two volume models a class (two groups to hold out)."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.cli import run_summary_lines
from rapomdp.config import METHOD_NAMES, Config, config_from_dict
from rapomdp.context import RunContext
from rapomdp.data.dataset import class_ranks, load_dataset
from rapomdp.experiment.evaluation import ClosedLoop
from rapomdp.experiment.held_out import (
    DECLARED_FIT_FILE,
    HELD_OUT_DIR,
    HELD_OUT_STARTS,
    NOT_HELD_OUT,
    HeldOutRun,
    HeldOutStops,
    closed_loop_declared,
    closed_loop_skipped,
    held_out_comparison,
    held_out_folds,
    held_out_runs,
    load_declared_fit,
    load_held_out_comparison,
)
from rapomdp.experiment.report import held_out_comparison_cells, held_out_comparison_story
from rapomdp.experiment.report_awareness import closed_loop_cells
from rapomdp.io import read_json
from rapomdp.pipeline import get_stage, run_pipeline
from rapomdp.planning.stage import declared_temperatures
from rapomdp.recognition.artefacts import load_volume_probabilities
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, StageInputs, Workspace
from tests.conftest import TEST_CONTEXT
from tests.experiment.conftest import LEARNED_TINY, TINY

POMDPS = ["vptree", "classifier", "ra"]
FITTED = [*POMDPS, "learned"]  # every method whose a the closed loop fits
HELD_OUT_TINY = {
    **TINY,
    "dataset": {**TINY["dataset"], "split": {"train": 3, "volume": 2, "test": 1}},
    "train": {**TINY["train"], "epochs": 8},  # a classifier whose labels differ by model
    "learn": LEARNED_TINY["learn"],
    "evaluate": {**TINY["evaluate"], "methods": ["random", *FITTED], "lambdas": [],
                 "random_thresholds": []},
}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> tuple[Workspace, Config]:
    config = config_from_dict(HELD_OUT_TINY)
    ws = Workspace(tmp_path_factory.mktemp("held-out"))
    run_pipeline(config, ws, context=TEST_CONTEXT)
    return ws, config


def _inputs(ws: Workspace) -> StageInputs:
    return ws.inputs(get_stage("evaluate"))


def test_each_method_holds_out_each_volume_group_and_reads_its_recorded_labels(workspace):
    ws, config = workspace
    folds = held_out_folds(config, _inputs(ws), POMDPS)
    dataset = load_dataset(ws.require("dataset"))
    volume = dataset.with_role("volume")
    ranks = class_ranks(volume)
    outputs = load_volume_probabilities(ws.require("classifier_eval"))
    test_files = {m.file for m in dataset.with_role("test")}
    assert test_files.isdisjoint(m.file for m in volume)
    for name in POMDPS:
        assert [f.group for f in folds[name]] == [0, 1], name
        for fold in folds[name]:
            mine = [m for m, g in zip(volume, ranks, strict=True) if g == fold.group]
            assert fold.labels.tolist() == [dataset.label(m) for m in mine]
            if name != "vptree":  # the classifier's labels of exactly this group's models
                expected = np.stack([outputs.of(m).argmax(axis=1) for m in mine])
                np.testing.assert_array_equal(fold.predicted, expected)
            assert np.allclose(fold.model.sum(axis=2), 1.0)
        # a fold's model is fitted without its group: the two folds' models differ
        assert not np.allclose(folds[name][0].model, folds[name][1].model), name
    assert closed_loop_skipped(config, "ra") == (
        "fewer than two held-out groups of volume models the trained classifier labelled "
        "(dataset.split.volume)")


def test_the_pomdps_declare_with_the_a_fitted_at_their_held_out_stops(workspace):
    ws, config = workspace
    summary = read_json(ws.require("evaluate") / "evaluate.json")
    assert summary["declared_fit"]["kind"] == "closed_loop"
    fits = summary["declared_fit"]["closed_loop"]
    record = read_json(ws.require("evaluate") / HELD_OUT_DIR / DECLARED_FIT_FILE)
    assert record["plans"] == "solve stage" and record["methods"] == fits
    assert record["walks_kept"] == {}
    reachable = int(load_robot(ws.require("robot"))["reachable"].sum())
    stops = 2 * 3 * min(HELD_OUT_STARTS, reachable)  # groups x classes x starts
    assert set(fits) == set(FITTED)
    for name, fit in fits.items():
        declared = fit["declared_confidence"]
        assert fit["episodes"] == declared["stops"] == stops, name
        assert declared["groups"] == [0, 1] and declared["thresholds"] == []
        assert 0.05 <= declared["temperature"] <= 2.0
        assert 0.0 <= fit["accuracy"] <= 1.0 and fit["energy"] >= 0.0
    a = {name: fit["declared_confidence"]["temperature"] for name, fit in fits.items()}
    loop = ClosedLoop.load(config, _inputs(ws), declared_fit=a)
    for name in FITTED:
        assert loop.methods[name]._bayes.declared_temperature == a[name]
    # Random keeps the walks' a at its threshold
    offered = {config.evaluate.random.observation_model: None}
    walks = declared_temperatures(ws.require("observe"), offered, ws.require("vptree"),
                                  config.evaluate.random.belief_threshold)
    assert loop.methods["random"]._bayes.declared_temperature == \
        walks[config.evaluate.random.observation_model]
    # the evaluate stage's episodes report b ** a: the POMDPs' final confidences there are
    # those of the episodes rerun with the a (same actions, same beliefs before the report)
    model = loop.dataset.with_role("test")[0]
    saved = {(r.method, r.start): r for r in loop.run_model(model)}
    plain = ClosedLoop.load(config, _inputs(ws), declared_fit={name: 1.0 for name in FITTED})
    for episode_record in plain.run_model(model):
        if episode_record.method in FITTED:
            t = a[episode_record.method]
            b = episode_record.episode.beliefs ** t
            assert np.allclose(saved[(episode_record.method, episode_record.start)].episode.beliefs,
                               b / b.sum(axis=1, keepdims=True))


def test_the_fit_does_not_depend_on_the_number_of_workers(workspace, tmp_path):
    ws, config = workspace
    record = read_json(ws.require("evaluate") / HELD_OUT_DIR / DECLARED_FIT_FILE)
    fits = closed_loop_declared(config, _inputs(ws), FITTED, tmp_path,
                                RunContext(workers=2, progress=False))
    for name, fit in fits.items():
        assert fit.to_dict() == record["methods"][name], name


def test_a_model_without_held_out_folds_keeps_the_walks_a_and_the_record_says_why(
        workspace, tmp_path, monkeypatch):
    """The observe stage's folds withheld (as with one volume group): the VP-tree's own are
    run."""
    from rapomdp.experiment import held_out

    ws, config = workspace
    folds = held_out.held_out_folds

    def without_ra(*args, **kwargs):  # type: ignore[no-untyped-def]
        return {name: (f if name == "vptree" else []) for name, f in folds(*args,
                                                                             **kwargs).items()}

    monkeypatch.setattr(held_out, "held_out_folds", without_ra)
    fits = closed_loop_declared(config, _inputs(ws), ["ra", "vptree"], tmp_path)
    assert set(fits) == {"vptree"}  # the VP-tree's folds do not depend on the observe stage's
    record = read_json(tmp_path / DECLARED_FIT_FILE)
    assert record["walks_kept"] == {"ra": closed_loop_skipped(config, "ra")}


def test_a_method_the_solve_stage_did_not_solve_is_named(workspace, tmp_path):
    ws, config = workspace
    inputs = _inputs(ws)
    empty = StageInputs("evaluate", dataset_dir=inputs.dataset_dir, observe_dir=inputs.observe,
                        vptree_dir=inputs.vptree_dir, robot_dir=inputs.robot,
                        solve_dir=tmp_path / "solve")
    with pytest.raises(StageError, match="method 'ra' needs policy_ra.npz from the solve "
                                         "stage for its held-out closed loop"):
        closed_loop_declared(config, empty, ["ra"], tmp_path / "held_out")


def test_one_volume_group_leaves_every_method_the_walks_a(pipeline_workspace, tmp_path):
    ws, config = pipeline_workspace  # one volume model a class: no group can be held out
    assert config.dataset.split.volume == 1
    assert closed_loop_declared(config, ws.inputs(get_stage("evaluate")), POMDPS,
                                tmp_path / "held_out") == {}
    assert not (tmp_path / "held_out").exists()
    # nor is there a held-out comparison: the stage writes none and the report shows none
    assert load_held_out_comparison(ws.require("evaluate")) is None
    assert "What held-out objects say" not in (ws.require("report") / "report.md").read_text()


def test_the_report_shows_the_closed_loop_fit_and_says_what_was_reported(workspace):
    ws, _ = workspace
    record = load_declared_fit(ws.require("evaluate"))
    header, rows = closed_loop_cells(record)
    assert header[:2] == ["Method", "a"] and len(rows) == len(FITTED)
    for row in rows:
        key = next(k for k in FITTED if METHOD_NAMES[k] == row[0])
        fit = record["methods"][key]
        assert row[1] == f"{fit['declared_confidence']['temperature']:.3f}"
        assert row[-1] == str(fit["episodes"])
        floor = fit["declared_confidence"]["declared_ece_if_calibrated"]
        assert 0.0 < floor < 1.0 and row[-2] == f"{floor:.3f}"
    report = (ws.require("report") / "report.md").read_text()
    assert "The POMDP methods' and the learned baseline's declared confidence, fitted at " \
           "their own held-out closed-loop stops: each volume group's models" in report
    assert "the others' where their own held-out closed loop stops" in report
    assert rows[0][1] in report


def test_every_method_runs_on_the_held_out_objects_paired_with_ra(workspace):
    ws, config = workspace
    record = load_held_out_comparison(ws.require("evaluate"))
    reachable = int(load_robot(ws.require("robot"))["reachable"].sum())
    episodes = 2 * 3 * min(HELD_OUT_STARTS, reachable)  # groups x classes x starts
    assert record["reference"] == "ra" and record["unpaired"] == [] and record["skipped"] == {}
    # the learned baseline trained on these objects' labels: its loop is not held out for it
    assert record["not_held_out"] == {"learned": NOT_HELD_OUT["learned"]}
    assert set(record["methods"]) == set(config.evaluate.methods) - {"learned"}
    for row in record["methods"].values():
        assert row["episodes"] == episodes and row["objects"] == 2 * 3
    # the declared confidence is fitted on these same episodes
    fits = read_json(ws.require("evaluate") / HELD_OUT_DIR / DECLARED_FIT_FILE)["methods"]
    for name in POMDPS:
        assert record["methods"][name]["accuracy"] == fits[name]["accuracy"], name
    assert set(record["paired"]) == set(config.evaluate.methods) - {"ra", "learned"}
    for name, paired in record["paired"].items():  # the same pairs: a difference of means
        assert paired["difference"] == pytest.approx(
            record["methods"][name]["accuracy"] - record["methods"]["ra"]["accuracy"])
        assert paired["low"] <= paired["difference"] <= paired["high"]
        assert paired["pairs"] == episodes and paired["objects"] == 2 * 3
    report = (ws.require("report") / "report.md").read_text()
    assert held_out_comparison_story(record) in report
    assert held_out_comparison_story(record).endswith(
        " Learned (PPO) is not compared: the learn stage trained it on these objects' recorded "
        "labels, so its episodes here are not held out.")
    assert "What held-out objects say, before any test model is read" in report
    # and the lines that end a run say it too
    assert ("held out, the forecast made before any test model was read: "
            + held_out_comparison_story(record)) in run_summary_lines(ws.root, 1.0, (0.1, 0.0))


def test_static_declares_its_start_views_label_on_the_held_out_objects(workspace, tmp_path):
    ws, config = workspace
    runs, skipped = held_out_runs(config, _inputs(ws), ["static", "ra"])
    assert skipped == {}
    static, ra = runs["static"], runs["ra"]
    label_at = {(f.group, int(c)): f.predicted[r]
                for f in held_out_folds(config, _inputs(ws), ["ra"])["ra"]
                for r, c in enumerate(f.labels)}
    expected = [label_at[(int(g), int(c))][s] == c for g, c, s in
                zip(static.groups, static.stops.truth, static.stops.starts, strict=True)]
    np.testing.assert_array_equal(static.stops.correct, expected)
    assert np.all(static.stops.energy == 0) and np.all(static.stops.images == 1)
    np.testing.assert_array_equal(static.pairs(), ra.pairs())  # the same starts


def _run(groups: list[int], truth: list[int], starts: list[int], correct: list[int]
         ) -> HeldOutRun:
    n = len(truth)
    return HeldOutRun(HeldOutStops(np.zeros((n, 2)), np.array(truth), np.array(correct, bool),
                                   np.ones(n), np.ones(n, dtype=int), np.array(starts)),
                      np.array(groups))


def test_the_comparison_pairs_by_object_and_start_whatever_the_order():
    ra = _run([0, 0, 1, 1], [0, 1, 0, 1], [5, 6, 5, 6], [1, 1, 0, 1])
    reordered = _run([1, 1, 0, 0], [1, 0, 1, 0], [6, 5, 6, 5], [1, 1, 1, 1])
    other_start = _run([0, 0, 1, 1], [0, 1, 0, 1], [7, 6, 5, 6], [1, 1, 1, 1])
    record = held_out_comparison({"ra": ra, "random": reordered, "vptree": other_start})
    assert record["methods"]["ra"] == {"accuracy": 0.75, "energy_m": 1.0, "episodes": 4,
                                       "objects": 4}
    assert record["unpaired"] == ["vptree"]
    paired = record["paired"]["random"]
    assert paired["difference"] == pytest.approx(0.25)
    assert (paired["pairs"], paired["objects"]) == (4, 4)
    # resampling the 4 objects: the one RA got wrong is drawn 0 times with p = 0.32 and 4 times
    # with p = 0.004 < 0.025 < p(3 or more) = 0.051
    assert paired["low"] == 0.0 and paired["high"] == pytest.approx(0.75)
    assert paired["per_object"] == {"objects": ["0/0", "0/1", "1/0", "1/1"],
                                    "sums": [0.0, 0.0, 1.0, 0.0], "pairs": [1, 1, 1, 1]}
    assert record["order"] == ["ra", "random", "vptree"]


def test_without_ra_held_out_the_comparison_says_why(workspace, tmp_path, monkeypatch):
    from rapomdp.experiment import held_out

    ws, config = workspace
    folds = held_out.held_out_folds

    def without_ra(*args, **kwargs):  # type: ignore[no-untyped-def]
        return {name: (f if name == "vptree" else []) for name, f in folds(*args,
                                                                             **kwargs).items()}

    monkeypatch.setattr(held_out, "held_out_folds", without_ra)
    runs, skipped = held_out_runs(config, _inputs(ws), ["random", "ra", "vptree"])
    assert set(runs) == {"vptree"} and set(skipped) == {"random", "ra"}
    record = held_out_comparison(runs, skipped=skipped)
    assert record["paired"] == {} and list(record["methods"]) == ["vptree"]
    assert held_out_comparison_story(record) == (
        "RA-POMDP has no held-out closed loop to pair the others with: fewer than two "
        "held-out groups of volume models the trained classifier labelled "
        "(dataset.split.volume).")


def test_the_comparison_story_says_where_the_intervals_leave_zero():
    record = {"reference": "ra", "methods": {},
              "paired": {"static": {"difference": -0.1, "low": -0.15, "high": -0.05,
                                    "pairs": 48, "objects": 12},
                         "random": {"difference": 0.02, "low": -0.03, "high": 0.07,
                                    "pairs": 48, "objects": 12}}, "unpaired": []}
    assert held_out_comparison_story(record) == (
        "On the 12 held-out objects, with 95 % intervals that resample them, RA-POMDP is more "
        "accurate than Static (by 0.100); not distinguishable from Random.")
    record["methods"] = {"ra": {"accuracy": 0.5, "energy_m": 1.25, "episodes": 48},
                         "static": {"accuracy": 0.4, "energy_m": 0.0, "episodes": 48},
                         "vptree": {"accuracy": 0.3, "energy_m": 2.0, "episodes": 40}}
    header, rows = held_out_comparison_cells(record)
    assert header[3] == "Δ accuracy vs RA-POMDP [95 %, held-out objects]"
    assert rows == [["RA-POMDP", "0.500", "1.25", "—", "48"],
                    ["Static", "0.400", "0.00", "-0.100 [-0.150, -0.050]", "48"],
                    ["VP-tree", "0.300", "2.00", "not paired", "40"]]
