"""The episode simulator and the methods on a scripted scene (no rendering, no network)."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.experiment.episode import Motion, run_episode, score
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy, StaticPolicy
from rapomdp.geometry.viewsphere import geodesic_distance_matrix, k_nearest, viewpoints
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import build_active_recognition_problem, update_beliefs
from rapomdp.planning.policy import ARAction

V, C = 24, 3


class ViewScene:
    """A scene whose depth image encodes the viewpoint it was taken from."""

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        return np.full((2, 3), float(viewpoint))


class TableRecogniser:
    """Returns a fixed label per viewpoint (read back from the image), as probabilities."""

    def __init__(self, labels: np.ndarray, confidence: float = 0.8) -> None:
        self.labels, self.confidence = labels, confidence

    def predict(self, depth_images: np.ndarray) -> np.ndarray:
        views = depth_images[:, 0, 0].astype(int)
        out = np.full((views.size, C), (1 - self.confidence) / (C - 1))
        out[np.arange(views.size), self.labels[views]] = self.confidence
        return out


class Scripted:
    """Moves along a fixed list of viewpoints, then declares class 0."""

    name, recogniser = "scripted", "cnn"

    def __init__(self, path: list[int]) -> None:
        self.path = path
        self.belief = np.full(C, 1 / C)

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self.remaining = list(self.path)

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        self.belief = output

    def act(self, viewpoint: int) -> ARAction:
        if self.remaining:
            return ARAction("move", self.remaining.pop(0))
        return ARAction("declare", 0)


@pytest.fixture
def motion() -> Motion:
    distance = geodesic_distance_matrix(viewpoints(V, 0.6, hemisphere=True), 0.6)
    reachable = np.ones(V, dtype=bool)
    reachable[[5, 6]] = False
    energy = distance + 0.1 * (distance > 0)
    energy[:, ~reachable] = np.inf
    energy[~reachable, :] = np.inf
    return Motion(energy, distance, reachable)


def _confusion(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    right = rng.uniform(0.4, 0.95, size=(V, C))
    P = np.repeat(((1 - right) / (C - 1))[:, :, None], C, axis=2)
    P[:, np.arange(C), np.arange(C)] = right
    return P


def test_episode_records_views_outputs_and_costs(motion: Motion) -> None:
    labels = np.arange(V) % C
    episode = run_episode(ViewScene(), TableRecogniser(labels), Scripted([3, 9, 4]), motion,
                          start_viewpoint=0, max_moves=10, rng=np.random.default_rng(0))
    assert episode.viewpoints.tolist() == [0, 3, 9, 4]
    assert episode.outputs.argmax(axis=1).tolist() == labels[[0, 3, 9, 4]].tolist()
    assert np.allclose(episode.move_energy, motion.energy[[0, 3, 9], [3, 9, 4]])
    assert np.allclose(episode.move_distance_m, motion.distance_m[[0, 3, 9], [3, 9, 4]])
    assert episode.actions == [ARAction("move", 3), ARAction("move", 9), ARAction("move", 4),
                               ARAction("declare", 0)]
    assert not episode.exhausted and episode.moves == 3
    right, wrong = score(episode, 0), score(episode, 2)
    assert right.correct and not wrong.correct
    assert right.energy == pytest.approx(episode.move_energy.sum())
    assert right.distance_m == pytest.approx(episode.move_distance_m.sum())
    assert right.belief == pytest.approx(episode.beliefs[-1, 0])
    assert wrong.belief == pytest.approx(episode.beliefs[-1, 2])


def test_step_budget_forces_a_declaration_of_the_most_likely_class(motion: Motion) -> None:
    labels = np.full(V, 2)
    episode = run_episode(ViewScene(), TableRecogniser(labels), Scripted([1, 2, 3, 4, 7, 8]),
                          motion, 0, max_moves=2, rng=np.random.default_rng(0))
    assert episode.exhausted and episode.moves == 2 and episode.declared == 2


def test_unreachable_moves_and_starts_are_refused(motion: Motion) -> None:
    recogniser = TableRecogniser(np.zeros(V, dtype=int))
    with pytest.raises(ValueError, match="move to viewpoint 5: the arm cannot reach it"):
        run_episode(ViewScene(), recogniser, Scripted([5]), motion, 0, 10,
                    np.random.default_rng(0))
    with pytest.raises(ValueError, match="already there"):
        run_episode(ViewScene(), recogniser, Scripted([0]), motion, 0, 10,
                    np.random.default_rng(0))
    with pytest.raises(ValueError, match="start viewpoint 6 is not reachable"):
        run_episode(ViewScene(), recogniser, Scripted([]), motion, 6, 10,
                    np.random.default_rng(0))


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
    informative = _confusion(0)
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
    P = _confusion(1)
    problem = build_active_recognition_problem(P, distance + 0.1, reachable, lambda_=6.0)
    return P, solve_active_recognition(problem, precision=1e-2, timeout=3.0).policy


@pytest.mark.parametrize("revisit", [True, False])
def test_pomdp_method_acts_as_its_policy_on_its_own_belief(motion: Motion, solved,
                                                           revisit: bool) -> None:
    P, policy = solved
    method = POMDPPolicy(policy, P, "RA-POMDP", revisit=revisit)
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
            expected = policy.act(int(view), belief, None if revisit else visited)
            assert episode.actions[t] == expected
        revisits += episode.viewpoints.size - np.unique(episode.viewpoints).size
    if not revisit:
        assert revisits == 0
    with pytest.raises(ValueError, match="observation model"):
        POMDPPolicy(policy, P[:5], "bad")


def test_a_move_is_checked_and_costs_its_energy_and_distance() -> None:
    energy = np.arange(9, dtype=np.float64).reshape(3, 3)
    motion = Motion(energy, 0.5 * energy, np.array([True, True, False]))
    assert motion.move(0, 1) == (1.0, 0.5)
    with pytest.raises(ValueError, match="cannot reach"):
        motion.move(0, 2)
    with pytest.raises(ValueError, match="already there"):
        motion.move(1, 1)
