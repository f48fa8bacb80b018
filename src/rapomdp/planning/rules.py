"""The active-recognition MOMDP's decision rules and the planners' tolerances, written once.

Every solver, bound, policy and simulator of the package calls these: the value of declaring
(Eq. 2: −λ(1 − max b) for the best class), and the move-or-declare rule with its tie-break
(declare unless a move is worth more by more than :data:`TIE_TOL`).
"""

from __future__ import annotations

import numpy as np

#: A move must beat declaring by more than this to be chosen (ties go to declaring: it ends
#: the episode, and on equal value the shorter plan is the one a user expects).
TIE_TOL = 1e-12
#: A backed-up value must beat the current bound by more than this to be kept (rounding in
#: the products would otherwise add copies of the same vector or point forever).
IMPROVEMENT_TOL = 1e-10
#: A child below this probability is not evaluated (its weight in the backup is nil).
NEGLIGIBLE_PROBABILITY = 1e-300
#: Decimals to which beliefs are rounded when duplicates are removed.
BELIEF_DECIMALS = 12
#: Single-belief backups of the flat solver keep a vector or point that improves by this.
POINT_IMPROVEMENT_TOL = 1e-12
#: Two plans' values this close count as equal (the structured-label test, point pruning).
EQUAL_TOL = 1e-12


def declare_values(belief: np.ndarray, lambda_: float) -> np.ndarray:
    """Value of declaring each class: −λ(1 − b_k), shape (..., C)."""
    return -lambda_ * (1.0 - belief)


def declare_value(belief: np.ndarray, lambda_: float) -> np.ndarray:
    """Value of declaring the best class now: −λ(1 − max_k b_k), shape (...,)."""
    return -lambda_ * (1.0 - np.max(belief, axis=-1))


def unnormalised_declare_value(u: np.ndarray, lambda_: float) -> np.ndarray:
    """p · declare_value(u / p) for unnormalised children u (..., C), p = Σ u: −λ(p − max u)
    (no division, so children of probability 0 are worth 0)."""
    return -lambda_ * (u.sum(axis=-1) - u.max(axis=-1))


def move_or_declare(move_values: np.ndarray, declare: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The best of the moves ``move_values`` (K, M) and declaring ``declare`` (K,): the value
    (K,) and the index of the move chosen, −1 for declaring (K,). A move wins only if it beats
    declaring by more than :data:`TIE_TOL`; among moves, the first best."""
    if move_values.shape[-1] == 0:
        return np.asarray(declare, dtype=np.float64), np.full(np.shape(declare), -1)
    m = move_values.argmax(axis=-1)
    best = np.take_along_axis(move_values, m[..., None], axis=-1)[..., 0]
    go = best > declare + TIE_TOL
    return np.where(go, best, declare), np.where(go, m, -1)
