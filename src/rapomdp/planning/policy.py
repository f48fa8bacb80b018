"""Solved policies as artefacts: alpha vectors in an ``.npz`` (no pickle anywhere).

- :class:`AlphaVectorPolicy` for a flat POMDP: ``act(belief)``, ``value(belief)``.
- :class:`ActiveRecognitionPolicy` for the active-recognition MOMDP: ``act(viewpoint, belief)``
  returns an :class:`ARAction` (move to a viewpoint or declare a class), ``value(viewpoint,
  belief)`` the lower bound (the value the policy is guaranteed), ``upper(viewpoint, belief)``
  the solver's upper bound.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from rapomdp.io import ArtefactError, load_npz, save_npz
from rapomdp.planning.rules import (
    TIE_TOL,
    declare_value,
    declare_values,
    move_or_declare,
    unnormalised_declare_value,
)

FORMAT_FLAT = "rapomdp.alpha-vector-policy.v1"
FORMAT_AR = "rapomdp.active-recognition-policy.v1"

#: Plans per chunk of the lookahead's float32 screen (a chunk holds plans of one first target).
SCREEN_CHUNK = 4
#: Absolute slack added to the screen's error bound (the float64 roundings of both paths).
SCREEN_SLACK = 1e-9


def save_npz_atomic(path: str | os.PathLike[str], **arrays: np.ndarray) -> Path:
    """Write a policy's arrays atomically (compressed, no pickle); returns the path."""
    save_npz(Path(path), compressed=True, **arrays)
    return Path(path)


def _load(path: str | os.PathLike[str], expected: str) -> dict[str, np.ndarray]:
    try:
        arrays = load_npz(Path(path))
    except ArtefactError as exc:
        raise ValueError(f"{path}: not a readable policy file ({exc})") from None
    fmt = str(arrays.get("format", ""))
    if fmt != expected:
        raise ValueError(f"{path}: expected a {expected!r} file, found format {fmt!r}")
    return arrays


