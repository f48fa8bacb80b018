"""The headroom decomposition on a tiny finished workspace: the learned row is the evaluate
stage's RA-POMDP, the oracles are counted on what they claim (and the cross-object one never on
the episode's own object), and every output labels the oracle rows. One tiny workspace whose
RA-POMDP moves (two volume and two test models a class, a classifier between chance and
perfect), built once for the module."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from rapomdp.awareness.artefacts import OBSERVATION_FILE
from rapomdp.config import Config, config_from_dict
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import TestViews
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.metrics import table1
from rapomdp.io import load_npz
from rapomdp.pipeline import run_pipeline
from rapomdp.recognition.belief import (
    TEMPERATURE_BOUNDS,
    fit_temperature,
    held_out_walks,
    temper,
)
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.study.headroom import (
    CROSS_ROWS,
    HEADROOM_CSV,
    HEADROOM_DIR,
    HEADROOM_MD,
    ORACLE_NOTE,
    ROWS,
    HeadroomResult,
    HeadroomRow,
    cross_object_halves,
    headroom_csv,
    headroom_markdown,
    run_headroom,
    with_correct_probability,
)
from rapomdp.workspace import StageError, Workspace
from tests.conftest import TEST_CONTEXT, TINY_PIPELINE

#: Three classes, 2 volume models a class (a held-out temperature), 2 test models a class (a
#: cross-object split), only RA-POMDP evaluated.
TINY_HEADROOM = {
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


@pytest.fixture(scope="module")
def headroom_run(tmp_path_factory: pytest.TempPathFactory
                 ) -> tuple[Workspace, Config, HeadroomResult, dict[str, tuple[int, int]],
                            dict[str, tuple[int, int]]]:
    """The workspace, its configuration, the decomposition into ``W/headroom/`` and the
    workspace's other files before and after it."""
    config = config_from_dict(TINY_HEADROOM)
    ws = Workspace(tmp_path_factory.mktemp("headroom"))
    run_pipeline(config, ws, context=TEST_CONTEXT)
    before = _files(ws.root, "headroom")
    result = run_headroom(ws, context=TEST_CONTEXT)
    return ws, config, result, before, _files(ws.root, "headroom")


def _count(labels: np.ndarray, predicted: np.ndarray, classes: int, a: float) -> np.ndarray:
    """P(o | c, x) = (n + a) / (n + C a), counted by a plain loop."""
    n = np.zeros((predicted.shape[1], classes, classes))
    for c, row in zip(labels, predicted, strict=True):
        for x, o in enumerate(row):
            n[x, c, o] += 1
    return (n + a) / (n.sum(axis=2, keepdims=True) + classes * a)


def test_the_learned_row_is_the_evaluate_stages_ra_pomdp(headroom_run) -> None:
    ws, _, result, _, _ = headroom_run
    evaluated = EpisodeTable.load(ws.require("evaluate") / EPISODES_FILE)
    ra = table1(evaluated, ["ra"])[0]
    learned = result.rows[0]
    assert learned.name == "learned" and not learned.oracle
    assert learned.accuracy == ra.accuracy
    assert learned.energy_m == ra.means["energy"]
    assert learned.moves == ra.means["moves"]
    assert learned.episodes == ra.episodes == 2 * 3 * 3  # 6 test models x 3 starts
    assert result.evaluate_mismatches == 0
    mine = np.flatnonzero(result.table.method == "learned")
    theirs = np.flatnonzero(evaluated.method == "ra")
    assert np.array_equal(result.table.model[mine], evaluated.model[theirs])
    assert np.array_equal(result.table.start[mine], evaluated.start[theirs])
    assert np.array_equal(result.table.declared[mine], evaluated.declared[theirs])
    for i, j in zip(mine, theirs, strict=True):
        assert np.array_equal(result.table.viewpoints_of(i), evaluated.viewpoints_of(j))
    assert learned.moves > 0  # the fixture's RA-POMDP moves: the rows can differ


def test_every_row_runs_the_same_pairs(headroom_run) -> None:
    _, _, result, _, _ = headroom_run
    assert [r.name for r in result.rows] == list(ROWS)
    table = result.table
    pairs = {r: list(zip(table.model[table.method == r], table.start[table.method == r],
                         strict=True)) for r in ROWS}
    assert all(p == pairs["learned"] for p in pairs.values())


