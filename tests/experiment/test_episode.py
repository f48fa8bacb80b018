"""The episode simulator on a scripted scene (no rendering, no network)."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.experiment.episode import Motion, run_episode, score
from rapomdp.planning.policy import ARAction
from tests.experiment.scripted import C, Scripted, TableRecogniser, V, ViewScene


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

class CountingRecogniser(TableRecogniser):
    """A :class:`TableRecogniser` that counts the images it classifies."""

    images = 0

    def predict(self, depth_images: np.ndarray) -> np.ndarray:
        self.images += depth_images.shape[0]
        return super().predict(depth_images)


def test_a_memo_classifies_each_viewpoint_once_and_changes_no_episode(motion: Motion) -> None:
    labels = (np.arange(V) * 7) % C
    paths = [[3, 9, 4], [9, 3], [4, 9, 3, 10], [1]]
    plain, counted = CountingRecogniser(labels), CountingRecogniser(labels)
    memo: dict[int, np.ndarray] = {}
    for path in paths:
        a = run_episode(ViewScene(), plain, Scripted(path), motion, 0, 10,
                        np.random.default_rng(1))
        b = run_episode(ViewScene(), counted, Scripted(path), motion, 0, 10,
                        np.random.default_rng(1), memo=memo)
        for name in ("viewpoints", "outputs", "beliefs", "move_energy", "move_distance_m"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (a.declared, a.exhausted) == (b.declared, b.exhausted)
    assert plain.images == sum(len(p) + 1 for p in paths) == 14
    assert counted.images == len(memo) == len({0, 1, 3, 4, 9, 10}) == 6
    # the memo's rows are the recogniser's; an episode's outputs are copies of them
    b.outputs[:] = -1.0
    assert np.array_equal(memo[0], counted.predict(np.full((1, 2, 3), 0.0))[0])


def test_a_move_is_checked_and_costs_its_energy_and_distance() -> None:
    energy = np.arange(9, dtype=np.float64).reshape(3, 3)
    motion = Motion(energy, 0.5 * energy, np.array([True, True, False]))
    assert motion.move(0, 1) == (1.0, 0.5)
    with pytest.raises(ValueError, match="cannot reach"):
        motion.move(0, 2)
    with pytest.raises(ValueError, match="already there"):
        motion.move(1, 1)
