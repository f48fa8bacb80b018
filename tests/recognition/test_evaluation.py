"""Single-view evaluation: the per-viewpoint confusion with pseudo-counts."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.recognition.evaluation import viewpoint_confusion, viewpoint_label_counts


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


def test_viewpoint_label_counts_count_each_label_per_viewpoint_and_class() -> None:
    true = np.array([0, 1, 1])
    predicted = np.array([[0, 1, 2], [1, 1, 0], [2, 1, 0]])
    n = viewpoint_label_counts(true, predicted, 3)
    assert n.shape == (3, 3, 3) and n.sum() == predicted.size
    assert n[0, 0].tolist() == [1, 0, 0] and n[0, 1].tolist() == [0, 1, 1]
    assert n[1, 1].tolist() == [0, 2, 0] and n[2, 1].tolist() == [2, 0, 0]
    assert n[2, 0].tolist() == [0, 0, 1] and n[:, 2].sum() == 0  # no model of class 2