def test_the_in_sample_oracle_counts_the_test_renders_labels(headroom_run) -> None:
    ws, config, result, _, _ = headroom_run
    dataset = load_dataset(ws.require("dataset"))
    test = dataset.with_role("test")
    classifier = load_stage_classifier(config, ws.require("train"), dataset.classes, 1)
    rng = np.random.default_rng(0)  # noise is off: the renders draw nothing
    labels = np.array([dataset.label(m) for m in test])
    scenes = [TestViews.of_model(dataset, m, config.viewpoints, config.camera,
                                 config.render.noise) for m in test]
    predicted = np.stack([
        [int(classifier.predict(scene.look(v, rng)[None]).argmax())
         for v in range(config.viewpoints.count)] for scene in scenes])
    assert np.array_equal(result.labels, labels)
    assert np.array_equal(result.predicted, predicted)
    expected = _count(labels, predicted, len(dataset.classes),
                      config.observe.classifier_pseudo_count)
    np.testing.assert_allclose(result.models["oracle_in_sample"], expected, rtol=1e-12)
    assert result.counted_on["oracle_in_sample"] == tuple(m.file for m in test)
    assert set(result.assignment["oracle_in_sample"].values()) == {"oracle_in_sample"}


def test_the_cross_object_oracle_never_counts_the_episodes_object(headroom_run) -> None:
    ws, config, result, _, _ = headroom_run
    dataset = load_dataset(ws.require("dataset"))
    test = {m.file: m for m in dataset.with_role("test")}
    index = {f: i for i, f in enumerate(result.test_models)}
    for row in CROSS_ROWS:
        used = result.assignment[row]
        assert set(used) == set(test)
        for file, arm in used.items():
            counted = result.counted_on[arm]
            assert file not in counted
            # ... but every other test object of its class is (two a class: the other one)
            same_class = {f for f, m in test.items()
                          if m.class_name == test[file].class_name and f != file}
            assert same_class <= set(counted) and len(same_class) == 1
            # each half covers every class
            assert {test[f].class_name for f in counted} == set(dataset.classes)
        for arm, objects in table_episodes(result, row):  # the episodes as run
            assert not objects & set(result.counted_on[arm])
    # the halves' models are the counts on their own objects
    for h in (0, 1):
        on = [index[f] for f in result.counted_on[f"oracle_cross_object_h{h}"]]
        np.testing.assert_allclose(
            result.models[f"oracle_cross_object_h{h}"],
            _count(result.labels[on], result.predicted[on], len(dataset.classes),
                   config.observe.classifier_pseudo_count), rtol=1e-12)
    assert result.halves is not None and sorted(np.bincount(result.halves)) == [3, 3]


def table_episodes(result: HeadroomResult, row: str) -> list[tuple[str, set[str]]]:
    """(observation model, the test models whose episodes of ``row`` used it)."""
    out: dict[str, set[str]] = {}
    for model in result.table.model[result.table.method == row]:
        out.setdefault(result.assignment[row][str(model)], set()).add(str(model))
    return sorted(out.items())


def test_oracle_p_correct_rows_keep_the_learned_wrong_labels(headroom_run) -> None:
    _, _, result, _, _ = headroom_run
    single = temper(result.models["learned"], 1.0 / result.learned_temperature)
    c = single.shape[1]
    idx = np.arange(c)
    wrong = ~np.eye(c, dtype=bool)
    for oracle, mixed in (("oracle_in_sample", "oracle_correct_in_sample"),
                          ("oracle_cross_object_h0", "oracle_correct_cross_object_h0"),
                          ("oracle_cross_object_h1", "oracle_correct_cross_object_h1")):
        # as evaluated: the learned temperature on top
        p = temper(result.models[mixed], 1.0 / result.learned_temperature)
        np.testing.assert_allclose(p.sum(axis=2), 1.0, atol=1e-12)
        np.testing.assert_allclose(p[:, idx, idx], result.models[oracle][:, idx, idx],
                                   rtol=1e-12)
        shares = p / (1 - p[:, idx, idx])[:, :, None]
        learned = single / (1 - single[:, idx, idx])[:, :, None]
        np.testing.assert_allclose(shares[:, wrong], learned[:, wrong], rtol=1e-9)
        assert result.counted_on[mixed] == result.counted_on[oracle]


