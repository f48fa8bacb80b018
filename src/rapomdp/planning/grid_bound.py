"""Grid upper bound for the active-recognition MOMDP (Lovejoy 1991, Freudenthal triangulation).

The value V(v, ·) of each viewpoint is convex on the class simplex, so the piecewise-linear
interpolation of its values at the vertices of a triangulation lies above it. Take the regular
grid {b : N·b integer} with Freudenthal's triangulation (Lovejoy's coordinates
y_i = N Σ_{k≥i} b_k, i = 2..C), and iterate

    U(v, g) ← max(declare(g), max_j −E[v, j] + γ Σ_o p(o | g, j) Ũ(j, child(g, j, o)))

at the grid points g, Ũ the interpolation. Starting from U = 0 ≥ V*, every iterate stays an
upper bound (the operator is monotone and Ũ ≥ V* where U ≥ V*, by convexity), so the bound is
valid whenever the iteration is stopped. The continuation term does not depend on the
viewpoint v we leave, so one sparse product per iteration serves all viewpoints.

Affordable while the grid is small: C(N + C − 1, C − 1) points; with 4 classes a fine grid
(N = 32: 6545 points) is tight to a fraction of a percent, with 10 classes N = 4…6 already
beats a long point-based run; with 35 classes even N = 2 is too large to be worth it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from math import comb

import numpy as np

from rapomdp.planning.memory import ENTRY_BYTES
from rapomdp.planning.rules import declare_value


def grid_size(n: int, n_classes: int) -> int:
    """Number of points of the grid {b : N·b integer} on the simplex of ``n_classes``."""
    return comb(n + n_classes - 1, n_classes - 1)


def grid_entries(resolution: int, n_classes: int, n_targets: int, n_labels: int) -> int:
    """Non-zeros of the grid's transition matrix: every (target, point, label) child
    interpolates over ``n_classes`` vertices (the measure of its build and sweep time)."""
    return grid_size(resolution, n_classes) * n_targets * n_labels * n_classes


def grid_bytes(resolution: int, n_classes: int, n_viewpoints: int, n_targets: int,
               n_labels: int) -> int:
    """Peak bytes :func:`grid_upper_bound` allocates, estimated from the sizes alone.

    The sparse matrix's triplets, their concatenation and the CSR copy (about 80 bytes per
    non-zero); one target's children and their interpolation (16 arrays of G·O·C); the value
    arrays (V, G) and a seeding evaluation (V, G, C); the sweep's blocks (4·10⁶ entries).
    """
    n_g = grid_size(resolution, n_classes)
    nnz = grid_entries(resolution, n_classes, n_targets, n_labels)
    per_target = 16 * n_g * n_labels * n_classes
    values = (3 * n_viewpoints + n_targets) * n_g + n_viewpoints * n_g * n_classes
    return 80 * nnz + ENTRY_BYTES * (per_target + values + 2 * 4_000_000 + 3 * n_g * n_classes)


class FreudenthalGrid:
    """The grid {b : N·b integer} over the C-simplex and interpolation in its triangulation."""

    def __init__(self, resolution: int, n_classes: int) -> None:
        if resolution < 1 or n_classes < 2:
            raise ValueError("grid needs resolution >= 1 and at least two classes")
        self.n, self.n_classes = resolution, n_classes
        # all integer y with N >= y_2 >= ... >= y_C >= 0
        ys = np.zeros((1, 0), dtype=np.int64)
        for _ in range(n_classes - 1):
            hi = ys[:, -1] if ys.shape[1] else np.full(ys.shape[0], resolution)
            reps = hi + 1
            rows = np.repeat(np.arange(ys.shape[0]), reps)
            starts = np.cumsum(reps) - reps
            new = np.arange(rows.size) - np.repeat(starts, reps)
            ys = np.concatenate([ys[rows], new[:, None]], axis=1)
        self.y = ys
        full = np.concatenate(
            [np.full((ys.shape[0], 1), resolution), ys, np.zeros((ys.shape[0], 1), np.int64)],
            axis=1,
        )
        self.points = (full[:, :-1] - full[:, 1:]) / resolution  # (G, C)
        # lexicographic rank of a non-increasing y: Σ_k #sequences that share y_1..y_{k-1}
        # and have a smaller k-th entry = Σ_k comb(y_k + d − 1 − k, d − k) (k from 0, d = C − 1)
        d = n_classes - 1
        self._rank_terms = np.array(
            [[comb(y + d - 1 - k, d - k) for y in range(resolution + 1)] for k in range(d)],
            dtype=np.int64,
        )  # (d, N + 1), every entry < len(self)

    def __len__(self) -> int:
        return self.points.shape[0]

    def index(self, y: np.ndarray) -> np.ndarray:
        """Index of the grid point with Lovejoy coordinates ``y`` (..., C − 1); −1 where ``y``
        is not one (not non-increasing or outside [0, N]). No table over all codes: the
        rank is computed, so memory stays O(C·N) for any number of classes."""
        y = np.asarray(y, dtype=np.int64)
        valid = np.all((y >= 0) & (y <= self.n), axis=-1)
        if y.shape[-1] > 1:
            valid &= np.all(y[..., 1:] <= y[..., :-1], axis=-1)
        safe = np.where(valid[..., None], y, 0)
        rank = self._rank_terms[np.arange(y.shape[-1]), safe].sum(axis=-1)
        return np.where(valid, rank, -1)

    def interpolation(self, beliefs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vertex indices (K, C) and barycentric weights (K, C) of beliefs (K, C)."""
        b = np.asarray(beliefs, dtype=np.float64)
        cs = np.cumsum(b[:, ::-1], axis=1)[:, ::-1]
        y = np.clip(self.n * cs[:, 1:], 0.0, self.n)
        v0 = np.minimum(np.floor(y + 1e-9), self.n).astype(np.int64)
        # keep the base vertex itself valid (monotone) when rounding made it not so
        v0 = np.minimum.accumulate(v0, axis=1)
        d = np.clip(y - v0, 0.0, 1.0)
        order = np.argsort(-d, axis=1, kind="stable")
        ds = np.take_along_axis(d, order, axis=1)
        k_n, dim = y.shape
        verts = np.empty((k_n, dim + 1), dtype=np.int64)
        w = np.empty((k_n, dim + 1))
        cur = v0.copy()
        rows = np.arange(k_n)
        verts[:, 0] = self.index(cur)
        w[:, 0] = 1.0 - ds[:, 0]
        for k in range(1, dim + 1):
            cur[rows, order[:, k - 1]] += 1
            idx = self.index(np.minimum(cur, self.n))
            verts[:, k] = idx
            w[:, k] = ds[:, k - 1] - (ds[:, k] if k < dim else 0.0)
        bad = verts < 0
        if np.any(bad & (w > 1e-7)):
            raise AssertionError("interpolation reached outside the grid")
        verts[bad] = 0
        w[bad] = 0.0
        w = np.clip(w, 0.0, None)
        return verts, w / w.sum(axis=1, keepdims=True)


