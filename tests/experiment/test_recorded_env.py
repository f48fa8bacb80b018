"""The environment over recorded evidence: the rendering environment's observations, beliefs,
rewards and masks, from a lookup."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from rapomdp.awareness.artefacts import OBSERVATION_FILE
from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.experiment.env import ActiveRecognitionEnv
from rapomdp.experiment.episode import Motion
from rapomdp.experiment.learn_stage import belief_models, record_evidence
from rapomdp.experiment.methods import BayesBelief
from rapomdp.experiment.recorded_env import (
    RecordedEvidence,
    RecordedRecognitionEnv,
    policy_input,
    valid_actions,
)
from rapomdp.io import ArtefactError, load_npz
from rapomdp.recognition.artefacts import load_volume_probabilities
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.robot.artefacts import load_robot

LAMBDA = 3.0


@pytest.fixture(scope="module")
def recorded(pipeline_workspace):
    """The tiny workspace's volume models: their recorded evidence, the classifier, the
    RA-POMDP belief models and the robot's motion."""
    ws, config = pipeline_workspace
    dataset = load_dataset(ws.require("dataset"))
    classifier = load_stage_classifier(config, ws.require("train"), dataset.classes, 1)
    evidence = record_evidence(dataset, load_volume_probabilities(ws.require("classifier_eval")))
    models = belief_models(ws.require("observe"), config.learn.observation_model)
    motion = Motion.from_robot(load_robot(ws.require("robot")))
    return ws, config, dataset, classifier, evidence, models, motion


def _recorded_env(recorded, max_moves: int = 6, seed: int | None = None
                  ) -> RecordedRecognitionEnv:
    _, _, _, _, evidence, belief, motion = recorded
    return RecordedRecognitionEnv(evidence, motion=motion, lambda_=LAMBDA, max_moves=max_moves,
                                  revisit=False, seed=seed, **belief)


def test_the_evidence_is_every_volume_model_and_the_observe_stages_labels(recorded) -> None:
    ws, config, dataset, _, evidence, _, _ = recorded
    volume = dataset.with_role("volume")
    assert evidence.keys.tolist() == [f"{m.class_name}/{m.id}" for m in volume]
    assert evidence.labels.tolist() == [dataset.label(m) for m in volume]
    assert evidence.outputs.shape == (3, 16, 3) and (evidence.sources == "volume").all()
    np.testing.assert_allclose(evidence.outputs.sum(axis=2), 1.0, atol=1e-5)
    # the labels the observation models were fitted on (the xrho images, the classifier)
    observe = load_npz(ws.require("observe") / OBSERVATION_FILE)
    np.testing.assert_array_equal(evidence.outputs.argmax(axis=2),
                                  observe["volume_predictions"])
    test_keys = {f"{m.class_name}/{m.id}" for m in dataset.with_role("test")}
    assert not test_keys & set(evidence.keys.tolist())


def test_same_observations_beliefs_rewards_and_masks_as_the_rendering_env(recorded) -> None:
    """On the same (model, start, actions), the rendering environment's depth images,
    classified and fed to the closed loop's belief, give the recorded environment's
    observations; rewards and masks agree step by step."""
    _, config, dataset, classifier, evidence, arguments, motion = recorded
    volume = dataset.with_role("volume")
    scenes = [TestViews.of_model(dataset, m, config.viewpoints, config.camera,
                                 config.render.noise) for m in volume]
    rendering = ActiveRecognitionEnv(scenes,
                                     [dataset.label(m) for m in volume], dataset.classes,
                                     motion, LAMBDA, max_moves=6, revisit=False)
    fast = _recorded_env(recorded)
    rng = np.random.default_rng(0)
    reachable = np.flatnonzero(motion.reachable)
    compared = 0
    for m in range(len(volume)):
        for start in reachable[:3]:
            options = {"model": m, "start": int(start)}
            obs, _ = rendering.reset(options=options)
            mine, _ = fast.reset(options=options)
            belief = BayesBelief(**arguments)  # the closed loop's belief, as evaluate builds it
            visited = np.zeros(rendering.viewpoints, dtype=bool)
            for step in range(4):
                visited[obs["viewpoint"]] = True
                belief.update(obs["viewpoint"], classifier.predict(obs["depth"][None])[0])
                np.testing.assert_array_equal(
                    mine, policy_input(belief.belief, obs["viewpoint"], visited))
                np.testing.assert_array_equal(fast.belief, belief.belief)
                mask = rendering.action_masks()
                np.testing.assert_array_equal(fast.action_masks(), mask)
                moves = np.flatnonzero(mask[: rendering.viewpoints])
                declare = step == 3 or moves.size == 0
                action = (rendering.viewpoints + int(rng.integers(3)) if declare
                          else int(rng.choice(moves)))
                obs, reward, done, cut, info = rendering.step(action)
                mine, mine_reward, mine_done, mine_cut, mine_info = fast.step(action)
                assert (mine_reward, mine_done, mine_cut) == (reward, done, cut)
                compared += 1
                if done:
                    assert mine_info["correct"] == info["correct"]
                    assert mine_info["energy"] == pytest.approx(info["energy"])
                    break
    assert compared >= 20