def test_the_oracle_temperature_is_fitted_on_the_test_labels(headroom_run) -> None:
    ws, config, result, _, _ = headroom_run
    single = temper(result.models["learned"], 1.0 / result.learned_temperature)
    np.testing.assert_allclose(temper(single, result.learned_temperature),
                               result.models["learned"], atol=1e-12)
    rows = np.zeros(len(result.labels), dtype=np.int64)
    directions = load_npz(ws.require("observe") / OBSERVATION_FILE)["directions"]
    walks, walk_row = held_out_walks(rows, directions,
                                     class_seed(config.seed, "headroom/temperature"))
    assert result.correction == "temperature"
    for row, model in (("oracle_temperature", single),
                       ("oracle_in_sample_temperature", result.models["oracle_in_sample"])):
        t = fit_temperature([model], rows, result.labels, result.predicted, walks, walk_row)
        assert result.temperatures[row] == t
        assert TEMPERATURE_BOUNDS[0] <= t <= TEMPERATURE_BOUNDS[1]
        np.testing.assert_allclose(result.models[row], temper(model, t))
    assert result.temperatures["oracle_temperature"] != result.temperatures[
        "oracle_in_sample_temperature"]


def test_outputs_label_the_oracle_rows_and_touch_no_stage_folder(headroom_run) -> None:
    ws, _, result, before, after = headroom_run
    assert before == after  # nothing outside W/headroom/ was written
    out = ws.root / HEADROOM_DIR
    text = (out / HEADROOM_MD).read_text()
    assert ORACLE_NOTE in text.splitlines()[0]
    for row in result.rows:
        line = next(x for x in text.splitlines() if x.startswith(f"| {row.name} |"))
        assert (ORACLE_NOTE in line) == row.oracle
    table = list(csv.DictReader(io.StringIO((out / HEADROOM_CSV).read_text())))
    assert [r["name"] for r in table] == list(ROWS)
    for r, row in zip(table, result.rows, strict=True):
        assert float(r["accuracy"]) == row.accuracy
        assert r["note"] == (ORACLE_NOTE if row.oracle else "as evaluated")
    assert (out / "policies" / "policy_oracle_in_sample.npz").is_file()


def test_outputs_inside_a_stage_folder_are_refused(headroom_run) -> None:
    ws, _, _, _, _ = headroom_run
    with pytest.raises(StageError, match="inside the evaluate stage's folder"):
        run_headroom(ws, ws.root / "evaluate" / "headroom")


def test_cross_object_halves_alternate_within_each_class() -> None:
    class Model:
        def __init__(self, class_name: str) -> None:
            self.class_name = class_name

    models = [Model(c) for c in ("a", "b", "a", "a", "b")]
    assert cross_object_halves(models).tolist() == [0, 0, 1, 0, 1]  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="two or more test models a class; b has fewer"):
        cross_object_halves([Model("a"), Model("a"), Model("b")])  # type: ignore[list-item]


def test_with_correct_probability_rescales_the_wrong_labels() -> None:
    p = np.array([[[0.5, 0.3, 0.2], [0.1, 0.8, 0.1], [0.0, 0.0, 1.0]]])
    out = with_correct_probability(p, np.array([[0.9, 0.6, 0.7]]))
    np.testing.assert_allclose(out, [[[0.9, 0.06, 0.04], [0.2, 0.6, 0.2],
                                      [0.15, 0.15, 0.7]]])


def test_markdown_and_csv_of_given_rows() -> None:
    rows = [HeadroomRow("learned", 0.75, 1.25, 3.5, 0.125, 8, "(a) learned", False, 0.4,
                        0.9, 0.875, 1, 0.0, 2.0),
            HeadroomRow("oracle_in_sample", 1.0, 0.5, 1.0, -0.25, 8, "(b) in-sample, counted",
                        True, 0.7, 1.0, 0.75, 0, 3.0, 1.0)]
    md = headroom_markdown(rows)
    assert "| learned | (a) learned | 0.750 [0.400, 0.900] | 1.250 | 3.50 | +0.125 | 8 |" in md
    assert f"(b) in-sample, counted — {ORACLE_NOTE} | 1.000 [0.700, 1.000]" in md
    parsed = list(csv.DictReader(io.StringIO(headroom_csv(rows))))
    assert parsed[1]["label"] == "(b) in-sample, counted"
    assert parsed[1]["overconfidence"] == "-0.25" and parsed[1]["note"] == ORACLE_NOTE
