"""Single-view evaluation: the per-viewpoint confusion with pseudo-counts."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.recognition.evaluation import viewpoint_confusion


def test_viewpoint_confusion_counts_per_viewpoint_with_pseudo_counts() -> None:
    true = np.array([0, 1])
    predicted = np.array([[0, 1], [1, 1]])  # model of class 0 wrong at viewpoint 1
    p = viewpoint_confusion(true, predicted, 2, 0.5)
    assert p.shape == (2, 2, 2)
    np.testing.assert_allclose(p.sum(axis=2), 1.0)
    np.testing.assert_allclose(p[0, 0], [1.5 / 2, 0.5 / 2])  # (n + a) / (n(c, x) + C a)
    np.testing.assert_allclose(p[1, 0], [0.5 / 2, 1.5 / 2])
    np.testing.assert_allclose(p[1, 1], [0.5 / 2, 1.5 / 2])
    with pytest.raises(ValueError, match="pseudo-count must be positive"):
        viewpoint_confusion(true, predicted, 2, 0.0)