@dataclass(frozen=True)
class AlphaVectorPolicy:
    """Max over alpha vectors (N, S); each vector's action is the policy's choice there.

    What :func:`~rapomdp.planning.sarsop.solve_pomdp` returns; saved as a ``.npz``.

    Attributes:
        alphas: (N, S) alpha vectors; the value at a belief b is max_n alphas[n]·b.
        actions: (N,) the action of each vector.
        discount: The problem's discount.

    Example:
        >>> import numpy as np
        >>> policy = AlphaVectorPolicy(np.array([[1.0, 0.0], [0.0, 2.0]]), np.array([0, 1]))
        >>> policy.value(np.array([0.5, 0.5])), policy.act(np.array([0.9, 0.1])), len(policy)
        (1.0, 0, 2)
    """

    alphas: np.ndarray
    actions: np.ndarray
    discount: float = 0.95

    def value(self, belief: np.ndarray) -> float:
        """The lower bound at ``belief`` (S,): max over the vectors of alpha·b."""
        return float((self.alphas @ np.asarray(belief)).max())

    def act(self, belief: np.ndarray) -> int:
        """The action of the best vector at ``belief`` (S,)."""
        return int(self.actions[int(np.argmax(self.alphas @ np.asarray(belief)))])

    def __len__(self) -> int:
        return self.alphas.shape[0]

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the policy as a ``.npz`` (atomically); returns its path."""
        return save_npz_atomic(
            path,
            format=np.array(FORMAT_FLAT),
            alphas=self.alphas,
            actions=self.actions,
            discount=np.array(self.discount),
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> AlphaVectorPolicy:
        """Read a policy :meth:`save` wrote (a ValueError naming another file's format)."""
        a = _load(path, FORMAT_FLAT)
        return cls(a["alphas"], a["actions"].astype(np.int64), float(a["discount"]))


@dataclass(frozen=True)
class ARAction:
    """An action of the active-recognition MOMDP: ``kind`` is "move" or "declare"; ``target``
    is the viewpoint index (move) or the class index (declare)."""

    kind: str
    target: int

    @property
    def is_declare(self) -> bool:
        return self.kind == "declare"


@dataclass(frozen=True)
class ActiveRecognitionPolicy:
    """Lower-bound policy of the active-recognition MOMDP.

    The vectors ``betas`` (M, S) are continuation values of "move to ``targets[m]`` then act"
    over the S hidden states (the classes, or (type, class) pairs, type-major): from
    viewpoint v the plan m is worth β_m·b − E[v, targets[m]]. Declaring k is worth
    −λ(1 − b_k), b_k the belief's class marginal. The policy takes the best of all of them.
    ``upper_points`` (N, S) with ``upper_values`` (N, V) give the sawtooth upper bound
    (corners: 0, the state known). ``classes``: the declarable classes (0: as many as states).

    What :func:`~rapomdp.planning.ar_solver.solve_active_recognition` returns and the solve
    stage saves (``.npz``); the closed loop asks it :meth:`act` at every step.

    Example:
        A hand-made policy over two viewpoints and two classes: one plan, "move to viewpoint
        0", worth β·b − E[v, 0]; declaring costs λ = 8 per unit of doubt.

        >>> import numpy as np
        >>> policy = ActiveRecognitionPolicy(
        ...     betas=np.array([[-1.2, -1.2]]), targets=np.array([0]),
        ...     move_energy=np.array([[0.0, 1.0], [1.0, 0.0]]), lambda_=8.0, discount=0.95,
        ...     upper_points=np.zeros((0, 2)), upper_values=np.zeros((0, 2)))
        >>> policy.act(1, np.array([0.5, 0.5]))  # −1.2 − 1 beats declaring (−4)
        ARAction(kind='move', target=0)
        >>> policy.act(1, np.array([0.95, 0.05]))  # declaring costs 0.4
        ARAction(kind='declare', target=0)
        >>> round(policy.value(1, np.array([0.5, 0.5])), 2)
        -2.2
    """

    betas: np.ndarray
    targets: np.ndarray
    move_energy: np.ndarray
    lambda_: float
    discount: float
    upper_points: np.ndarray
    upper_values: np.ndarray
    classes: int = 0

    @property
    def n_viewpoints(self) -> int:
        return self.move_energy.shape[0]

    @property
    def n_classes(self) -> int:
        """The classes a declaration names."""
        return self.classes or self.betas.shape[1]

    @property
    def n_states(self) -> int:
        """The hidden states a belief is over (the classes times the instance types)."""
        return self.betas.shape[1]

    def _moves(self, viewpoint: int, belief: np.ndarray) -> np.ndarray:
        return self.betas @ belief - self.move_energy[viewpoint, self.targets]

    def value(self, viewpoint: int, belief: np.ndarray) -> float:
        """The lower bound at (viewpoint, belief): the policy's guaranteed expected return."""
        b = np.asarray(belief, dtype=np.float64)
        best = float(declare_value(b, self.lambda_, self.n_classes))
        if len(self.targets):
            best = max(best, float(self._moves(viewpoint, b).max()))
        return best

    def act(self, viewpoint: int, belief: np.ndarray,
            forbidden: np.ndarray | None = None) -> ARAction:
        """The action of the best plan at (viewpoint, belief); ties go to declaring.

        ``forbidden`` (V,) bool removes plans that start by moving to those viewpoints (e.g.
        ones already visited, when the sensor would only see the same image again)."""
        b = np.asarray(belief, dtype=np.float64)
        k = int(np.argmax(declare_values(b, self.lambda_, self.n_classes)))
        moves = self._moves(viewpoint, b)
        if forbidden is not None:
            moves = np.where(np.asarray(forbidden, dtype=bool)[self.targets], -np.inf, moves)
        _, m = move_or_declare(moves[None], declare_value(b, self.lambda_, self.n_classes)[None])
        if m[0] >= 0:
            return ARAction("move", int(self.targets[m[0]]))
        return ARAction("declare", k)

    def lookahead_act(self, viewpoint: int, belief: np.ndarray, observation_model: np.ndarray,
                      allowed: np.ndarray, forbidden: np.ndarray | None = None) -> ARAction:
        """One-step lookahead on the lower bound: the move j (``allowed``, not ``forbidden``)
        maximising −E[v, j] + γ Σ_o P(o | b, j) V(j, b_jo), V this policy's value and b_jo the
        Eq. 5 update, or declaring when no move beats it; ties go to declaring.

        ``observation_model`` (V, S, O) must be the model the policy was solved on. A
        point-based lower bound's own plans can be poor away from the beliefs the solver
        visited; one backup at the belief actually reached is less sensitive to them.

        Every move is first valued in float32 within a proven error (:meth:`_screen_values`);
        only the moves that can be the best are then valued exactly (:meth:`_lookahead_values`,
        unless one alone can be and it surely beats declaring), so the action is the one the
        exact values of every move give.

        Args:
            viewpoint: the camera's viewpoint index v.
            belief: (S,) the belief over the hidden states.
            observation_model: (V, S, O) P(o | s, x), the model the policy was solved on.
            allowed: (V,) bool, the viewpoints it may move to.
            forbidden: (V,) bool, viewpoints it may not move to (those seen), or None.

        Returns:
            The action: a move to a viewpoint, or the declaration of a class.
        """
        b = np.asarray(belief, dtype=np.float64)
        ok = np.asarray(allowed, dtype=bool).copy()
        ok[viewpoint] = False
        if forbidden is not None:
            ok &= ~np.asarray(forbidden, dtype=bool)
        targets = np.flatnonzero(ok)
        dec = float(declare_value(b, self.lambda_, self.n_classes))
        declare = ARAction("declare", int(np.argmax(declare_values(b, self.lambda_,
                                                                    self.n_classes))))
        if targets.size == 0:
            return declare
        tables = self._lookahead
        steps = self.move_energy[viewpoint, targets]
        if tables.values_nonpositive and -steps.min() + SCREEN_SLACK <= dec + TIE_TOL:
            return declare  # every child is worth at most 0, so no move beats declaring
        if len(self.targets) and targets.size > 2:
            rough, error = self._screen_values(viewpoint, b, observation_model, targets)
            # (an infinite energy or a child of probability 0: every move exactly)
            if np.all(np.isfinite(rough)):
                if (rough + error).max() <= dec + TIE_TOL:
                    return declare
                keep = rough + error >= (rough - error).max()
                if keep.sum() == 1 and (rough - error)[keep][0] > dec + TIE_TOL:
                    return ARAction("move", int(targets[keep][0]))  # best, beats declaring
                targets = targets[keep]
        q = self._lookahead_values(viewpoint, b, observation_model, targets)
        _, m = move_or_declare(q[None], np.asarray(dec)[None])
        return ARAction("move", int(targets[m[0]])) if m[0] >= 0 else declare

    @cached_property
    def _lookahead(self) -> _LookaheadTables:
        """The plans' arrangement for the lookahead, computed once per policy."""
        return _LookaheadTables.of(self)

    def _lookahead_values(self, viewpoint: int, belief: np.ndarray,
                          observation_model: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """The exact lookahead values q (J,) of moving from ``viewpoint`` to each of
        ``targets``. Each move is valued on its own (one product per move), so its value does
        not depend on which other moves are valued with it."""
        u = belief[None, None, :] * np.swapaxes(observation_model[targets], 1, 2)  # (J, O, S)
        prob = u.sum(axis=2)
        child = unnormalised_declare_value(u, self.lambda_, self.n_classes)  # (J, O)
        if len(self.targets):
            # a plan's move energy depends only on its first target, so the best plan of each
            # target group is found first (a max over plans sorted by target) and the energy
            # subtracted per group: the same maximum over far fewer elements
            t = self._lookahead
            best = np.maximum.reduceat(u @ t.betas.T, t.starts, axis=2)  # (J, O, T)
            best -= prob[..., None] * self.move_energy[np.ix_(targets, t.first)][:, None]
            child = np.maximum(child, best.max(axis=2))
        return self.discount * child.sum(axis=1) - self.move_energy[viewpoint, targets]

    def _screen_values(self, viewpoint: int, belief: np.ndarray, observation_model: np.ndarray,
                       targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_lookahead_values` with a float32 product, and a bound (J,) on the difference
        between the two: |rough − exact| ≤ error wherever rough is finite."""
        t = self._lookahead
        like = observation_model[targets]  # (J, S, O)
        n, s, o = like.shape
        u = np.empty((s, n, o))  # the unnormalised children, states first
        np.multiply(belief[:, None, None], np.swapaxes(like, 0, 1), out=u)
        prob = u.sum(axis=0)
        c = self.n_classes
        marginal = u if s == c else u.reshape(s // c, c, n, o).sum(axis=0)  # (C, J, O)
        child = -self.lambda_ * (prob - marginal.max(axis=0))
        # the children as beliefs (NaN where one has probability 0: then every move exactly)
        # by columns, the plans by rows: the maxima over chunks and over the plans of a chunk
        # are then elementwise maxima of contiguous rows
        children = np.empty((s, n, o), dtype=np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            np.multiply(u, 1.0 / prob, out=children, casting="same_kind")
        x = (t.screen @ children.reshape(s, n * o)).reshape(-1, n, o)  # (M, J, O)
        k = (x.shape[0] - t.single) // t.width  # chunks of ``width``
        for i in range(1, t.width):
            np.maximum(x[t.single:t.single + k], x[t.single + i * k:t.single + (i + 1) * k],
                       out=x[t.single:t.single + k])
        best = x[:t.single + k]
        best -= t.chunk_energy[targets].T[:, :, None]
        rough = (self.discount * np.maximum(child, prob * best.max(axis=0)).sum(axis=1)
                 - self.move_energy[viewpoint, targets])
        return rough, t.error * prob.sum(axis=1) + SCREEN_SLACK

    def upper(self, viewpoint: int, belief: np.ndarray) -> float:
        """The solver's upper bound on the optimal value at (viewpoint, belief)."""
        b = np.asarray(belief, dtype=np.float64)
        if self.upper_points.shape[0] == 0:
            return 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(self.upper_points > 0, b[None, :] / self.upper_points, np.inf)
        phi = ratio.min(axis=1)
        return float(min(0.0, (phi * self.upper_values[:, viewpoint]).min()))

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the policy as a ``.npz`` (atomically); returns its path."""
        return save_npz_atomic(
            path,
            format=np.array(FORMAT_AR),
            betas=self.betas,
            targets=self.targets,
            move_energy=self.move_energy,
            lambda_=np.array(self.lambda_),
            discount=np.array(self.discount),
            upper_points=self.upper_points,
            upper_values=self.upper_values,
            # a typed policy's declarable classes (an untyped one's file is as before)
            **({"classes": np.array(self.n_classes)} if self.n_states != self.n_classes
               else {}),
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ActiveRecognitionPolicy:
        """Read a policy :meth:`save` wrote (a ValueError naming another file's format)."""
        a = _load(path, FORMAT_AR)
        return cls(
            a["betas"],
            a["targets"].astype(np.int64),
            a["move_energy"],
            float(a["lambda_"]),
            float(a["discount"]),
            a["upper_points"],
            a["upper_values"],
            int(a["classes"]) if "classes" in a else 0,
        )


@dataclass(frozen=True)
class _LookaheadTables:
    """A policy's plans arranged for :meth:`ActiveRecognitionPolicy.lookahead_act`.

    ``betas`` (M, S): the plans sorted by first target (stable), ``first`` (T,) the targets,
    ``starts`` (T,) where each one's plans begin. The float32 screen ``screen`` (M, S) holds
    first the ``single`` plans left over when each target's plans are cut into chunks of
    ``width``, then the chunks position-major (row single + i · K + k: the i-th plan of chunk
    k), so that the best plan of each chunk is a maximum of ``width`` blocks of rows, written
    over the first block: rows [0, single + K) are then one value per chunk (a single plan is
    a chunk of one), whose target's energies from each viewpoint are ``chunk_energy``
    (V, single + K). ``error`` times a move's total child probability (1 up to rounding)
    bounds the screen's error on its value (float32 rounding of the children, the S-term sums
    and the energy subtraction, doubled). ``values_nonpositive``: every plan and energy gives
    a child value of at most 0."""

    betas: np.ndarray
    first: np.ndarray
    starts: np.ndarray
    width: int
    single: int
    screen: np.ndarray
    chunk_energy: np.ndarray
    error: float
    values_nonpositive: bool

    @classmethod
    def of(cls, policy: ActiveRecognitionPolicy, width: int = SCREEN_CHUNK
           ) -> _LookaheadTables:
        order = np.argsort(policy.targets, kind="stable")
        betas = policy.betas[order]
        first, starts = np.unique(policy.targets[order], return_index=True)
        ends = np.append(starts[1:], len(order))[: starts.size]
        sizes = ends - starts
        whole = starts + sizes // width * width  # where each target's single plans begin
        single = np.concatenate([np.arange(a, e) for a, e in zip(whole, ends, strict=True)]
                                + [np.zeros(0, dtype=np.int64)])
        chunks = np.array([c for a, e in zip(starts, whole, strict=True)
                           for c in range(a, e, width)], dtype=np.int64)  # first plans (K,)
        rows = np.concatenate([single, (chunks[None, :] + np.arange(width)[:, None]).ravel()])
        chunk_targets = policy.targets[order][np.concatenate([single, chunks])]
        energy = policy.move_energy
        finite = energy[:, first][np.isfinite(energy[:, first])]
        beta_max = float(np.abs(betas).max()) if betas.size else 0.0
        energy_max = float(np.abs(finite).max()) if finite.size else 0.0
        n_states = policy.n_states
        return cls(
            betas=betas,
            first=first,
            starts=starts,
            width=width,
            single=single.size,
            screen=np.ascontiguousarray(betas[rows], dtype=np.float32),
            chunk_energy=np.ascontiguousarray(energy[:, chunk_targets], dtype=np.float32),
            error=2.0 * policy.discount * 2.0**-24 * ((n_states + 8) * beta_max
                                                      + 4 * energy_max),
            values_nonpositive=bool((betas.size == 0 or betas.max() <= 0)
                                    and np.all(energy >= 0)),
        )
