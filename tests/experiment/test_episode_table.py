"""The episodes table: one row per episode plus the concatenated steps, saved and read back."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable, episodes_csv
from rapomdp.io import save_npz


def _table() -> EpisodeTable:
    """Two episodes over classes a, b: one declares at once (right), one moves twice (wrong)."""
    beliefs = np.array([[0.7, 0.3], [0.5, 0.5], [0.4, 0.6], [0.3, 0.7]])
    return EpisodeTable(
        classes=["a", "b"], methods=["static", "ra"], method=np.array(["static", "ra"]),
        class_index=np.array([0, 0]), model=np.array(["a/m1.stl", "a/m1.stl"]),
        start=np.array([3, 3]), declared=np.array([0, 1]), exhausted=np.array([False, True]),
        correct=np.array([True, False]), belief=np.array([0.7, 0.3]), moves=np.array([0, 2]),
        distance_m=np.array([0.0, 0.5]), energy=np.array([0.0, 0.75]),
        offsets=np.array([0, 1, 4]), step_viewpoints=np.array([3, 3, 7, 9]),
        step_outputs=beliefs, step_beliefs=beliefs, cpu_seconds=np.array([0.01, 0.02]))


def test_a_table_round_trips_through_its_npz(tmp_path: Path) -> None:
    table = _table()
    save_npz(tmp_path / EPISODES_FILE, **table.arrays())
    again = EpisodeTable.load(tmp_path / EPISODES_FILE)
    assert again.classes == ["a", "b"] and again.methods == ["static", "ra"]
    for name, value in table.arrays().items():
        assert np.array_equal(getattr(again, name, None) if name not in ("classes", "methods")
                              else np.array(getattr(again, name)), value), name
    assert again.viewpoints_of(1).tolist() == [3, 7, 9]
    np.testing.assert_allclose(again.beliefs_in_true_class(1), [0.5, 0.4, 0.3])


def test_the_csv_has_one_line_per_episode_with_its_path() -> None:
    lines = episodes_csv(_table()).splitlines()
    assert lines[0].startswith("method,class,model,start,declared,correct,belief,moves")
    assert lines[1] == "static,a,a/m1.stl,3,a,1,0.7,0,0,0,0,3"
    assert lines[2] == "ra,a,a/m1.stl,3,b,0,0.3,2,0.5,0.75,1,3 7 9"


def test_the_final_confidence_is_the_last_belief_in_the_declared_class() -> None:
    # episode 0 declares a from [0.7, 0.3]; episode 1 declares b from its last row [0.3, 0.7]
    np.testing.assert_allclose(_table().final_confidence(), [0.7, 0.7])
