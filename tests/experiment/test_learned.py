"""The learned policy's network, its artefact (no pickle) and the closed-loop method."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from rapomdp.experiment.episode import Motion, run_episode
from rapomdp.experiment.learned import (
    LearnedPolicy,
    PolicyNetwork,
    PolicySpec,
    load_learned_policy,
    policy_stem,
    save_learned_policy,
)
from rapomdp.experiment.recorded_env import (
    MapDeclaration,
    RecordedEvidence,
    RecordedRecognitionEnv,
    closed_loop_action,
)
from rapomdp.io import ArtefactError

V, C = 6, 3


def _problem(seed: int = 0) -> tuple[RecordedEvidence, np.ndarray, Motion]:
    """Four recorded models over 6 viewpoints (one unreachable) and 3 classes."""
    rng = np.random.default_rng(seed)
    outputs = rng.dirichlet(np.ones(C), size=(4, V)).astype(np.float32)
    evidence = RecordedEvidence(np.array([f"c/{i}" for i in range(4)]), np.array([0, 1, 2, 0]),
                                outputs, np.full(4, "volume"))
    model = rng.dirichlet(np.ones(C) * 3, size=(V, C))
    energy = rng.uniform(0.1, 0.5, (V, V))
    reachable = np.array([True, True, True, False, True, True])
    energy[:, ~reachable] = np.inf
    energy[~reachable, :] = np.inf
    return evidence, model, Motion(energy, energy, reachable)


def _spec(max_moves: int = 3) -> PolicySpec:
    return PolicySpec(C, V, (8,), "ra", 2.0, max_moves, False)


def test_the_network_is_sb3s_actor_layer_for_layer() -> None:
    """The saved network gives the logits of sb3's MaskablePPO policy it was copied from."""
    from sb3_contrib import MaskablePPO

    from rapomdp.experiment.learn_stage import network_of

    evidence, model, motion = _problem()
    env = MapDeclaration(RecordedRecognitionEnv(evidence, model, motion, 2.0, 3, seed=0))
    ppo = MaskablePPO("MlpPolicy", env, n_steps=32, batch_size=16, seed=0, device="cpu",
                      policy_kwargs={"net_arch": [8], "activation_fn": torch.nn.Tanh})
    ppo.learn(64)
    network = network_of(ppo.policy, _spec())
    observations = torch.from_numpy(np.stack([env.reset(seed=s)[0] for s in range(5)]))
    with torch.no_grad():
        theirs = ppo.policy.get_distribution(observations).distribution.logits
        ours = torch.log_softmax(network(observations), dim=1)
    torch.testing.assert_close(ours, theirs)
    obs, _ = env.reset(seed=9)
    mask = env.action_masks()
    action, _ = ppo.predict(obs, action_masks=mask, deterministic=True)
    assert network.best_action(obs, mask) == int(action)


def test_save_and_load_round_trip_and_refuse_altered_weights(tmp_path) -> None:
    torch.manual_seed(0)
    network, spec = PolicyNetwork.of(_spec()), _spec()
    path = save_learned_policy(tmp_path, network, spec, {"timesteps": 64})
    assert path.name == "learned_lambda_2.pt" and policy_stem(0.5) == "learned_lambda_0.5"
    again, spec_again = load_learned_policy(tmp_path, 2.0)
    assert spec_again == spec
    x = torch.rand(4, spec.inputs)
    torch.testing.assert_close(again(x), network(x))
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta["format"] == "rapomdp.learned-policy.v1" and meta["timesteps"] == 64
    assert meta["spec"]["declare"] == "map" and spec.actions == V + 1
    # a policy that chose the declared class itself (V + C actions) is no longer run
    any_path = path.with_suffix(".json")
    any_path.write_text(json.dumps({**meta, "spec": {**meta["spec"], "declare": "any"}}))
    with pytest.raises(ArtefactError, match="declare 'any' is no longer run .*0018"):
        load_learned_policy(tmp_path, 2.0)
    any_path.write_text(json.dumps(meta))
    path.write_bytes(path.read_bytes()[:-3] + b"abc")
    with pytest.raises(ArtefactError, match="do not match the SHA-256"):
        load_learned_policy(tmp_path, 2.0)
    with pytest.raises(ArtefactError, match="no learned policy for λ = 8"):
        load_learned_policy(tmp_path, 8.0)


