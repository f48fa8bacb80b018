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
from pathlib import Path

import numpy as np

from rapomdp.io import ArtefactError, load_npz, save_npz
from rapomdp.planning.rules import (
    declare_value,
    declare_values,
    move_or_declare,
    unnormalised_declare_value,
)

FORMAT_FLAT = "rapomdp.alpha-vector-policy.v1"
FORMAT_AR = "rapomdp.active-recognition-policy.v1"


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
    """Max over alpha vectors (N, S); each vector's action is the policy's choice there."""

    alphas: np.ndarray
    actions: np.ndarray
    discount: float = 0.95

    def value(self, belief: np.ndarray) -> float:
        return float((self.alphas @ np.asarray(belief)).max())

    def act(self, belief: np.ndarray) -> int:
        return int(self.actions[int(np.argmax(self.alphas @ np.asarray(belief)))])

    def __len__(self) -> int:
        return self.alphas.shape[0]

    def save(self, path: str | os.PathLike[str]) -> Path:
        return save_npz_atomic(
            path,
            format=np.array(FORMAT_FLAT),
            alphas=self.alphas,
            actions=self.actions,
            discount=np.array(self.discount),
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> AlphaVectorPolicy:
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
        visited; one backup at the belief actually reached is less sensitive to them."""
        b = np.asarray(belief, dtype=np.float64)
        ok = np.asarray(allowed, dtype=bool).copy()
        ok[viewpoint] = False
        if forbidden is not None:
            ok &= ~np.asarray(forbidden, dtype=bool)
        targets = np.flatnonzero(ok)
        dec = declare_value(b, self.lambda_, self.n_classes)
        k = int(np.argmax(declare_values(b, self.lambda_, self.n_classes)))
        if targets.size == 0:
            return ARAction("declare", k)
        u = b[None, None, :] * np.swapaxes(observation_model[targets], 1, 2)  # (J, O, S)
        prob = u.sum(axis=2)
        child = unnormalised_declare_value(u, self.lambda_, self.n_classes)  # (J, O)
        if len(self.targets):
            # a plan's move energy depends only on its first target, so the best plan of each
            # target group is found first (a max over plans sorted by target) and the energy
            # subtracted per group: the same maximum over far fewer elements
            order = np.argsort(self.targets, kind="stable")
            first_targets, starts = np.unique(self.targets[order], return_index=True)
            best = np.maximum.reduceat(u @ self.betas[order].T, starts, axis=2)  # (J, O, T)
            best -= prob[..., None] * self.move_energy[np.ix_(targets, first_targets)][:, None]
            child = np.maximum(child, best.max(axis=2))
        q = self.discount * child.sum(axis=1) - self.move_energy[viewpoint, targets]
        _, m = move_or_declare(q[None], np.asarray(dec)[None])
        if m[0] >= 0:
            return ARAction("move", int(targets[m[0]]))
        return ARAction("declare", k)

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
