"""The active-recognition solver's bounds against independent values: the Freudenthal-grid
upper bound (value iteration), heuristic threshold policies (lower values by simulation), and
the structured (fast) children against the plain ones."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.ar_solver import ActiveRecognitionSolver, _Moves, solve_active_recognition
from rapomdp.planning.grid_bound import FreudenthalGrid, grid_size, grid_upper_bound
from rapomdp.planning.momdp import benchmark_problem, update_beliefs


def grid_value(problem, resolution: int) -> float:
    g = grid_upper_bound(
        problem.observation_model, problem.move_cost(), problem.targets, problem.lambda_,
        problem.discount, resolution, tol=1e-9,
    )
    return float(g.evaluate(problem.start_belief[None], np.array([problem.start_viewpoint]))[0])


def threshold_policy_return(problem, tau: float, runs: int, seed: int) -> tuple[float, float]:
    """Declare when max belief ≥ tau, else move to the target with the best expected gain in
    max belief per unit cost; mean discounted return and its standard error."""
    rng = np.random.default_rng(seed)
    P, n_c = problem.observation_model, problem.n_classes
    cost = problem.move_cost()
    cls = rng.choice(n_c, size=runs, p=problem.start_belief)
    v = np.full(runs, problem.start_viewpoint)
    b = np.broadcast_to(problem.start_belief, (runs, n_c)).copy()
    ret, disc = np.zeros(runs), np.ones(runs)
    active = np.ones(runs, dtype=bool)
    for _ in range(60):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        bb = b[idx]
        stop = bb.max(axis=1) >= tau
        d = idx[stop]
        ret[d] += disc[d] * np.where(b[d].argmax(axis=1) == cls[d], 0.0, -problem.lambda_)
        active[d] = False
        m = idx[~stop]
        if not m.size:
            break
        u = b[m][:, None, None, :] * P[problem.targets].transpose(0, 2, 1)[None]  # (k,J,O,C)
        gain = u.max(axis=3).sum(axis=2) - b[m].max(axis=1)[:, None]
        j = problem.targets[np.argmax(gain / cost[v[m]], axis=1)]
        ret[m] -= disc[m] * problem.move_energy[v[m], j]
        disc[m] *= problem.discount
        cdf = np.cumsum(P[j, cls[m]], axis=1)
        labels = np.minimum((rng.random(m.size)[:, None] > cdf).sum(axis=1), n_c - 1)
        b[m] = update_beliefs(P, b[m], j, labels)
        v[m] = j
    ret[active] -= disc[active] * problem.lambda_
    return float(ret.mean()), float(ret.std(ddof=1) / np.sqrt(runs))


def test_grid_interpolation_reproduces_beliefs():
    rng = np.random.default_rng(0)
    for n_c, res in [(2, 7), (3, 5), (4, 6), (6, 3)]:
        grid = FreudenthalGrid(res, n_c)
        assert len(grid) == grid_size(res, n_c)
        B = np.vstack([rng.dirichlet(np.ones(n_c) * 0.5, size=200), grid.points[:20]])
        verts, w = grid.interpolation(B)
        assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
        assert np.allclose((grid.points[verts] * w[..., None]).sum(axis=1), B, atol=1e-9)


def test_structured_children_match_the_plain_ones():
    problem = benchmark_problem(5, 4, seed=3)
    Pj = np.ascontiguousarray(problem.observation_model.transpose(0, 2, 1))
    fast, plain = _Moves(Pj), _Moves(Pj)
    plain.fast = False
    assert fast.fast
    rng = np.random.default_rng(1)
    B = rng.dirichlet(np.ones(4), size=3)
    betas = rng.normal(size=(7, 4))
    pts = rng.dirichlet(np.ones(4), size=5)
    pts[0, 2] = 0.0
    pts[0] /= pts[0].sum()
    inv = np.where(pts > 0, 1.0 / np.where(pts > 0, pts, 1.0), 0.0)
    off = np.where(pts > 0, 0.0, np.inf)
    alpha = rng.normal(size=(3, 5, 4, 4))
    assert np.allclose(fast.dots(B, betas), plain.dots(B, betas))
    assert np.allclose(fast.phi(B, inv, off), plain.phi(B, inv, off))
    assert np.allclose(fast.backup(alpha), plain.backup(alpha))


@pytest.mark.parametrize("grid", [False, True])
def test_bounds_bracket_and_converge_to_the_grid_value(grid):
    problem = benchmark_problem(5, 3, seed=4)
    fine = grid_value(problem, 96)  # an upper bound, within ~1e-3 of the value here
    result = solve_active_recognition(problem, precision=2e-3, timeout=5, grid=grid)
    assert result.lower <= fine + 1e-9
    assert result.upper >= result.lower - 1e-9
    assert result.lower == pytest.approx(fine, abs=1e-2)
    # without the grid the sawtooth alone is slower to close
    assert result.upper == pytest.approx(fine, abs=1e-2 if grid else 0.15)


def test_grid_bounds_decrease_with_resolution_and_stay_above_the_lower_bound():
    problem = benchmark_problem(6, 3, seed=5)
    coarse, fine = grid_value(problem, 8), grid_value(problem, 48)
    result = solve_active_recognition(problem, precision=1e-3, timeout=3, grid=False)
    assert fine <= coarse + 1e-9
    assert result.lower <= fine + 1e-9


def test_heuristic_policies_never_beat_the_upper_bound():
    problem = benchmark_problem(8, 4, seed=0)
    solver = ActiveRecognitionSolver(problem)
    result = solver.solve(precision=1e-3, timeout=4)
    best = -np.inf
    for tau in (0.6, 0.8, 0.9, 0.95):
        mean, se = threshold_policy_return(problem, tau, 3000, seed=int(tau * 100))
        assert mean <= result.upper + 4 * se
        best = max(best, mean)
    # the solver's policy is at least as good as the best threshold rule (within noise)
    assert result.lower >= best - 0.1
