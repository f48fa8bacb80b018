"""The robot figure's choice of arms to draw."""

from __future__ import annotations

import numpy as np

from rapomdp.robot.figures import pick_poses


def test_pick_poses_spans_the_manipulability_range() -> None:
    m = np.array([0.05, np.nan, 0.09, 0.01, 0.07])
    reachable = ~np.isnan(m)
    assert pick_poses(m, reachable, 3).tolist() == [2, 4, 3]  # best, middle, worst
    assert pick_poses(m, np.zeros(5, dtype=bool)).size == 0
