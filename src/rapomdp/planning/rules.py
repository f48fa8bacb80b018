"""The active-recognition MOMDP's decision rules and the planners' tolerances, written once.

Every solver, bound, policy and simulator of the package calls these: the value of declaring
(Eq. 2: −λ(1 − max b) for the best class), and the move-or-declare rule with its tie-break
(declare unless a move is worth more by more than :data:`TIE_TOL`).

The hidden state is the class, or, with T *instance types* (a per-object nuisance), the pair
(type τ, class c) at index τ·C + c (type-major). A declaration names a class, so its value
reads the belief's class marginal (:func:`rapomdp.belief.class_marginal`, with the rest of the
belief's rule); ``n_classes`` None means the states are the classes.
"""

from __future__ import annotations

import numpy as np

from rapomdp.belief import class_marginal

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


def declare_values(belief: np.ndarray, lambda_: float,
                   n_classes: int | None = None) -> np.ndarray:
    """Value of declaring each class: −λ(1 − b_k), shape (..., C) (b: the class marginal)."""
    return -lambda_ * (1.0 - class_marginal(belief, n_classes))


def declare_value(belief: np.ndarray, lambda_: float,
                  n_classes: int | None = None) -> np.ndarray:
    """Value of declaring the best class now: −λ(1 − max_k b_k), shape (...,)."""
    return -lambda_ * (1.0 - np.max(class_marginal(belief, n_classes), axis=-1))


def unnormalised_declare_value(u: np.ndarray, lambda_: float,
                               n_classes: int | None = None) -> np.ndarray:
    """p · declare_value(u / p) for unnormalised children u (..., S), p = Σ u: −λ(p − max u)
    over the class marginal (no division, so children of probability 0 are worth 0)."""
    return -lambda_ * (u.sum(axis=-1) - np.max(class_marginal(u, n_classes), axis=-1))


def declare_alphas(declared: np.ndarray, lambda_: float, n_states: int,
                   n_classes: int) -> np.ndarray:
    """The alpha vectors (..., S) of declaring the classes ``declared`` (...,): −λ in every
    state of another class, 0 in the declared class's states (of every type)."""
    hit = np.eye(n_classes)[np.asarray(declared)]  # (..., C)
    return -lambda_ * (1.0 - np.tile(hit, n_states // n_classes))


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
