"""The structured active-recognition solver: memory plan (cap, fallback, note) and clock."""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest

from rapomdp.planning.ar_solver import ActiveRecognitionSolver, solve_active_recognition
from rapomdp.planning.memory import MemoryCapError
from rapomdp.planning.momdp import benchmark_problem


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
