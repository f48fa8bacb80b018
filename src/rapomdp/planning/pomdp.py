"""A flat discrete POMDP as separate named parts: transition, observation, reward, belief.

Arrays use the action-first layout that point-based backups want:

- ``T[a, s, s']`` = P(s' | s, a), rows sum to 1;
- ``Z[a, s', o]`` = P(o | s', a), the observation after arriving in s' by a;
- ``R[a, s]`` = expected immediate reward of a in s (the ``.pomdp`` reader folds rewards that
  depend on s' and o into this expectation, which is all a solver of expected return needs).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: How far a model's probability rows may sum from 1.
PROB_TOL = 1e-6


def _check_stochastic(name: str, array: np.ndarray, tol: float = PROB_TOL) -> None:
    """Raise ValueError unless ``array`` is non-negative with last-axis sums of 1."""
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} has non-finite entries")
    if np.any(array < 0):
        raise ValueError(f"{name} has negative probabilities")
    sums = array.sum(axis=-1)
    bad = np.argwhere(np.abs(sums - 1.0) > tol)
    if bad.size:
        idx = tuple(int(i) for i in bad[0])
        raise ValueError(f"{name}{list(idx)} sums to {sums[idx]:.6g}, not 1")


@dataclass(frozen=True)
class TransitionModel:
    """P(s' | s, a) as an array ``T[a, s, s']``."""

    T: np.ndarray

    def probability(self, next_state: int, state: int, action: int) -> float:
        return float(self.T[action, state, next_state])


@dataclass(frozen=True)
class ObservationModel:
    """P(o | s', a) as an array ``Z[a, s', o]``."""

    Z: np.ndarray

    def probability(self, observation: int, next_state: int, action: int) -> float:
        return float(self.Z[action, next_state, observation])


@dataclass(frozen=True)
class RewardModel:
    """Expected immediate reward ``R[a, s]``."""

    R: np.ndarray

    def reward(self, state: int, action: int) -> float:
        return float(self.R[action, state])


def belief_update(
    T: np.ndarray, Z: np.ndarray, belief: np.ndarray, action: int, observation: int
) -> np.ndarray:
    """Eq. 5, vectorised: the posterior after ``action`` and ``observation``.

    Args:
        T: (A, S, S) transition probabilities T[a, s, s'].
        Z: (A, S, O) observation probabilities Z[a, s', o].
        belief: (S,) the belief before.
        action: The action taken.
        observation: The observation received.

    Returns:
        (S,) b'(s') ∝ Z[a, s', o] Σ_s b(s) T[a, s, s'].

    Raises:
        ValueError: The observation has probability 0 after the action.

    Example:
        >>> import numpy as np
        >>> T = np.array([np.eye(2)])                     # listening leaves the state
        >>> Z = np.array([[[0.85, 0.15], [0.15, 0.85]]])  # and hears it right 85 % of the time
        >>> belief_update(T, Z, np.array([0.5, 0.5]), action=0, observation=0).tolist()
        [0.85, 0.15]
    """
    unnorm = (belief @ T[action]) * Z[action, :, observation]
    total = unnorm.sum()
    if total <= 0:
        raise ValueError(f"observation {observation} has probability 0 after action {action}")
    return unnorm / total


@dataclass
class POMDP:
    """A flat discrete POMDP: (S, A, T, R, Ω, O), discount and initial belief.

    Validated when made: shapes agree, T and O rows and the initial belief are distributions,
    the discount is in [0, 1). :meth:`from_arrays` builds one from plain arrays;
    :func:`~rapomdp.planning.io_pomdp.read_pomdp` from a ``.pomdp`` file.

    Example:
        >>> import numpy as np
        >>> pomdp = POMDP.from_arrays(T=np.array([np.eye(2)]),
        ...                           Z=np.array([[[0.85, 0.15], [0.15, 0.85]]]),
        ...                           R=np.array([[-1.0, -1.0]]), discount=0.95,
        ...                           initial_belief=np.array([0.5, 0.5]))
        >>> pomdp.n_states, pomdp.n_actions, pomdp.n_observations
        (2, 1, 2)
    """

    transition: TransitionModel
    observation: ObservationModel
    reward: RewardModel
    discount: float
    initial_belief: np.ndarray
    state_names: list[str] = field(default_factory=list)
    action_names: list[str] = field(default_factory=list)
    observation_names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        T, Z, R = self.T, self.Z, self.R
        if T.ndim != 3 or T.shape[1] != T.shape[2]:
            raise ValueError(f"T must have shape (A, S, S), got {T.shape}")
        n_a, n_s, _ = T.shape
        if Z.ndim != 3 or Z.shape[:2] != (n_a, n_s):
            raise ValueError(f"Z must have shape ({n_a}, {n_s}, n_obs), got {Z.shape}")
        if R.shape != (n_a, n_s):
            raise ValueError(f"R must have shape ({n_a}, {n_s}), got {R.shape}")
        if not 0.0 <= self.discount < 1.0:
            raise ValueError(f"discount must be in [0, 1), got {self.discount}")
        b0 = np.asarray(self.initial_belief, dtype=np.float64)
        if b0.shape != (n_s,):
            raise ValueError(f"initial belief must have shape ({n_s},), got {b0.shape}")
        _check_stochastic("T", T)
        _check_stochastic("O", Z)
        _check_stochastic("initial belief", b0)
        self.initial_belief = b0
        if not self.state_names:
            self.state_names = [str(i) for i in range(n_s)]
        if not self.action_names:
            self.action_names = [str(i) for i in range(n_a)]
        if not self.observation_names:
            self.observation_names = [str(i) for i in range(Z.shape[2])]

    @classmethod
    def from_arrays(
        cls,
        T: np.ndarray,
        Z: np.ndarray,
        R: np.ndarray,
        discount: float,
        initial_belief: np.ndarray,
        **names: list[str],
    ) -> POMDP:
        """Build from plain arrays ``T[a,s,s']``, ``Z[a,s',o]``, ``R[a,s]``."""
        return cls(
            TransitionModel(np.asarray(T, dtype=np.float64)),
            ObservationModel(np.asarray(Z, dtype=np.float64)),
            RewardModel(np.asarray(R, dtype=np.float64)),
            float(discount),
            np.asarray(initial_belief, dtype=np.float64),
            **names,
        )

    @property
    def T(self) -> np.ndarray:
        return self.transition.T

    @property
    def Z(self) -> np.ndarray:
        return self.observation.Z

    @property
    def R(self) -> np.ndarray:
        return self.reward.R

    @property
    def n_states(self) -> int:
        return self.T.shape[1]

    @property
    def n_actions(self) -> int:
        return self.T.shape[0]

    @property
    def n_observations(self) -> int:
        return self.Z.shape[2]
