"""The saliency, volume and observe stages end to end on a tiny two-class workspace."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.observation import load_observation_models
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.cli import app
from rapomdp.config import config_from_dict
from rapomdp.context import RunContext
from rapomdp.io import load_npz, read_json
from rapomdp.pipeline import get_stage, run_pipeline
from rapomdp.workspace import Workspace
from tests.conftest import SMALL_SPLIT, TEST_CONTEXT, TINY_PIPELINE

#: Three volume models a class: three held-out groups, so that every held-out choice is made
#: (the stacked variants are fitted in each fold on the other two).
TINY = {**TINY_PIPELINE, "dataset": {"classes": ["bicycle", "teapot"],
                                     "split": {**SMALL_SPLIT, "volume": 3}},
        "viewpoints": {"count": 10}}
MODELS = ("ra", "ra_paper", "ra_class", "ra_area", "ra_class_area", "ra_viewpoint",
          "ra_region", "ra_transfer", "classifier", "blackbox", "ra_mixture")


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    config = config_from_dict(TINY)
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    run_pipeline(config, ws, until="observe", context=TEST_CONTEXT)
    (ws.root / "tiny.yaml").write_text(config.to_yaml())
    return ws


def test_saliency_maps_cover_object_pixels_only(workspace):
    maps = load_npz(workspace.root / "saliency" / "maps" / "bicycle" /
                    f"{_volume_model(workspace, 'bicycle')}.npz")
    depth = load_npz(workspace.root / "render" / "views" / "bicycle" /
                     f"{_volume_model(workspace, 'bicycle')}.npz")["depth"]
    saliency = maps["saliency"].astype(np.float32)
    assert saliency.shape == depth.shape == (12, 48, 64)
    assert np.all(saliency[depth == 0] == 0) and saliency.min() >= 0 and saliency.max() <= 1
    assert maps["probability"].shape == (12,)
    assert read_json(workspace.root / "saliency" / "saliency.json")["method"] == "mask"


def test_one_volume_per_class_with_empty_voxels_marked(workspace):
    for name in ("bicycle", "teapot"):
        volume = SaliencyVolume.load(workspace.root / "volume" / f"{name}.npz")
        assert max(volume.grid.shape) == 13  # resolution 12, padded by half a voxel
        scored = ~np.isnan(volume.scores)
        assert np.array_equal(scored, volume.counts > 0) and scored.any() and (~scored).any()
        assert np.all((volume.scores[scored] >= 0) & (volume.scores[scored] <= 1))


def test_observation_models_follow_the_planner_contract(workspace):
    data = load_npz(workspace.root / "observe" / "observation_models.npz")
    assert list(data["classes"]) == ["bicycle", "teapot"]
    assert list(data["models"]) == list(MODELS)
    for name in data["models"]:
        p = data[name]
        assert p.shape == (10, 2, 2) and np.allclose(p.sum(axis=2), 1) and np.all(p > 0)
    assert data["scores"].shape == (2, 10)
    assert data["scores"].min() >= 0 and data["scores"].max() <= 1
    assert data["directions"].shape == (10, 3) and np.all(data["directions"][:, 2] >= 0)
    similarity = data["view_similarity"]
    assert similarity.shape == (2, 10, 10) and np.allclose(np.diagonal(similarity, 0, 1, 2), 1,
                                                           atol=1e-5)
    for name in data["models"]:  # the first update's record: the model itself
        np.testing.assert_array_equal(data[f"first_view_{name}"], data[name])
    models = load_observation_models(workspace.root / "observe" / "observation_models.npz")
    assert set(models) == set(MODELS)
    with open(workspace.root / "observe" / "quality.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["model"] for r in rows] == list(MODELS)
    assert all(float(r["log_likelihood"]) <= 0 for r in rows)
    # ra_transfer's kernel: the grid kernel of best held-out log-likelihood, recorded
    chosen = read_json(workspace.root / "observe" / "calibration.json")["transfer_kernel"]
    grid = chosen.pop("grid")
    assert len(grid) == 64 and {r["class_prior"] for r in grid} == {0.0}
    best = max(grid, key=lambda r: r["held_out_log_likelihood"])
    assert chosen == {k: best[k] for k in ("power", "bandwidth_deg", "prior", "class_prior")}
    assert read_json(workspace.root / "observe" / "timing.json")["transfer_kernel_s"] >= 0
    # read back for a refit: the same evidence, scores, kernel and RA variant
    recorded = RecordedObservation.load(workspace.root / "observe")
    assert recorded.classes == ["bicycle", "teapot"]
    np.testing.assert_array_equal(recorded.evidence.predicted, data["evidence_predictions"])
    np.testing.assert_array_equal(recorded.scores["area"], data["area_scores"])
    assert recorded.transfer_kernel.to_dict() == chosen
    assert recorded.variant == f"ra_{recorded.calibration['ra_model']}"
    assert data["evidence_from_volume"].all()  # every row a volume model
    calibration = recorded.calibration
    assert (calibration["evidence"], calibration["belief"]) == ("volume", "naive")
    assert set(calibration["level_shifts"].values()) == {0.0}


def test_fig1_is_written_and_a_wrong_class_is_named(workspace):
    runner = CliRunner()
    args = ["figure", "fig1", "-w", str(workspace.root), "-c", str(workspace.root / "tiny.yaml")]
    result = runner.invoke(app, [*args, "--class", "teapot"])
    assert result.exit_code == 0, result.output
    assert (workspace.root / "figures" / "fig1_teapot.png").stat().st_size > 1000
    assert (workspace.root / "figures" / "fig1_teapot.html").exists()
    result = runner.invoke(app, [*args, "--class", "unicycle"])
    assert result.exit_code == 2 and "class 'unicycle' is not in the dataset" in result.output


def _volume_model(ws: Workspace, class_name: str) -> str:
    from rapomdp.data.dataset import load_dataset

    dataset = load_dataset(ws.root / "dataset")
    return next(m.id for m in dataset.with_role("volume") if m.class_name == class_name)


def test_solve_stage_plans_on_the_observation_models_and_robot(workspace):
    """The full chain: observe + vptree + robot -> one policy per observation model asked for."""
    from rapomdp.planning.policy import ActiveRecognitionPolicy

    config = config_from_dict({**TINY, "solve": {"timeout_s": 2.0}})
    results = run_pipeline(config, workspace, until="solve", context=TEST_CONTEXT)
    assert [r.name for r in results][-4:] == ["robot", "observe", "vptree", "solve"]
    summary = read_json(workspace.root / "solve" / "solve_summary.json")
    assert set(summary) == {"ra", "classifier", "vptree"}  # the default solve.models
    reachable = load_npz(workspace.root / "robot" / "robot.npz")["reachable"]
    start = int(np.flatnonzero(reachable)[0])
    for name, bounds in summary.items():
        assert bounds["lower"] <= bounds["upper"] + 1e-9
        # declaring at once is worth -lambda / 2 with two classes; a policy never does worse
        assert bounds["lower"] >= -config.solve.wrong_declaration_cost_m / 2 - 1e-9
        policy = ActiveRecognitionPolicy.load(workspace.root / "solve" / f"policy_{name}.npz")
        action = policy.act(start, np.array([0.5, 0.5]))
        if action.kind == "move":
            assert reachable[action.target] and action.target != start


def test_saliency_maps_do_not_depend_on_the_number_of_processes(workspace, tmp_path):
    from rapomdp.awareness.stage import run_saliency_stage

    config = config_from_dict(TINY)
    inputs = workspace.inputs(get_stage("saliency"))
    run_saliency_stage(config, inputs, tmp_path, RunContext(workers=2, progress=False))
    for name in ("bicycle", "teapot"):
        model = _volume_model(workspace, name)
        serial = load_npz(workspace.root / "saliency" / "maps" / name / f"{model}.npz")
        spread = load_npz(tmp_path / "maps" / name / f"{model}.npz")
        assert np.array_equal(serial["saliency"], spread["saliency"])
    assert read_json(tmp_path / "saliency.json")["processes"] == 2


def test_report_figures_read_the_single_view_models_the_quality_table_scores(workspace,
                                                                              tmp_path):
    from rapomdp.awareness.observation import ObservationModel
    from rapomdp.awareness.quality import awareness_quality
    from rapomdp.awareness.report import single_view_models, write_awareness_figures
    from rapomdp.recognition.belief import temper

    observe = load_npz(workspace.root / "observe" / "observation_models.npz")
    single = single_view_models(observe)
    for name, t in zip(observe["models"].tolist(), observe["temperatures"].tolist(),
                       strict=True):
        assert np.allclose(temper(single[name], t), observe[name], atol=1e-9)
    with open(workspace.root / "observe" / "quality.csv") as handle:
        table = {r["model"]: r for r in csv.DictReader(handle)}
    for name in ("ra", "classifier", "blackbox"):
        measured = awareness_quality(ObservationModel(single[name], ["bicycle", "teapot"]),
                                     observe["test_labels"], observe["test_predictions"])
        assert measured["log_likelihood"] == pytest.approx(
            float(table[name]["log_likelihood"]), abs=1e-9)
    rel, hemi = write_awareness_figures(workspace.root / "observe", "teapot", tmp_path)
    assert rel.stat().st_size > 1000 and hemi.name == "awareness_hemisphere_teapot.png"
    with pytest.raises(Exception, match="class 'unicycle' is not in the observe stage"):
        write_awareness_figures(workspace.root / "observe", "unicycle", tmp_path)


def test_the_papers_protocol_keeps_naive_bayes_on_one_volume_model_a_class(tmp_path):
    """configs/paper-awareness.yaml: one volume model a class, so no held-out group to fit a
    temperature on (t = 1: naive Bayes, Eq. 5) and RA by the Eq. 6 mean score."""
    from pathlib import Path

    import yaml

    paper = yaml.safe_load((Path(__file__).parents[2] / "configs" /
                            "paper-awareness.yaml").read_text())
    assert paper["observe"] == {"ra_model": "paper"}
    assert paper["dataset"] == {"split": {"volume": 1}}
    config = config_from_dict({**TINY, "dataset": {**TINY["dataset"], "split": SMALL_SPLIT},
                               "observe": paper["observe"]})
    assert config.dataset.split.volume == 1
    workspace = Workspace(tmp_path)
    run_pipeline(config, workspace, until="observe", context=TEST_CONTEXT)
    data = load_npz(workspace.root / "observe" / "observation_models.npz")
    assert np.all(data["temperatures"] == 1.0) and np.all(data["evidence_groups"] == 0)
    assert np.allclose(data["ra"], data["ra_paper"])
    assert not (workspace.root / "observe" / "validation.md").exists()
    calibration = read_json(workspace.root / "observe" / "calibration.json")
    assert set(calibration["belief_corrections"].values()) == {"none"}  # nothing fitted
    assert calibration["transfer_kernel"] == {
        "power": 4.0, "bandwidth_deg": 20.0, "prior": 4.0, "class_prior": 0.0,
        "grid": []}  # one group: default
    assert calibration["ra_model_choice"]["rule"] == "configured"
    assert calibration["ra_model_choice"]["dataset_held_out_groups"] == 1  # one volume model


def test_saliency_volumes_use_each_classs_first_volume_models_only():
    from types import SimpleNamespace

    from rapomdp.awareness.stage import saliency_models

    models = [SimpleNamespace(class_name=c, id=f"{c}{i}") for c in "ab" for i in range(3)]
    dataset = SimpleNamespace(with_role=lambda role: models if role == "volume" else [])
    assert [m.id for m in saliency_models(dataset, 1)] == ["a0", "b0"]
    assert [m.id for m in saliency_models(dataset, 2)] == ["a0", "a1", "b0", "b1"]
    assert len(saliency_models(dataset, None)) == 6


def test_the_wrong_label_choice_is_recorded_per_model(workspace):
    """observe.wrong_labels: each model's held-out choice in calibration.json, RA-POMDP's that
    of its variant; with two classes a class's mistakes have one place to go, so every
    amount gives the same rows (to rounding)."""
    from rapomdp.awareness.shrinkage import WRONG_LABEL_SHRINKAGES

    run_pipeline(config_from_dict(TINY), workspace, until="observe", context=TEST_CONTEXT)
    data = load_npz(workspace.root / "observe" / "observation_models.npz")
    calibration = read_json(workspace.root / "observe" / "calibration.json")
    made = calibration["wrong_labels"]
    assert set(made) == set(data["models"].tolist())
    assert made["ra"] == made[f"ra_{calibration['ra_model']}"]
    assert made["ra_mixture"]["rule"] == "configured"  # a mixture of the shrunk variants
    for name, record in made.items():
        if name in ("ra", "ra_mixture"):
            continue
        assert record["grid"] == list(WRONG_LABEL_SHRINKAGES)
        assert record["amount"] in WRONG_LABEL_SHRINKAGES and record["rule"] in {
            "best", "one standard error"}
        assert all(abs(row["difference_to_none"]) < 1e-9 for row in record["held_out"].values())


def fit_thresholds() -> list[float]:
    from rapomdp.recognition.belief import DECLARED_STOP_THRESHOLDS

    return list(DECLARED_STOP_THRESHOLDS)


def test_the_declared_confidence_is_fitted_per_model_and_recorded_with_its_held_out_score(
        workspace):
    data = load_npz(workspace.root / "observe" / "observation_models.npz")
    record = read_json(workspace.root / "observe" / "calibration.json")
    declared = record["declared_confidence"]
    assert set(declared) == set(MODELS)  # every model, "ra" its chosen variant's
    assert declared["ra"] == declared[f"ra_{record['ra_model']}"]
    groups = len(np.unique(data["evidence_groups"]))
    assert data["declared_thresholds"].tolist() == fit_thresholds()
    for name, fit in declared.items():
        assert fit["criterion"] == "confidence"  # chosen held out (docs/awareness.md §4.8)
        assert float(data[f"declared_temperature_{name}"]) == fit["temperature"]
        assert data[f"declared_threshold_temperatures_{name}"].tolist() == \
            fit["threshold_temperatures"]
        assert len(fit["threshold_own_ece"]) == len(fit_thresholds())
        assert 0.05 <= fit["temperature"] <= 2.0
        assert len(fit["held_out_temperatures"]) == len(fit["groups"]) == groups
        assert fit["stops"] == groups * 2 * 16 * 6  # rows a group x walks a row x thresholds
        assert 0.0 <= fit["ece"] <= 1.0 and 0.0 <= fit["declared_ece"] <= 1.0


def test_the_recorded_belief_folds_are_those_the_stage_fitted_its_declared_confidence_on(
        workspace):
    from rapomdp.awareness.temperature import held_out_declared_confidence
    from rapomdp.data.splits import class_seed
    from rapomdp.recognition.belief import TEMPERATURE_NEIGHBOURS, TEMPERATURE_WALKS_PER_ROW

    config = config_from_dict(TINY)
    recorded = RecordedObservation.load(workspace.root / "observe")
    folds = recorded.belief_folds(config.observe)
    assert len(folds) == len(np.unique(recorded.evidence.groups)) >= 2
    for _, models in folds:
        assert np.array_equal(models["ra"].probabilities,
                              models[recorded.variant].probabilities)
    calibration = recorded.calibration
    refit = held_out_declared_confidence(
        recorded.evidence, [(held, {n: m for n, m in models.items() if n != "ra"})
                            for held, models in folds],
        calibration["temperatures"], recorded.arrays["directions"], TEMPERATURE_WALKS_PER_ROW,
        TEMPERATURE_NEIGHBOURS, class_seed(config.seed, "observe/declared"))
    for name in ("classifier", "blackbox", "ra_paper", "ra_class"):  # no float32 similarity
        assert refit[name].temperature == pytest.approx(
            calibration["declared_confidence"][name]["temperature"], abs=1e-9), name


def test_the_stage_records_the_choices_held_out_choices_makes_on_its_evidence(workspace):
    """The stage's choices are :func:`held_out_choices` on its evidence: made again from the
    recorded evidence and scores, they are the recorded ones (a nested loop relies on it).
    The artefact keeps the saliency similarity in float32, so ``ra_transfer``'s kernel may
    break a near-tie otherwise on this tiny workspace: the models that do not read it are
    compared."""
    from rapomdp.awareness.choices import held_out_choices

    config = config_from_dict(TINY)
    recorded = RecordedObservation.load(workspace.root / "observe")
    chosen = held_out_choices(recorded.evidence, recorded.scores, recorded.classes,
                              config.observe, recorded.arrays["directions"], config.seed)
    calibration = recorded.calibration
    assert f"ra_{chosen.variant}" == recorded.variant
    for name in ("classifier", "blackbox", "ra_paper", "ra_class"):
        assert chosen.corrections[name] == calibration["belief_corrections"][name]
        assert chosen.shrinkage[name].amount == calibration["wrong_labels"][name]["amount"]
        assert chosen.temperatures[name] == pytest.approx(
            calibration["temperatures"][name], rel=1e-9), name
        assert chosen.declared[name].temperature == pytest.approx(
            calibration["declared_confidence"][name]["temperature"], abs=1e-9), name


def test_observe_and_its_inputs_without_a_pipeline_configuration(workspace):
    """observe, observe_inputs and xrho_outcomes take the sections they read: on the stage's
    folders they give the stage's models, and rendering afresh gives its test labels."""
    from rapomdp.awareness.observe_stage import observe, observe_inputs, xrho_outcomes
    from rapomdp.config import CameraConfig, ObserveConfig, ViewpointsConfig
    from rapomdp.data.dataset import load_dataset
    from rapomdp.data.test_views import TEST_STREAM
    from rapomdp.recognition.stage import load_stage_classifier

    config = config_from_dict(TINY)
    dataset = load_dataset(workspace.require("dataset"))
    classifier = load_stage_classifier(config, workspace.require("train"), dataset.classes, 1)
    viewpoints, camera = ViewpointsConfig(count=10), CameraConfig(width=64, height=48)
    stored = load_npz(workspace.root / "observe" / "observation_models.npz")
    inputs = workspace.inputs(get_stage("observe"))
    result = observe_inputs(inputs, dataset, classifier, ObserveConfig(), viewpoints, camera,
                            progress=False)
    assert list(result.models) == stored["models"].tolist()
    for name, model in result.models.items():
        assert model.probabilities.shape == (10, 2, 2)
        np.testing.assert_array_equal(model.probabilities, stored[name])
    np.testing.assert_array_equal(result.scores, stored["scores"])
    test = dataset.with_role("test")
    seen = xrho_outcomes(dataset, test[0], classifier, TEST_STREAM, 0, viewpoints, camera)
    assert seen.clean.shape == (10, 48, 64) and seen.probabilities.shape == (10, 2)
    np.testing.assert_array_equal(seen.predicted, stored["test_predictions"][0])
    volumes = {name: SaliencyVolume.load(workspace.root / "volume" / f"{name}.npz")
               for name in dataset.classes}
    fresh = observe(dataset, classifier, volumes, viewpoints=viewpoints, camera=camera,
                    progress=False)
    np.testing.assert_array_equal(fresh.test_predictions, stored["test_predictions"])
    np.testing.assert_array_equal(fresh.raw_scores, stored["raw_scores"])
