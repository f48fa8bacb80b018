"""Viewpoint scores (Eq. 6): the mean of visible scored voxels, normalised per class."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.scores import normalise_scores, viewpoint_scores
from rapomdp.awareness.visibility import visibility_from_depth
from tests.awareness.test_volume import GRID, TINY, side_camera


def test_viewpoint_score_is_the_mean_of_visible_scored_voxels():
    depth = np.zeros((2, 5, 5))
    depth[0, 2, 2] = 0.9  # view 0 sees voxel (2, 2, 2)
    depth[1, 1, 4] = 0.5  # view 1 sees voxel (3, 2, 2)
    depth[1, 2, 2] = 0.9  # ... and voxel (2, 2, 2)
    vis = visibility_from_depth(depth, np.repeat(side_camera(), 2, axis=0), TINY, GRID)
    scores = np.full(GRID.shape, np.nan)
    scores[2, 2, 2], scores[3, 2, 2] = 0.2, 0.6
    out = viewpoint_scores(vis, scores.reshape(-1))
    assert out == pytest.approx([0.2, 0.4])
    scores[3, 2, 2] = np.nan  # an empty voxel does not count
    assert viewpoint_scores(vis, scores.reshape(-1)) == pytest.approx([0.2, 0.2])


def test_scores_normalise_per_class_to_unit_range():
    out = normalise_scores(np.array([[0.2, 0.4, 0.3], [0.5, 0.5, 0.5], [1.0, np.nan, 3.0]]))
    assert out[0] == pytest.approx([0.0, 1.0, 0.5])
    assert out[1] == pytest.approx([0.5, 0.5, 0.5])
    assert out[2] == pytest.approx([0.0, 0.0, 1.0])
