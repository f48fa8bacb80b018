"""The Freudenthal grid and its upper bound: interpolation, monotone in the resolution."""

from __future__ import annotations

import numpy as np

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.grid_bound import FreudenthalGrid, grid_size
from rapomdp.planning.momdp import benchmark_problem
from tests.planning.planning_fixtures import grid_value


def test_grid_interpolation_reproduces_beliefs():
    rng = np.random.default_rng(0)
    for n_c, res in [(2, 7), (3, 5), (4, 6), (6, 3)]:
        grid = FreudenthalGrid(res, n_c)
        assert len(grid) == grid_size(res, n_c)
        B = np.vstack([rng.dirichlet(np.ones(n_c) * 0.5, size=200), grid.points[:20]])
        verts, w = grid.interpolation(B)
        assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
        assert np.allclose((grid.points[verts] * w[..., None]).sum(axis=1), B, atol=1e-9)


def test_grid_bounds_decrease_with_resolution_and_stay_above_the_lower_bound():
    problem = benchmark_problem(6, 3, seed=5)
    coarse, fine = grid_value(problem, 8), grid_value(problem, 48)
    result = solve_active_recognition(problem, precision=1e-3, timeout=1e6, grid=False,
                                      max_iterations=100)
    assert fine <= coarse + 1e-9
    assert result.lower <= fine + 1e-9
