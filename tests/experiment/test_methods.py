"""The methods of the closed loop (Static, Random, the POMDP methods) on a scripted scene."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.experiment.episode import Motion, run_episode
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy, StaticPolicy
from rapomdp.geometry.viewsphere import geodesic_distance_matrix, k_nearest, viewpoints
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import build_active_recognition_problem, update_beliefs
from tests.experiment.scripted import C, TableRecogniser, V, ViewScene, confusion


def test_static_declares_the_recognisers_choice_from_one_view(motion: Motion) -> None:
    labels = np.arange(V) % C
    for start in (0, 1, 2, 7):
        episode = run_episode(ViewScene(), TableRecogniser(labels), StaticPolicy(), motion,
                              start, 10, np.random.default_rng(0))
        assert episode.moves == 0 and episode.declared == labels[start]
        assert np.allclose(episode.beliefs[-1], episode.outputs[0])


def test_random_walk_never_revisits_and_steps_to_near_neighbours(motion: Motion) -> None:
    P = np.full((V, C, C), 1 / C)  # uninformative: the belief never reaches the threshold
    walk = RandomWalkPolicy(P, motion.distance_m, motion.reachable, neighbours=8,
                            belief_threshold=0.99, max_moves=50)
    near = k_nearest(motion.distance_m, 8, allowed=motion.reachable)
    recogniser = TableRecogniser(np.zeros(V, dtype=int))
    lengths = set()
    for seed in range(20):
        episode = run_episode(ViewScene(), recogniser, walk, motion, 0, 100,
                              np.random.default_rng(seed))
        views = episode.viewpoints.tolist()
        assert len(set(views)) == len(views)
        assert all(b in near[a] for a, b in zip(views, views[1:], strict=False))
        assert motion.reachable[views].all()
        # it stops only when every neighbour of the last view was visited
        assert set(near[views[-1]]) <= set(views)
        lengths.add(len(views))
    assert len(lengths) > 1  # different seeds, different walks


def test_random_walk_stop_rules(motion: Motion) -> None:
    informative = confusion(0)
    recogniser = TableRecogniser(np.zeros(V, dtype=int), confidence=0.9)
    walk = RandomWalkPolicy(informative, motion.distance_m, motion.reachable,
                            belief_threshold=0.8, max_moves=30)
    episode = run_episode(ViewScene(), recogniser, walk, motion, 0, 100,
                          np.random.default_rng(0))
    assert episode.beliefs[-1].max() >= 0.8 and (episode.beliefs[:-1].max(axis=1) < 0.8).all()
    capped = RandomWalkPolicy(np.full((V, C, C), 1 / C), motion.distance_m, motion.reachable,
                              belief_threshold=0.99, max_moves=3)
    episode = run_episode(ViewScene(), recogniser, capped, motion, 0, 100,
                          np.random.default_rng(0))
    assert episode.moves == 3 and not episode.exhausted
    with pytest.raises(ValueError, match="belief_threshold"):
        RandomWalkPolicy(informative, motion.distance_m, motion.reachable, belief_threshold=0)


@pytest.fixture(scope="module")
def solved() -> tuple[np.ndarray, object]:
    distance = geodesic_distance_matrix(viewpoints(V, 0.6, hemisphere=True), 0.6)
    reachable = np.ones(V, dtype=bool)
    reachable[[5, 6]] = False
    P = confusion(1)
    problem = build_active_recognition_problem(P, distance + 0.1, reachable, lambda_=6.0)
    return P, solve_active_recognition(problem, precision=1e-2, timeout=3.0).policy


@pytest.mark.parametrize("revisit", [True, False])
def test_pomdp_method_acts_by_its_policys_lookahead_on_its_own_belief(motion: Motion, solved,
                                                                       revisit: bool) -> None:
    P, policy = solved
    method = POMDPPolicy(policy, P, "RA-POMDP", revisit=revisit)
    everywhere = np.ones(V, dtype=bool)  # no lookahead_over: every viewpoint
    assert np.array_equal(method.lookahead_over, everywhere)
    revisits = 0
    for seed in range(6):
        labels = np.random.default_rng(seed).integers(0, C, size=V)
        episode = run_episode(ViewScene(), TableRecogniser(labels), method, motion, 0, 30,
                              np.random.default_rng(0))
        belief = np.full(C, 1 / C)
        visited = np.zeros(V, dtype=bool)
        for t, view in enumerate(episode.viewpoints):
            belief = update_beliefs(P, belief, view, labels[view])
            visited[view] = True
            assert np.allclose(episode.beliefs[t], belief)
            expected = policy.lookahead_act(int(view), belief, P, everywhere,
                                            None if revisit else visited)
            assert episode.actions[t] == expected
        revisits += episode.viewpoints.size - np.unique(episode.viewpoints).size
    if not revisit:
        assert revisits == 0
    with pytest.raises(ValueError, match="observation model"):
        POMDPPolicy(policy, P[:5], "bad")


def test_static_belief_is_the_output_temperature_scaled_and_declares_its_argmax() -> None:
    output = np.array([0.5, 0.3, 0.2])
    static = StaticPolicy(softmax_temperature=0.5)
    static.reset(0, np.random.default_rng(0))
    static.observe(0, output)
    assert np.allclose(static.belief, output**2 / (output**2).sum())
    assert static.act(0).target == 0
    plain = StaticPolicy()
    plain.observe(0, output)
    assert np.allclose(plain.belief, output)
    with pytest.raises(ValueError, match="softmax_temperature must be positive"):
        StaticPolicy(softmax_temperature=0.0)


def test_a_pomdp_method_with_lookahead_acts_by_it():
    from rapomdp.planning.momdp import benchmark_problem

    problem = benchmark_problem(6, 3, seed=2, lambda_=10.0)
    policy = solve_active_recognition(problem, precision=1e-2, timeout=1e6,
                                      max_iterations=5).policy
    allowed = np.array([True, True, False, True, True, True])
    method = POMDPPolicy(policy, problem.observation_model, "ra", lookahead_over=allowed)
    method.reset(0, np.random.default_rng(0))
    method.observe(0, np.eye(3)[1])
    visited = np.zeros(6, dtype=bool)
    visited[0] = True
    assert method.act(0) == policy.lookahead_act(0, method.belief, problem.observation_model,
                                                 allowed, visited)


def test_random_walk_stops_on_its_belief_and_reports_the_declared_one(motion: Motion) -> None:
    informative = confusion(0)
    recogniser = TableRecogniser(np.zeros(V, dtype=int), confidence=0.9)
    episodes = {}
    for a in (1.0, 0.3):
        walk = RandomWalkPolicy(informative, motion.distance_m, motion.reachable,
                                belief_threshold=0.8, max_moves=30, declared_temperature=a)
        episodes[a] = run_episode(ViewScene(), recogniser, walk, motion, 0, 100,
                                  np.random.default_rng(0))
    plain, declared = episodes[1.0], episodes[0.3]
    assert declared.actions == plain.actions  # the same stop, though it reports less than 0.8
    assert plain.beliefs[-1].max() >= 0.8 > declared.beliefs[-1].max()
    expected = plain.beliefs ** 0.3
    assert np.allclose(declared.beliefs, expected / expected.sum(axis=1, keepdims=True))
    with pytest.raises(ValueError, match="declared-confidence temperature must be positive"):
        RandomWalkPolicy(informative, motion.distance_m, motion.reachable,
                         declared_temperature=0.0)


def test_a_pomdp_method_acts_on_its_belief_and_reports_the_declared_one(motion: Motion,
                                                                        solved) -> None:
    P, policy = solved
    labels = np.random.default_rng(4).integers(0, C, size=V)
    runs = [run_episode(ViewScene(), TableRecogniser(labels),
                        POMDPPolicy(policy, P, "RA-POMDP", declared_temperature=a), motion, 0,
                        30, np.random.default_rng(0)) for a in (1.0, 0.5)]
    assert runs[1].actions == runs[0].actions
    expected = np.sqrt(runs[0].beliefs)
    assert np.allclose(runs[1].beliefs, expected / expected.sum(axis=1, keepdims=True))