class GridUpperBound:
    """Interpolated grid values per viewpoint: an upper bound on V*(v, b) at every belief."""

    def __init__(self, grid: FreudenthalGrid, values: np.ndarray, sweeps: int, residual: float):
        self.grid = grid
        self.values = values  # (V, G)
        self.sweeps = sweeps
        self.residual = residual

    def evaluate(self, beliefs: np.ndarray, viewpoints: np.ndarray | None = None) -> np.ndarray:
        """Upper bound at beliefs (K, C): (K, V) for every viewpoint, or (K,) at
        ``viewpoints`` (K,)."""
        verts, w = self.grid.interpolation(np.atleast_2d(beliefs))
        if viewpoints is None:
            return np.einsum("kc,vkc->kv", w, self.values[:, verts])
        return (self.values[np.asarray(viewpoints)[:, None], verts] * w).sum(axis=1)


def grid_upper_bound(
    observation_model: np.ndarray,
    move_cost: np.ndarray,
    targets: np.ndarray,
    lambda_: float,
    discount: float,
    resolution: int,
    deadline: float = np.inf,
    clock: Callable[[], float] = time.process_time,
    tol: float = 1e-6,
    max_sweeps: int = 2000,
    initial: GridUpperBound | None = None,
) -> GridUpperBound:
    """Value iteration on the Freudenthal grid of ``resolution``; stops at ``tol``, at
    ``max_sweeps`` or at ``deadline`` (on ``clock``) with a valid bound in every case.

    ``observation_model`` (V, S, O) (S hidden states: the O classes, or T types of them; the
    grid lies on the S-simplex); ``move_cost`` (V, J) to the ``targets`` (inf where a
    move is forbidden). ``initial`` (a coarser bound) seeds the iteration: the minimum of two
    upper bounds is one.
    """
    import scipy.sparse as sp  # here: planning's import stays light (start-up of the CLI)

    P = np.asarray(observation_model, dtype=np.float64)
    n_v, n_c, n_o = P.shape
    grid = FreudenthalGrid(resolution, n_c)
    pts = grid.points
    n_g, n_j = len(grid), len(targets)
    dec = declare_value(pts, lambda_, n_o)
    rows, cols, vals = [], [], []
    for a, j in enumerate(targets):
        if clock() > deadline:
            break
        u = pts[:, None, :] * P[j].T[None, :, :]  # (G, O, C)
        prob = u.sum(axis=2)
        ok = prob > 0
        gi, oi = np.nonzero(ok)
        verts, w = grid.interpolation(u[gi, oi] / prob[gi, oi, None])
        rows.append(np.repeat(a * n_g + gi, n_c))
        cols.append((a * n_g + verts).ravel())
        vals.append((w * prob[gi, oi, None]).ravel())
    if len(rows) < n_j:  # out of time while building: the trivial bound
        return GridUpperBound(grid, np.zeros((n_v, n_g)), 0, np.inf)
    M = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n_j * n_g, n_j * n_g),
    )
    M.sum_duplicates()
    U = np.zeros((n_v, n_g))
    if initial is not None:
        U = np.minimum(U, initial.evaluate(pts).T)
    cost = np.asarray(move_cost, dtype=np.float64)
    sweeps, residual = 0, np.inf
    while sweeps < max_sweeps:
        if clock() > deadline:
            break
        sweeps += 1
        cont = (discount * (M @ U[targets].ravel())).reshape(n_j, n_g)  # (J, G)
        new = np.empty((n_v, n_g))
        step = max(1, 4_000_000 // (n_j * n_g))
        for v in range(0, n_v, step):  # max over targets in blocks of viewpoints
            q = cont[None] - cost[v : v + step, :, None]  # (v, J, G); -inf where forbidden
            new[v : v + step] = np.maximum(dec[None], q.max(axis=1))
        new = np.minimum(new, U)
        residual = float(np.abs(new - U).max())
        U = new
        if residual < tol:
            break
    return GridUpperBound(grid, U, sweeps, residual)
