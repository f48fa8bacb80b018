"""Flat bounds: blind policies (exact and iterated), the fast informed bound cut at any
deadline, alpha-vector pruning and the sawtooth upper bound."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning import bounds
from rapomdp.planning.bounds import (
    AlphaVectorSet,
    SawtoothUpperBound,
    blind_policy_alphas,
    fast_informed_bound,
    flat_solver_bytes,
)
from rapomdp.planning.pomdp import POMDP


def random_pomdp(seed: int, n_s: int = 5, n_a: int = 3, n_z: int = 2) -> POMDP:
    rng = np.random.default_rng(seed)
    return POMDP.from_arrays(rng.dirichlet(np.ones(n_s), size=(n_a, n_s)),
                             rng.dirichlet(np.ones(n_z), size=(n_a, n_s)),
                             rng.uniform(-1, 1, size=(n_a, n_s)), 0.9, np.full(n_s, 1 / n_s))


def test_iterated_blind_policies_are_lower_bounds_that_reach_the_exact_ones(monkeypatch):
    pomdp = random_pomdp(0)
    exact = blind_policy_alphas(pomdp)
    # α_a = R_a + γ T_a α_a
    np.testing.assert_allclose(exact, pomdp.R + 0.9 * np.einsum("ast,at->as", pomdp.T, exact))
    monkeypatch.setattr(bounds, "EXACT_BLIND_STATES", 0)
    iterated = blind_policy_alphas(pomdp, tol=1e-12)
    np.testing.assert_allclose(iterated, exact, atol=1e-9)
    cut = blind_policy_alphas(pomdp, deadline=-np.inf)  # no time at all: the trivial bound
    assert np.all(cut <= exact + 1e-12)
    assert np.allclose(cut, pomdp.R.min() / (1 - 0.9))


def test_the_fast_informed_bound_is_an_upper_bound_at_every_cut():
    pomdp = random_pomdp(1)
    full = fast_informed_bound(pomdp)
    early = fast_informed_bound(pomdp, max_iter=3)
    none = fast_informed_bound(pomdp, deadline=-np.inf)
    assert np.all(early >= full - 1e-12) and np.all(none >= early)
    assert np.allclose(none, pomdp.R.max() / (1 - 0.9))
    # above every blind policy's value
    assert np.all(full.max(axis=0) >= blind_policy_alphas(pomdp).max(axis=0) - 1e-9)


def test_pruning_keeps_the_vectors_best_somewhere_and_the_sawtooth_bounds_from_above():
    alphas = np.array([[1.0, 0.0], [0.0, 1.0], [0.4, 0.4], [0.6, 0.6]])
    lower = AlphaVectorSet(alphas, np.arange(4))
    beliefs = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    assert lower.prune(beliefs) == 1  # [0.4, 0.4] is best nowhere
    assert lower.actions.tolist() == [0, 1, 3]
    upper = SawtoothUpperBound(np.array([1.0, 1.0]))
    upper.add(np.array([0.5, 0.5]), 0.6)
    upper.add(np.array([0.5, 0.5]), 2.0)  # above the corners: not kept
    assert len(upper) == 1
    b = np.linspace(0, 1, 11)
    grid = np.stack([b, 1 - b], axis=1)
    values = upper.values(grid)
    assert values[5] == pytest.approx(0.6)
    assert np.all(values >= lower.values(grid) - 1e-12) and np.all(values <= 1.0 + 1e-12)


def test_the_memory_estimate_counts_the_informed_bound():
    # T alone (8·A·S²) and the informed bound's two A·S·Z·A arrays (8 · 2 · 40·1000·40·40)
    assert flat_solver_bytes(1000, 40, 40) > 8 * 40 * 1000 * 1000 + 8 * 2 * 40 * 1000 * 40 * 40
    assert flat_solver_bytes(2, 3, 2) < 1e8


def test_the_fast_informed_bound_is_its_backup_written_out():
    """Each iteration is Q ← R + γ Σ_o max_a' Σ_s' T(s,a,s') O(s',a,o) Q(s',a'), computed here
    by loops over a small random POMDP (two iterations: the second's Q differs by action)."""
    pomdp = random_pomdp(3, n_z=3)
    n_a, n_s, n_z = pomdp.Z.shape

    def backup(q: np.ndarray) -> np.ndarray:
        out = np.empty_like(q)
        for a in range(n_a):
            for s in range(n_s):
                total = sum(max(sum(pomdp.T[a, s, t] * pomdp.Z[a, t, o] * q[b, t]
                                    for t in range(n_s)) for b in range(n_a))
                            for o in range(n_z))
                out[a, s] = pomdp.R[a, s] + pomdp.discount * total
        return out

    q0 = np.full(pomdp.R.shape, pomdp.R.max() / (1 - pomdp.discount))
    np.testing.assert_allclose(fast_informed_bound(pomdp, max_iter=1), backup(q0), rtol=1e-12)
    np.testing.assert_allclose(fast_informed_bound(pomdp, max_iter=2), backup(backup(q0)),
                               rtol=1e-12)
