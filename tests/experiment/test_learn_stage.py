"""The learn stage on the tiny workspace: trained on held-out models only, its policies load and
act within the mask, and ``evaluate`` runs ``learned`` like every method."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from rapomdp.config import config_from_dict
from rapomdp.data.dataset import Dataset, load_dataset
from rapomdp.experiment.episode import Motion
from rapomdp.experiment.episode_table import EpisodeTable
from rapomdp.experiment.learn_stage import (
    held_out_comparison,
    plateau_timesteps,
    recorded_scores,
    run_learn_stage,
)
from rapomdp.experiment.learned import LearnedPolicy, load_learned_policy
from rapomdp.experiment.recorded_env import RecordedEvidence, valid_actions
from rapomdp.experiment.sections import learn_fingerprint, learned_lambdas
from rapomdp.io import read_json
from rapomdp.pipeline import get_stage
from rapomdp.planning.stage import offered_observation_models
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError
from tests.conftest import TEST_CONTEXT
from tests.experiment.conftest import LEARNED_TIMESTEPS, LEARNED_TINY, TINY

LAMBDAS = [8.0, 1.0, 2.0, 6.0]  # Table 1's (solve's default), then the sweep's


def _keys(dataset: Dataset, role: str) -> set[str]:
    return {f"{m.class_name}/{m.id}" for m in dataset.with_role(role)}


def test_the_stage_reads_no_test_model(learned_workspace, monkeypatch, tmp_path) -> None:
    """The learn stage loads no mesh and, of classifier_eval's outputs, only the volume models'
    arrays; its evidence names exactly the volume models (the tiny workspace cross-fits
    nothing)."""
    from rapomdp.recognition import artefacts

    ws, config = learned_workspace
    dataset = load_dataset(ws.require("dataset"))
    meshes: list[str] = []
    arrays: list[tuple[str, tuple[str, ...] | None]] = []
    mesh, load_npz = Dataset.mesh, artefacts.load_npz

    def recording_mesh(self: Dataset, model):  # noqa: ANN001, ANN202
        meshes.append(model.file)
        return mesh(self, model)

    def recording_npz(path, keys=None):  # noqa: ANN001, ANN202
        arrays.append((path.name, None if keys is None else tuple(keys)))
        return load_npz(path, keys)

    monkeypatch.setattr(Dataset, "mesh", recording_mesh)
    monkeypatch.setattr(artefacts, "load_npz", recording_npz)
    run_learn_stage(config, ws.inputs(get_stage("learn")), tmp_path, TEST_CONTEXT)
    assert meshes == []
    assert arrays == [("probabilities.npz", ("volume_files", "volume_xrho"))]
    summary = read_json(tmp_path / "learn.json")
    assert set(summary["evidence"]["keys"]) == _keys(dataset, "volume")
    assert not set(summary["evidence"]["keys"]) & _keys(dataset, "test")
    assert summary["evidence"] == {**summary["evidence"], "models": 3, "volume": 3}
    assert "crossfit" not in summary["evidence"]
    evidence = RecordedEvidence.load(tmp_path / "recorded_evidence.npz")
    assert set(evidence.keys.tolist()) == _keys(dataset, "volume")
    # the same seed and configuration give the same policies as the pipeline's run
    for lam in LAMBDAS:
        assert (tmp_path / f"learned_lambda_{lam:g}.pt").read_bytes() == \
            (ws.require("learn") / f"learned_lambda_{lam:g}.pt").read_bytes()


def test_a_policy_per_lambda_loads_and_acts_within_the_mask(learned_workspace) -> None:
    ws, _ = learned_workspace
    out = ws.require("learn")
    evidence = RecordedEvidence.load(out / "recorded_evidence.npz")
    models, _ = offered_observation_models(ws.require("observe"))
    motion = Motion.from_robot(load_robot(ws.require("robot")))
    config = config_from_dict(LEARNED_TINY)
    assert learned_lambdas(config.solve.wrong_declaration_cost_m,
                           config.evaluate.lambdas) == LAMBDAS
    assert learned_lambdas(3.0) == [3.0]  # no sweep: Table 1's λ alone
    assert learned_lambdas(3.0, [1.0, 3.000001, 5.0]) == [3.0, 1.0, 5.0]  # np.isclose
    for lam in LAMBDAS:
        network, spec = load_learned_policy(out, lam)
        assert (spec.lambda_, spec.max_moves, spec.revisit, spec.hidden) == (lam, 6, False,
                                                                              (16,))
        assert spec.inputs == 3 + 2 * 16 and spec.actions == 16 + 1  # moves, then stop
        assert spec.to_dict()["declare"] == "map"
        policy = LearnedPolicy(network, spec, models["ra"], motion.reachable)
        for m in range(evidence.models):
            for start in np.flatnonzero(motion.reachable)[:4]:
                policy.reset(int(start), np.random.default_rng(0))
                viewpoint, moves = int(start), 0
                while True:
                    policy.observe(viewpoint, evidence.outputs[m, viewpoint])
                    mask = valid_actions(motion.reachable, viewpoint, policy._visited, moves,
                                         6, False, 3)
                    action = policy.act(viewpoint)
                    index = action.target + (16 if action.is_declare else 0)
                    assert mask[index]
                    if action.is_declare:
                        break
                    viewpoint, moves = action.target, moves + 1
                assert moves <= 6


def test_curves_and_held_out_scores_are_recorded(learned_workspace) -> None:
    ws, config = learned_workspace
    out = ws.require("learn")
    with open(out / "training_curves.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    updates = LEARNED_TIMESTEPS // (2 * 32)  # envs x rollout steps per update
    assert [float(r["lambda"]) for r in rows] == [lam for lam in LAMBDAS for _ in range(updates)]
    assert [float(r["timesteps"]) for r in rows[:updates]] == [64.0 * (i + 1)
                                                               for i in range(updates)]
    for row in rows:
        assert 0 <= float(row["accuracy"]) <= 1 and float(row["mean_energy"]) >= 0
        assert float(row["mean_return"]) <= 0 and int(row["episodes"]) > 0
    assert (out / "training_curves.png").stat().st_size > 10_000
    summary = read_json(out / "learn.json")
    assert summary["trained"] is True and summary["lambdas"] == LAMBDAS
    assert set(summary["policies"]) == {"8", "1", "2", "6"}
    reachable = int(load_robot(ws.require("robot"))["reachable"].sum())
    held = summary["held_out"]
    assert [(r["method"], r["value"]) for r in held] == [
        *(("learned", lam) for lam in LAMBDAS), ("random", 0.9), ("random", 0.6)]
    assert all(r["episodes"] == 3 * reachable for r in held)
    # a row is what recorded_scores gives for that method, seed and pairs
    evidence = RecordedEvidence.load(out / "recorded_evidence.npz")
    models, _ = offered_observation_models(ws.require("observe"))
    motion = Motion.from_robot(load_robot(ws.require("robot")))
    network, spec = load_learned_policy(out, 8.0)
    again = recorded_scores(evidence, LearnedPolicy(network, spec, models["ra"],
                                                    motion.reachable), motion, 6, config.seed,
                            "learned")
    assert again == {k: held[0][k] for k in again}
    # the whole comparison again from the sections alone, without a pipeline configuration
    rows = held_out_comparison(evidence, out, ws.require("observe"), motion, 8.0,
                               config.evaluate.model_copy(), "ra", config.seed, progress=False)
    assert rows == held


def test_evaluate_runs_learned_in_table1_the_paired_column_and_the_sweep(
        learned_workspace) -> None:
    ws, _ = learned_workspace
    out = ws.require("evaluate")
    table = EpisodeTable.load(out / "episodes.npz")
    assert table.methods[-1] == "learned"
    learned, ra = table.method == "learned", table.method == "ra"
    assert learned.sum() == ra.sum() == 9
    np.testing.assert_array_equal(table.start[learned], table.start[ra])  # the same pairs
    assert list(table.model[learned]) == list(table.model[ra])
    lines = (out / "table1.md").read_text().splitlines()
    row = next(line for line in lines if line.startswith("| Learned (PPO) |"))
    accuracy = table.correct[learned].mean()
    assert f"| {accuracy:.3f} [" in row
    with open(out / "paired.csv", newline="") as handle:
        paired = {r["method"]: r for r in csv.DictReader(handle)}
    difference = accuracy - table.correct[ra].mean()
    assert float(paired["learned"]["accuracy_difference"]) == pytest.approx(difference,
                                                                            abs=1e-6)
    assert paired["learned"]["pairs"] == "9"
    with open(out / "tradeoff.csv", newline="") as handle:
        points = [r for r in csv.DictReader(handle) if r["method"] == "learned"]
    assert [float(p["value"]) for p in points] == sorted(LAMBDAS)
    assert [p["configured"] for p in points] == ["0", "0", "0", "1"]


def test_the_stage_trains_nothing_unless_learned_is_a_method(pipeline_workspace) -> None:
    ws, config = pipeline_workspace
    out = ws.require("learn")
    assert sorted(p.name for p in out.iterdir()) == ["learn.json", "stage.json"]
    assert read_json(out / "learn.json")["trained"] is False
    # without the method, its λs and budget are no part of the key; with it they are
    other = config.model_copy(deep=True)
    other.evaluate.lambdas = [3.0]
    other.evaluate.max_moves = 9
    assert learn_fingerprint(other) == learn_fingerprint(config)
    learned = config_from_dict(LEARNED_TINY)
    changed = learned.model_copy(deep=True)
    changed.evaluate.lambdas = [3.0]
    assert len({learn_fingerprint(config), learn_fingerprint(learned),
                learn_fingerprint(changed)}) == 3


def test_an_unknown_observation_model_is_named(pipeline_workspace, tmp_path) -> None:
    ws, _ = pipeline_workspace
    config = config_from_dict({**LEARNED_TINY, "learn": {"observation_model": "nope"}})
    with pytest.raises(StageError, match="learn.observation_model is 'nope'; the observe stage "
                                         "made .*ra"):
        run_learn_stage(config, ws.inputs(get_stage("learn")), tmp_path, TEST_CONTEXT)
    assert TINY["evaluate"]["methods"][-1] == "ra"


def test_without_sb3_contrib_the_stage_says_what_to_install(pipeline_workspace, monkeypatch,
                                                            tmp_path) -> None:
    import sys

    ws, _ = pipeline_workspace
    monkeypatch.setitem(sys.modules, "sb3_contrib", None)  # an import of it fails
    with pytest.raises(StageError, match=r"pip install 'rapomdp\[learned\]'"):
        run_learn_stage(config_from_dict(LEARNED_TINY), ws.inputs(get_stage("learn")),
                        tmp_path, TEST_CONTEXT)
    assert not any(tmp_path.iterdir())  # nothing written


def test_plateau_is_where_the_smoothed_return_settles() -> None:
    rising = [{"timesteps": 100.0 * (i + 1), "mean_return": r}
              for i, r in enumerate([-9, -7, -5, -3, -2.3, -2.05, -2, -2, -2, -2, -2, -2])]
    # smoothed over 2: ..., -2.65, -2.175 (rows 5-6), -2.025 (rows 6-7): within 0.1 of -2
    assert plateau_timesteps(rising, window=2) == 700.0
    assert plateau_timesteps(rising, window=2, tolerance_m=0.5) == 600.0
    flat = [{"timesteps": 10.0 * (i + 1), "mean_return": -1.0} for i in range(6)]
    assert plateau_timesteps(flat, window=3) == 30.0
    assert plateau_timesteps([]) is None


def test_the_learned_configurations_are_the_defaults_plus_the_method() -> None:
    from pathlib import Path

    from rapomdp.config import Config, load_config, read_config_data

    configs = Path(__file__).parents[2] / "configs"
    learned = load_config(configs / "learned.yaml")
    default = Config()
    assert learned.evaluate.methods == [*default.evaluate.methods, "learned"]
    assert learned.model_copy(update={"evaluate": default.evaluate}) == default
    both = read_config_data(configs / "real-cad-dev-learned.yaml")
    assert both["dataset"] == read_config_data(configs / "real-cad-dev.yaml")["dataset"]
    assert both["evaluate"] == read_config_data(configs / "learned.yaml")["evaluate"]


def test_the_report_shows_the_training_when_the_method_ran(learned_workspace,
                                                           pipeline_workspace) -> None:
    ws, _ = learned_workspace
    text = (ws.require("report") / "report.md").read_text()
    summary = read_json(ws.require("learn") / "learn.json")
    assert "## Learned baseline (MaskablePPO)" in text
    assert (f"Training took {summary['seconds']['train_wall']:.0f} s of wall time "
            f"({summary['seconds']['train_cpu']:.0f} s of CPU over 1 process(es))") in text
    assert "| Learned (PPO) | lambda = 8 |" in text and "| Random | threshold = 0.9 |" in text
    assert "![Training curves of the learned baseline" in text
    assert (ws.require("report") / "training_curves.png").is_file()
    assert "| Learned (PPO) |" in text.split("## Learned baseline")[0]  # Table 1's row
    plain = (pipeline_workspace[0].require("report") / "report.md").read_text()
    assert "Learned baseline" not in plain
