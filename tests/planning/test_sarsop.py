"""The flat SARSOP-style solver keeps its word: CPU-time budget in every phase, memory
estimated and refused before allocation, NaN and infinite options refused."""

from __future__ import annotations

import time

import numpy as np
import pytest
from planning_fixtures import TIGER

from rapomdp.planning.bounds import EXACT_BLIND_STATES, flat_solver_bytes
from rapomdp.planning.io_pomdp import parse_pomdp
from rapomdp.planning.memory import MemoryCapError
from rapomdp.planning.sarsop import FlatSarsop, solve_pomdp


def big_file(n_states: int) -> str:
    """A short file declaring many states (dense arrays of n_states², every phase slow)."""
    return (f"discount: 0.95\nvalues: reward\nstates: {n_states}\nactions: 2\n"
            "observations: 2\nstart: uniform\nT: 0 identity\nT: 1 uniform\nO: * uniform\n"
            "R: 0 : * : * : * 1\nR: 1 : 7 : * : * 50\n")


def test_every_phase_stops_within_the_cpu_budget() -> None:
    pomdp = parse_pomdp(big_file(2000))
    assert pomdp.n_states > EXACT_BLIND_STATES  # the blind policies are iterated too
    start = time.process_time()
    result = solve_pomdp(pomdp, precision=1e-9, timeout=1.0, report_every=1e9)
    spent = time.process_time() - start
    assert not result.converged
    assert result.elapsed <= 1.05 and spent <= 1.1
    # valid bounds whatever phase was cut: blind "always 0" is worth 1/(1-γ) = 20 at most,
    # and nothing is worth more than 50/(1-γ)
    assert 0.0 <= result.lower <= 20.0 + 1e-9
    assert result.lower <= result.upper <= 50.0 / 0.05 + 1e-9


def test_sleeping_does_not_consume_the_budget() -> None:
    pomdp = parse_pomdp(big_file(1000))
    naps: list[float] = []

    def nap(progress: object) -> None:
        if not naps:
            time.sleep(0.5)
            naps.append(0.5)

    wall = time.perf_counter()
    result = solve_pomdp(pomdp, precision=1e-9, timeout=0.3, callback=nap, report_every=1e9)
    assert naps and time.perf_counter() - wall > 0.5
    assert 0.3 <= result.elapsed <= 0.3 * 1.05 + 0.02


def test_memory_is_estimated_and_refused_before_allocation() -> None:
    # 1000 states x 40 actions x 40 observations: the fast informed bound alone is 12.8 GB
    assert flat_solver_bytes(1000, 40, 40) > 12.8e9
    text = ("discount: 0.95\nstates: 1000\nactions: 40\nobservations: 40\n"
            "T: * uniform\nO: * uniform\n")
    start = time.process_time()
    with pytest.raises(MemoryCapError, match=r"solving big\.pomdp \(1000 states x 40 actions "
                                             r"x 40 observations\) needs about 13\.\d GB, over "
                                             r"the memory cap of 4 GB"):
        parse_pomdp(text, "big.pomdp", solver_bytes=flat_solver_bytes)
    assert time.process_time() - start < 0.5  # nothing dense was built
    tiger = parse_pomdp(TIGER)
    with pytest.raises(MemoryCapError, match="the flat solver on 2 states x 3 actions x 2 "
                                             "observations needs about"):
        FlatSarsop(tiger, memory_gb=1e-6)


@pytest.mark.parametrize(("precision", "timeout"), [(float("nan"), 1.0), (1e-3, float("inf")),
                                                    (0.0, 1.0), (1e-3, -1.0)])
def test_non_finite_or_non_positive_options_are_refused(precision: float, timeout: float
                                                        ) -> None:
    with pytest.raises(ValueError, match="must be a positive finite number"):
        solve_pomdp(parse_pomdp(TIGER), precision=precision, timeout=timeout)


def test_tiger_within_a_few_iterations_brackets_its_optimum() -> None:
    result = solve_pomdp(parse_pomdp(TIGER), precision=1e-6, timeout=1e6, max_iterations=40)
    assert result.iterations <= 40
    assert result.lower <= 19.3716 + 1e-3 and result.upper >= 19.3716 - 1e-3
    assert result.note == ""
    policy = result.policy
    assert np.all(np.isin(policy.actions, [0, 1, 2]))