def test_the_budget_leaves_only_declarations_and_revisits_are_masked(recorded) -> None:
    env = _recorded_env(recorded, max_moves=2)
    obs, _ = env.reset(seed=0)
    path = [int(np.argmax(obs[env.classes: env.classes + env.viewpoints]))]
    for _ in range(2):
        mask = env.action_masks()
        assert mask[env.viewpoints:].all() and not mask[path].any()
        path.append(int(np.flatnonzero(mask[: env.viewpoints])[0]))
        obs, reward, done, cut, _ = env.step(path[-1])
        assert reward == -env.motion.energy[path[-2], path[-1]] and not (done or cut)
    mask = env.action_masks()
    assert not mask[: env.viewpoints].any() and mask[env.viewpoints:].all()
    np.testing.assert_array_equal(obs[env.classes + env.viewpoints:] > 0,
                                  np.isin(np.arange(env.viewpoints), path))
    # an invalid action at the budget is a penalised no-op that ends the episode
    _, reward, done, cut, info = env.step(path[0])
    assert (reward, done, cut) == (-env.invalid_penalty, False, True) and info["invalid"]
    assert info["moves"] == 2 and not env.action_masks().any()
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(env.viewpoints)


def test_a_declaration_scores_zero_or_minus_lambda(recorded) -> None:
    env = _recorded_env(recorded)
    truth = int(env.evidence.labels[1])
    env.reset(options={"model": 1})
    _, reward, done, _, info = env.step(env.viewpoints + truth)
    assert (reward, done, info["correct"], info["true_class"]) == (0.0, True, True, truth)
    env.reset(options={"model": 1})
    _, reward, done, _, info = env.step(env.viewpoints + (truth + 1) % env.classes)
    assert (reward, done, info["correct"]) == (-LAMBDA, True, False)


def test_check_env_passes_without_a_warning(recorded) -> None:
    for seed in range(5):
        env = _recorded_env(recorded, seed=seed)
        env.action_space.seed(seed)
        with warnings.catch_warnings():
            warnings.filterwarnings("error")
            check_env(env, skip_render_check=True)  # it renders nothing
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs)


def test_valid_actions_is_the_closed_loops_rule() -> None:
    reachable = np.array([True, True, False, True])
    visited = np.array([True, False, False, False])
    mask = valid_actions(reachable, 1, visited, 0, 3, revisit=False, classes=2)
    assert mask.tolist() == [False, False, False, True, True, True]
    mask = valid_actions(reachable, 1, visited, 0, 3, revisit=True, classes=2)
    assert mask.tolist() == [True, False, False, True, True, True]
    assert valid_actions(reachable, 1, visited, 3, 3, False, 2).tolist() == [False] * 4 + [True] * 2


def test_recorded_evidence_round_trips_and_refuses_another_file(recorded, tmp_path) -> None:
    evidence = recorded[4]
    evidence.save(tmp_path / "e.npz")
    again = RecordedEvidence.load(tmp_path / "e.npz")
    np.testing.assert_array_equal(again.outputs, evidence.outputs)
    assert again.keys.tolist() == evidence.keys.tolist()
    np.savez(tmp_path / "other.npz", keys=evidence.keys)
    with pytest.raises(ArtefactError, match="not recorded evidence"):
        RecordedEvidence.load(tmp_path / "other.npz")
    with pytest.raises(ValueError, match=r"must be \(models=3, V, C\)"):
        RecordedEvidence(evidence.keys, evidence.labels, evidence.outputs[:2], evidence.sources)


def test_the_constructor_names_a_mismatched_model(recorded) -> None:
    _, _, _, _, evidence, belief, motion = recorded
    model = belief["observation_model"]
    with pytest.raises(ValueError, match=r"observation model is \(16, 2, 2\)"):
        RecordedRecognitionEnv(evidence, model[:, :2, :2], motion, 1.0, 3)
    with pytest.raises(ValueError, match="must be positive"):
        RecordedRecognitionEnv(evidence, model, motion, 0.0, 3)


def test_the_training_environment_and_policy_without_a_pipeline_configuration(recorded) -> None:
    """belief_models, recorded_environment and train_policy take the sections they read."""
    from rapomdp.config import EvaluateConfig, LearnConfig
    from rapomdp.experiment.learn_stage import recorded_environment, train_policy
    from rapomdp.workspace import StageError

    ws, config, _, _, evidence, belief, motion = recorded
    models = belief_models(ws.require("observe"))  # RA-POMDP's, learn.observation_model's default
    assert list(models) == ["observation_model"]
    np.testing.assert_array_equal(models["observation_model"], belief["observation_model"])
    assert models["observation_model"].shape == (config.viewpoints.count, 3, 3)
    with pytest.raises(StageError, match="learn.observation_model is 'nope'"):
        belief_models(ws.require("observe"), "nope")
    env = recorded_environment(evidence, models, motion, LAMBDA,
                               EvaluateConfig(max_moves=4, revisit=False), seed=0)
    assert (env.max_moves, env.revisit, env.lambda_) == (4, False, LAMBDA)
    assert recorded_environment(evidence, models, motion, 1.0).max_moves == \
        EvaluateConfig().max_moves
    learn = LearnConfig(timesteps=64, envs=2, rollout_steps=32, batch_size=32, epochs=1,
                        hidden=[8])
    network, spec, rows = train_policy(evidence, ws.require("observe"), motion, LAMBDA, 0,
                                       learn, EvaluateConfig(max_moves=4))
    assert (spec.lambda_, spec.max_moves, spec.hidden) == (LAMBDA, 4, (8,))
    assert [row["update"] for row in rows] == [1] and rows[0]["timesteps"] == 64