def test_the_closed_loop_method_acts_as_in_the_training_environment() -> None:
    """run_episode with the recorded outputs as its memo and the environment (wrapped by
    MapDeclaration), driven by the same network, take the same actions and hold the same
    beliefs (one input rule, one mask rule)."""
    evidence, model, motion = _problem(1)
    torch.manual_seed(3)
    spec = _spec(max_moves=3)
    network = PolicyNetwork.of(spec)
    with torch.no_grad():
        network.head.bias[:V] += 2.0  # prefer moving, so the episodes reach the budget
    env = RecordedRecognitionEnv(evidence, model, motion, spec.lambda_, spec.max_moves)
    driven = MapDeclaration(env)
    assert driven.action_space.n == spec.actions == V + 1
    policy = LearnedPolicy(network, spec, model, motion.reachable)
    budget_reached = 0
    for m in range(evidence.models):
        for start in np.flatnonzero(motion.reachable):
            obs, _ = driven.reset(options={"model": m, "start": int(start)})
            actions, beliefs = [], [env.belief.copy()]
            while True:
                mask = driven.action_masks()
                action = network.best_action(obs, mask)
                assert mask[action]
                actions.append(closed_loop_action(action, env.belief, V))
                obs, _, done, cut, info = driven.step(action)
                if done or cut:
                    break
                beliefs.append(env.belief.copy())
            memo = {v: evidence.outputs[m, v] for v in range(V)}
            episode = run_episode(None, None, policy, motion, int(start), 10,  # type: ignore[arg-type]
                                  np.random.default_rng(0), memo)
            taken = [a.target + (V if a.is_declare else 0) for a in episode.actions]
            assert taken == actions
            np.testing.assert_allclose(episode.beliefs, np.stack(beliefs))
            assert not episode.exhausted and episode.moves <= spec.max_moves
            budget_reached += episode.moves == spec.max_moves
            assert len(set(episode.viewpoints.tolist())) == episode.viewpoints.size
            # stopping declares the belief's most likely class
            assert episode.declared == int(np.argmax(episode.beliefs[-1]))
    assert budget_reached > 0


def test_map_declaration_stops_with_the_most_likely_class() -> None:
    evidence, model, motion = _problem(2)
    env = RecordedRecognitionEnv(evidence, model, motion, 2.0, 3)
    wrapped = MapDeclaration(env)
    wrapped.reset(options={"model": 1, "start": 0})
    full = env.action_masks()
    np.testing.assert_array_equal(wrapped.action_masks(), np.append(full[:V], True))
    best = int(np.argmax(env.belief))
    _, reward, done, _, info = wrapped.step(V)
    assert done and info["declared"] == best
    assert reward == (0.0 if best == evidence.labels[1] else -2.0)


def test_the_method_refuses_a_model_of_another_shape() -> None:
    _, model, motion = _problem()
    with pytest.raises(ValueError, match="trained on 6 viewpoints and 3 classes"):
        LearnedPolicy(PolicyNetwork.of(_spec()), _spec(), model[:, :2, :2], motion.reachable)


def test_a_declared_temperature_changes_what_it_reports_and_no_action() -> None:
    evidence, model, motion = _problem(1)
    torch.manual_seed(4)
    spec = _spec(max_moves=3)
    network = PolicyNetwork.of(spec)
    plain = LearnedPolicy(network, spec, model, motion.reachable)
    sharp = LearnedPolicy(network, spec, model, motion.reachable, declared_temperature=1.5)
    for m in range(evidence.models):
        memo = {v: evidence.outputs[m, v] for v in range(V)}
        a = run_episode(None, None, plain, motion, 0, 10,  # type: ignore[arg-type]
                        np.random.default_rng(0), memo)
        b = run_episode(None, None, sharp, motion, 0, 10,  # type: ignore[arg-type]
                        np.random.default_rng(0), memo)
        assert a.actions == b.actions and a.declared == b.declared
        raised = a.beliefs ** 1.5
        np.testing.assert_allclose(b.beliefs, raised / raised.sum(axis=1, keepdims=True))
