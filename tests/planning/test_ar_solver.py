"""The structured active-recognition solver: memory plan (cap, fallback, note) and clock."""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest

from rapomdp.planning.ar_children import MoveChildren, min_ratio
from rapomdp.planning.ar_solver import ActiveRecognitionSolver, solve_active_recognition
from rapomdp.planning.memory import MemoryCapError
from rapomdp.planning.momdp import benchmark_problem, update_beliefs
from tests.planning.planning_fixtures import grid_value


def test_forty_classes_solve_under_a_small_cap_without_the_grid_and_say_so() -> None:
    problem = benchmark_problem(8, 40, seed=0)
    # under the default cap the plan uses the grid (resolution 2 fits)
    assert ActiveRecognitionSolver(problem).max_resolution >= 2
    cap_gb = 0.3
    tracemalloc.start()
    try:
        result = solve_active_recognition(problem, precision=1e-3, timeout=1e6,
                                          max_iterations=4, memory_gb=cap_gb)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert result.note.startswith("upper bound: sawtooth only, grid skipped (resolution 2 "
                                  "needs ")
    assert "300 MB cap" in result.note
    assert peak < cap_gb * 1e9
    declare_at_once = -problem.lambda_ * 39 / 40
    assert declare_at_once - 1e-9 <= result.lower <= result.upper <= 0.0
    assert result.lower > declare_at_once + 1.0  # looking first is worth much more here


def test_a_problem_that_cannot_fit_is_refused_before_allocation() -> None:
    problem = benchmark_problem(256, 100, seed=0)
    tracemalloc.start()
    try:
        with pytest.raises(MemoryCapError, match=r"256 viewpoints x 100 classes, 256 move "
                                                 r"targets\) needs about [\d.]+ MB, over the "
                                                 r"memory cap of 100 MB"):
            ActiveRecognitionSolver(problem, memory_gb=0.1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.1e9
    with pytest.raises(ValueError, match="memory_gb must be a positive finite number"):
        ActiveRecognitionSolver(problem, memory_gb=float("nan"))


def test_many_classes_and_viewpoints_plan_within_the_cap() -> None:
    """2 to 100 classes, up to 256 viewpoints: planned within 4 GB, grid only where cheap."""
    for n_v, n_c in [(16, 2), (64, 22), (128, 85), (256, 100)]:
        solver = ActiveRecognitionSolver(benchmark_problem(n_v, n_c, seed=1))
        used = solver.working_bytes(solver.chunk, n_v, n_v, n_c)
        assert used < 4e9
        assert (solver.max_resolution > 0) == (n_c <= 22), (n_v, n_c, solver.note)
        assert solver.max_vectors > 100_000 and solver.max_points > 10_000


def test_sleeping_does_not_consume_the_cpu_budget() -> None:
    problem = benchmark_problem(16, 4, seed=0)
    slept: list[float] = []

    def sleepy(progress: object) -> None:  # a slow terminal, a suspended process...
        if not slept:
            time.sleep(0.6)
            slept.append(0.6)

    wall = time.perf_counter()
    result = solve_active_recognition(problem, precision=1e-9, timeout=0.4, callback=sleepy,
                                      report_every=1e9, grid=False)
    wall = time.perf_counter() - wall
    assert slept and wall > 0.6
    # the budget is CPU time: the 0.6 s asleep did not count, the solver kept working
    assert 0.4 <= result.elapsed <= 0.4 * 1.05 + 0.02
    assert result.iterations > 0


def test_the_solver_stops_within_five_percent_of_its_budget() -> None:
    problem = benchmark_problem(64, 35, seed=0)  # slow backups: the overshoot is visible
    start = time.process_time()
    result = solve_active_recognition(problem, precision=1e-9, timeout=1.0, report_every=1e9)
    spent = time.process_time() - start
    assert 1.0 <= result.elapsed <= 1.05
    assert spent <= 1.05 + 0.1  # the final pruning and the policy's arrays
    assert np.isfinite(result.lower) and result.lower <= result.upper


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


def test_structured_children_match_the_plain_ones():
    problem = benchmark_problem(5, 4, seed=3)
    Pj = np.ascontiguousarray(problem.observation_model.transpose(0, 2, 1))
    fast, plain = MoveChildren(Pj), MoveChildren(Pj)
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


def test_min_ratio_gives_the_bits_of_the_direct_minimum():
    # the sawtooth ratio by a running minimum over classes equals the (..., N, C) temporary's
    # minimum bit for bit: zero children, points off their support, an all-zero child
    rng = np.random.default_rng(4)
    u = rng.dirichlet(np.ones(6) * 0.4, size=(3, 5, 6)) * rng.uniform(0, 1, size=(3, 5, 6, 1))
    u[0, 0, 0] = 0.0
    u[1, 2, :, 3] = 0.0
    pts = rng.dirichlet(np.ones(6) * 0.5, size=9)
    pts[[0, 4], [2, 5]] = 0.0
    pts /= pts.sum(axis=1, keepdims=True)
    inv = np.where(pts > 0, 1.0 / np.where(pts > 0, pts, 1.0), 0.0)
    off = np.where(pts > 0, 0.0, np.inf)
    direct = (u[..., None, :] * inv + off).min(axis=-1)
    fast = min_ratio(u, inv, off)
    assert fast.shape == (3, 5, 6, 9)
    assert np.array_equal(fast, direct)
    assert np.all(fast[0, 0, 0] == 0.0)  # an all-zero child is 0 times every point
    assert np.array_equal(min_ratio(u[0, 0], inv, off), direct[0, 0])


@pytest.mark.parametrize("grid", [False, True])
def test_bounds_bracket_and_converge_to_the_grid_value(grid):
    problem = benchmark_problem(5, 3, seed=4)
    fine = grid_value(problem, 96)  # an upper bound, within ~1e-3 of the value here
    result = solve_active_recognition(problem, precision=2e-3, timeout=1e6, grid=grid,
                                      max_iterations=180)
    assert result.lower <= fine + 1e-9
    assert result.upper >= result.lower - 1e-9
    assert result.lower == pytest.approx(fine, abs=1e-2)
    # without the grid the sawtooth alone is slower to close
    assert result.upper == pytest.approx(fine, abs=1e-2 if grid else 0.15)


def test_heuristic_policies_never_beat_the_upper_bound():
    problem = benchmark_problem(8, 4, seed=0)
    solver = ActiveRecognitionSolver(problem, grid=16)  # a fixed grid: the budget is iterations
    result = solver.solve(precision=1e-3, timeout=1e6, max_iterations=40)
    best = -np.inf
    for tau in (0.6, 0.8, 0.9, 0.95):
        mean, se = threshold_policy_return(problem, tau, 3000, seed=int(tau * 100))
        assert mean <= result.upper + 4 * se
        best = max(best, mean)
    # the solver's policy is at least as good as the best threshold rule (within noise)
    assert result.lower >= best - 0.1
