"""Value-function bounds for flat POMDPs: alpha-vector lower bound, sawtooth upper bound.

The lower bound is a set of alpha vectors, each the value of a conditional plan, so it is the
value of a policy in hand; it starts from the blind policies ("always do a"). The upper bound is
the fast informed bound (FIB, Hauskrecht 2000) at the corners of the simplex plus belief points
with values, combined by sawtooth interpolation (Hauskrecht 2000; used by HSVI and SARSOP).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from rapomdp.planning.memory import ENTRY_BYTES
from rapomdp.planning.pomdp import POMDP
from rapomdp.planning.rules import EQUAL_TOL

#: States up to which the blind policies are solved exactly (a dense solve, ~S³ flops per
#: action); beyond, they are iterated, with the deadline checked at every sweep.
EXACT_BLIND_STATES = 600


def blind_policy_alphas(
    pomdp: POMDP,
    deadline: float = np.inf,
    clock: Callable[[], float] = time.process_time,
    tol: float = 1e-7,
) -> np.ndarray:
    """(A, S) lower bounds on the values of the blind policies (α_a = R_a + γ T_a α_a).

    Exact (a linear solve) for small problems; otherwise iterated from the trivial bound
    min R / (1 − γ), which keeps every iterate a lower bound, until ``tol`` or ``deadline``.
    """
    n_a, n_s = pomdp.n_actions, pomdp.n_states
    g, T, R = pomdp.discount, pomdp.T, pomdp.R
    if n_s <= EXACT_BLIND_STATES:
        eye = np.eye(n_s)
        return np.stack([np.linalg.solve(eye - g * T[a], R[a]) for a in range(n_a)])
    alphas = np.full((n_a, n_s), R.min() / (1.0 - g))
    while clock() <= deadline:
        nxt = R + g * np.matmul(T, alphas[:, :, None])[..., 0]
        step = float(np.abs(nxt - alphas).max())
        alphas = nxt
        if step < tol:
            break
    return alphas


def fast_informed_bound(
    pomdp: POMDP,
    tol: float = 1e-7,
    max_iter: int = 10_000,
    deadline: float = np.inf,
    clock: Callable[[], float] = time.process_time,
) -> np.ndarray:
    """Q(a, s) of the fast informed bound, iterated towards its fixed point (an upper bound on
    Q* at every iterate: it starts from max R / (1 − γ) and decreases), until ``tol``,
    ``max_iter`` or ``deadline``.

    Q(s,a) = R(s,a) + γ Σ_o max_a' Σ_s' T(s,a,s') O(s',a,o) Q(s',a').
    """
    T, Z, R, g = pomdp.T, pomdp.Z, pomdp.R, pomdp.discount
    Q = np.full(R.shape, R.max() / (1.0 - g))
    n_a, n_s, n_z = Z.shape
    for _ in range(max_iter):
        if clock() > deadline:
            return Q
        # M[a, s', (o, a')] = O(s', a, o) Q(s', a'); one product with T[a] per action gives
        # Σ_s' T(s,a,s') O(s',a,o) Q(s',a') for every (o, a') without an A·Z·S² array
        M = (Z[:, :, :, None] * Q.T[None, :, None, :]).reshape(n_a, n_s, -1)
        nxt = R + g * np.matmul(T, M).reshape(n_a, n_s, n_z, -1).max(axis=-1).sum(axis=-1)
        if np.max(np.abs(nxt - Q)) < tol:
            return nxt
        Q = nxt
    return Q


def flat_solver_bytes(n_states: int, n_actions: int, n_observations: int) -> int:
    """Bytes the flat solver's fixed arrays take, estimated from the sizes alone.

    The model (T: A·S², O: A·S·Z, R), the fast informed bound's two A·S·Z·A arrays (O times
    Q, and its product with T), a dense blind solve (2·S²), one belief's children (6·A·S·Z) and
    the batched sweep's blocks (2 × 4·10⁶).
    """
    s, a, z = n_states, n_actions, n_observations
    model = a * s * s + a * s * z + 2 * a * s
    fib = 2 * a * s * z * a
    blind = 2 * s * s if s <= EXACT_BLIND_STATES else 3 * a * s
    return ENTRY_BYTES * (model + fib + blind + 6 * a * s * z + 8_000_000)


class AlphaVectorSet:
    """A lower bound: max over alpha vectors, each tagged with its first action."""

    def __init__(self, alphas: np.ndarray, actions: np.ndarray) -> None:
        self.alphas = np.ascontiguousarray(alphas, dtype=np.float64)
        self.actions = np.asarray(actions, dtype=np.int64)

    def __len__(self) -> int:
        return self.alphas.shape[0]

    def values(self, beliefs: np.ndarray) -> np.ndarray:
        """Lower-bound values at beliefs (..., S)."""
        return (beliefs @ self.alphas.T).max(axis=-1)

    def add(self, alpha: np.ndarray, action: int) -> None:
        self.alphas = np.vstack([self.alphas, alpha[None, :]])
        self.actions = np.append(self.actions, action)

    def prune(self, beliefs: np.ndarray) -> int:
        """Keep only vectors that are best at one of ``beliefs`` (SARSOP's pruning at the
        sampled beliefs); pointwise-dominated vectors never are. Returns how many went."""
        best = np.unique(np.argmax(beliefs @ self.alphas.T, axis=1))
        removed = len(self) - best.size
        self.alphas = self.alphas[best]
        self.actions = self.actions[best]
        return removed


class SawtoothUpperBound:
    """Corner values plus (belief, value) points, interpolated by the sawtooth rule.

    For convex V*, V*(b) ≤ b·v_c + φ_i(b) (v_i − b_i·v_c) with φ_i(b) = min_{s: b_i(s)>0}
    b(s)/b_i(s), for every point i; the bound is the minimum over points and the corners.
    """

    def __init__(self, corners: np.ndarray) -> None:
        self.corners = np.asarray(corners, dtype=np.float64)
        n_s = self.corners.size
        self.points = np.zeros((0, n_s))
        self.values_ = np.zeros(0)
        self._inv = np.zeros((0, n_s))
        self._off = np.zeros((0, n_s))
        self._support = np.zeros((0, n_s))
        self._excess = np.zeros(0)

    def __len__(self) -> int:
        return self.points.shape[0]

    def values(self, beliefs: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
        """Upper-bound values at beliefs (M, S) or (S,).

        A point whose support is not inside a query's support has φ = 0 there and cannot
        tighten it, so only (point, query) pairs with nested supports are evaluated: on sparse
        beliefs (grid worlds) that skips most of the work; on dense ones every pair counts.
        """
        single = beliefs.ndim == 1
        B = np.atleast_2d(beliefs)
        out = B @ self.corners
        n, s = self._inv.shape
        if n:
            m = B.shape[0]
            outside = self._support @ (B <= 0).T.astype(np.float64)  # (N, M) states missed
            nested = outside < 0.5
            n_pairs = int(nested.sum())
            if n_pairs > 0.3 * n * m:  # dense beliefs: broadcast over all pairs, in chunks
                best = np.empty((n, m))
                step = max(1, chunk // (n * s))
                for i in range(0, m, step):
                    ratio = B[None, i : i + step, :] * self._inv[:, None, :]
                    ratio += self._off[:, None, :]
                    best[:, i : i + step] = ratio.min(axis=2)
                best *= self._excess[:, None]
                best[~nested] = 0.0
                out = out + np.minimum(best.min(axis=0), 0.0)
            elif n_pairs:  # sparse beliefs: only (point, query) pairs with nested supports
                pi, qm = np.nonzero(nested)
                best = np.zeros((n, m))
                step = max(1, chunk // s)
                for i in range(0, pi.size, step):
                    ii, mm = pi[i : i + step], qm[i : i + step]
                    # φ = min over the point's support of b(s)/b_i(s): the inverse is 0 off the
                    # support and the +inf offset there makes those states impose nothing.
                    ratio = B[mm] * self._inv[ii]
                    ratio += self._off[ii]
                    best[ii, mm] = ratio.min(axis=1) * self._excess[ii]
                out = out + best.min(axis=0)
        return out[0] if single else out

    def add(self, belief: np.ndarray, value: float) -> None:
        excess = value - float(belief @ self.corners)
        if excess >= 0:
            return
        support = belief > 0
        inv = np.where(support, 1.0 / np.where(support, belief, 1.0), 0.0)
        off = np.where(support, 0.0, np.inf)
        self.points = np.vstack([self.points, belief[None, :]])
        self.values_ = np.append(self.values_, value)
        self._inv = np.vstack([self._inv, inv[None, :]])
        self._off = np.vstack([self._off, off[None, :]])
        self._support = np.vstack([self._support, support[None, :].astype(np.float64)])
        self._excess = np.append(self._excess, excess)

    def prune(self, chunk: int = 4_000_000) -> int:
        """Drop points that a single other point already bounds as tightly (vectorised; ties
        keep the older point). The bound stays valid; it only loses redundant points."""
        n, s = self._inv.shape
        if n < 2:
            return 0
        drop = np.zeros(n, dtype=bool)
        idx = np.arange(n)
        step = max(1, chunk // (n * s))
        for i in range(0, n, step):
            rows = slice(i, min(n, i + step))
            ratio = self.points[rows, None, :] * self._inv[None, :, :]
            ratio += self._off[None, :, :]
            bound = ratio.min(axis=2) * self._excess[None, :]  # (rows, n): j's bound at b_i
            own = self._excess[rows, None]
            later = idx[None, :] > idx[rows, None]
            earlier = idx[None, :] < idx[rows, None]
            dominated = ((later & (bound <= own + EQUAL_TOL))
                         | (earlier & (bound < own - EQUAL_TOL)))
            drop[rows] = dominated.any(axis=1)
        keep = ~drop
        self.points, self.values_ = self.points[keep], self.values_[keep]
        self._inv, self._excess = self._inv[keep], self._excess[keep]
        self._off, self._support = self._off[keep], self._support[keep]
        return int(drop.sum())
