"""The flat POMDP's named parts: validation with named rows, and Eq. 5."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.pomdp import POMDP, belief_update


def test_validation_names_the_row_that_does_not_sum_to_one():
    T = np.tile(np.eye(2), (1, 1, 1))
    Z = np.full((1, 2, 2), 0.5)
    R = np.zeros((1, 2))
    bad = Z.copy()
    bad[0, 1] = [0.5, 0.6]
    with pytest.raises(ValueError, match=r"O\[0, 1\] sums to 1.1, not 1"):
        POMDP.from_arrays(T, bad, R, 0.9, np.array([0.5, 0.5]))
    with pytest.raises(ValueError, match=r"discount must be in \[0, 1\)"):
        POMDP.from_arrays(T, Z, R, 1.0, np.array([0.5, 0.5]))
    p = POMDP.from_arrays(T, Z, R, 0.9, np.array([0.5, 0.5]))
    assert p.state_names == ["0", "1"] and p.transition.probability(1, 1, 0) == 1.0


def test_belief_update_is_bayes_rule():
    T = np.array([[[0.9, 0.1], [0.2, 0.8]]])
    Z = np.array([[[0.7, 0.3], [0.1, 0.9]]])
    b = np.array([0.6, 0.4])
    pred = b @ T[0]
    expected = pred * Z[0, :, 1] / (pred * Z[0, :, 1]).sum()
    np.testing.assert_allclose(belief_update(T, Z, b, 0, 1), expected)
    with pytest.raises(ValueError, match="observation 1 has probability 0"):
        belief_update(T, np.array([[[1.0, 0.0], [1.0, 0.0]]]), b, 0, 1)
