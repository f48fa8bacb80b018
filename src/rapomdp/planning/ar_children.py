"""The children of class beliefs under every move and label, and the sawtooth ratio.

A move to target j followed by label o turns the class belief b into the unnormalised child
b ⊙ P(o | ·, j). :class:`MoveChildren` forms every child of a block of beliefs at once and
their products with the solver's library (dot products, sawtooth ratios, backups); where the
confusion is "right with probability a_j(c), else the same w_j(c) for each wrong label", a
child is b ⊙ w_j plus one bump at the observed label, and the products cost O(|C|) per child
instead of O(|C|²).
"""

from __future__ import annotations

import numpy as np

from rapomdp.planning.rules import EQUAL_TOL


def min_ratio(u: np.ndarray, inv: np.ndarray, off: np.ndarray) -> np.ndarray:
    """min_c (u[..., c] inv[i, c] + off[i, c]) for every point i: (..., N) from u (..., C) and
    inv, off (N, C) (off: 0 on a point's support, +inf elsewhere).

    The sawtooth ratio φ_i. A running minimum over the classes, each step one product over
    (..., N), instead of a (..., N, C) temporary reduced over its short last axis: the same
    products and an order-free minimum, so the same bits, several times faster."""
    u = np.asarray(u)
    by_class = np.moveaxis(u, -1, 0)  # (C, ...)
    inv_t, off_t = np.ascontiguousarray(inv.T), np.ascontiguousarray(off.T)  # (C, N)
    has_off = np.isinf(off_t).any(axis=1)
    out = np.full(u.shape[:-1] + (inv.shape[0],), np.inf)
    term = np.empty_like(out)
    for c in range(u.shape[-1]):
        np.multiply(by_class[c][..., None], inv_t[c], out=term)
        if has_off[c]:
            term += off_t[c]
        np.minimum(out, term, out=out)
    return out


class MoveChildren:
    """Children of class beliefs under every move target a and label o.

    ``Pj[a, o, c]`` = P(o | c, targets[a]). With the structure P = w_j(c) off the diagonal
    and a_j(c) on it, the products use it (``fast``).
    """

    def __init__(self, Pj: np.ndarray) -> None:
        self.Pj = Pj
        n_j, n_o, n_c = Pj.shape
        self.fast = False
        self.idx = np.arange(n_c)
        if n_o == n_c:
            diag = Pj[:, self.idx, self.idx]  # (J, C)
            off = Pj.copy()
            off[:, self.idx, self.idx] = np.nan
            hi, lo = np.nanmax(off, axis=1), np.nanmin(off, axis=1)  # (J, C) over wrong o
            if np.all(hi - lo <= EQUAL_TOL):
                self.fast = True
                self.A, self.W, self.D = diag, lo, diag - lo

    def unnormalised(self, B: np.ndarray) -> np.ndarray:
        """u[k, a, o, c] = B[k, c] P(o | c, a): (K, J, O, C)."""
        return B[:, None, None, :] * self.Pj[None]

    def dots(self, B: np.ndarray, betas: np.ndarray) -> np.ndarray:
        """u[k, a, o] · β_m: (K, J, O, M)."""
        if self.fast:
            first = (B[:, None, :] * self.W[None]) @ betas.T  # (K, J, M)
            bump = B[:, None, :] * self.D[None]  # (K, J, O)
            return first[:, :, None, :] + bump[..., None] * betas.T[None, None]
        return self.unnormalised(B) @ betas.T

    def phi(self, B: np.ndarray, inv: np.ndarray, off: np.ndarray) -> np.ndarray:
        """min_c u[k, a, o, c] inv_i(c) (+inf off the point's support): (K, J, O, N)."""
        if self.fast:
            x = (B[:, None, :] * self.W[None])[:, :, None, :] * inv[None, None] + off
            part = np.partition(x, 1, axis=-1)  # (K, J, N, C)
            m1, m2 = part[..., 0], part[..., 1]
            arg = x.argmin(axis=-1)
            y = (B[:, None, :] * self.A[None])[:, :, None, :] * inv[None, None] + off
            excl = np.where(arg[..., None] == self.idx, m2[..., None], m1[..., None])
            return np.minimum(y, excl).transpose(0, 1, 3, 2)
        return min_ratio(self.unnormalised(B), inv, off)

    def backup(self, alpha: np.ndarray) -> np.ndarray:
        """Σ_o P(o | c, a) α[k, a, o, c]: (K, J, C)."""
        if self.fast:
            return self.W[None] * alpha.sum(axis=2) + self.D[None] * alpha[:, :, self.idx, self.idx]
        return np.einsum("aoc,kaoc->kac", self.Pj, alpha)
