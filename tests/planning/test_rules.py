"""The decision rules every solver, bound, policy and simulator share."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.rules import (
    TIE_TOL,
    declare_value,
    declare_values,
    move_or_declare,
    unnormalised_declare_value,
)


def test_declaring_is_worth_minus_lambda_times_the_error_probability():
    b = np.array([[0.2, 0.5, 0.3], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(declare_values(b, 4.0), [[-3.2, -2.0, -2.8], [0.0, -4.0, -4.0]])
    np.testing.assert_allclose(declare_value(b, 4.0), [-2.0, 0.0])
    u = 0.5 * b  # children of probability 0.5
    np.testing.assert_allclose(unnormalised_declare_value(u, 4.0), 0.5 * declare_value(b, 4.0))


def test_a_move_must_beat_declaring_by_more_than_the_tie_tolerance():
    declare = np.array([-1.0, -1.0, -1.0])
    moves = np.array([[-0.5, -0.2], [-1.0 + TIE_TOL / 2, -2.0], [-3.0, -1.0 + 2 * TIE_TOL]])
    value, index = move_or_declare(moves, declare)
    assert index.tolist() == [1, -1, 1]  # a near-tie goes to declaring
    np.testing.assert_allclose(value, [-0.2, -1.0, -1.0 + 2 * TIE_TOL])
    value, index = move_or_declare(np.zeros((3, 0)), declare)  # no move at all
    assert index.tolist() == [-1, -1, -1] and value.tolist() == declare.tolist()


def test_a_declaration_over_typed_states_reads_the_class_marginal():
    from rapomdp.planning.rules import class_marginal, declare_alphas

    # states (type, class) at tau * C + c: 2 types x 3 classes
    b = np.array([[0.1, 0.2, 0.1, 0.3, 0.0, 0.3]])
    np.testing.assert_allclose(class_marginal(b, 3), [[0.4, 0.2, 0.4]])
    np.testing.assert_allclose(declare_values(b, 4.0, 3), [[-2.4, -3.2, -2.4]])
    np.testing.assert_allclose(declare_value(b, 4.0, 3), [-2.4])
    np.testing.assert_allclose(unnormalised_declare_value(0.5 * b, 4.0, 3), [-1.2])
    alphas = declare_alphas(np.array([2, 0]), 4.0, 6, 3)
    np.testing.assert_allclose(alphas, [[-4, -4, 0, -4, -4, 0], [0, -4, -4, 0, -4, -4]])
    np.testing.assert_allclose(alphas @ b[0], declare_values(b, 4.0, 3)[0, [2, 0]])
    assert class_marginal(b[:, :3], 3) is not None and np.array_equal(class_marginal(b), b)
    with pytest.raises(ValueError, match="7 states is no whole number of types of 3"):
        class_marginal(np.ones(7) / 7, 3)
