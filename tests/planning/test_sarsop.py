"""The flat SARSOP-style solver keeps its word: CPU-time budget in every phase, memory
estimated and refused before allocation, NaN and infinite options refused."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest

from rapomdp.planning.bounds import EXACT_BLIND_STATES, flat_solver_bytes
from rapomdp.planning.io_pomdp import parse_pomdp
from rapomdp.planning.memory import MemoryCapError
from rapomdp.planning.policy import AlphaVectorPolicy
from rapomdp.planning.pomdp import POMDP
from rapomdp.planning.sarsop import FlatSarsop, solve_pomdp
from tests.planning.planning_fixtures import TIGER


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
    # 3000 states x 40 actions x 40 observations: T alone is 2.9 GB, the whole about 6.3 GB
    assert flat_solver_bytes(3000, 40, 40) > 6e9
    text = ("discount: 0.95\nstates: 3000\nactions: 40\nobservations: 40\n"
            "T: * uniform\nO: * uniform\n")
    start = time.process_time()
    with pytest.raises(MemoryCapError, match=r"solving big\.pomdp \(3000 states x 40 actions "
                                             r"x 40 observations\) needs about 6\.\d+ GB, over "
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


TIGER_OPTIMUM = 19.3716  # reference SARSOP brackets it in [19.3711, 19.3721]


def exact_value(pomdp: POMDP, grid: int = 2001, tol: float = 1e-7) -> float:
    """Brute-force value iteration for a two-state POMDP: enumerate every backed-up vector
    (|A|·|Γ|^|Z| cross-sums) each step, prune to those best somewhere on a dense grid."""
    assert pomdp.n_states == 2
    beliefs = np.stack([np.linspace(0, 1, grid), 1 - np.linspace(0, 1, grid)], axis=1)
    gamma = blind = np.array([np.full(2, pomdp.R.min() / (1 - pomdp.discount))])
    del blind
    T, Z, R, g = pomdp.T, pomdp.Z, pomdp.R, pomdp.discount
    prev = -np.inf
    for _ in range(2000):
        cands = []
        for a in range(pomdp.n_actions):
            # proj[o, i, s] = Σ_s' T[a,s,s'] Z[a,s',o] Γ_i(s')
            proj = np.einsum("st,to,it->ois", T[a], Z[a], gamma)
            for combo in itertools.product(range(len(gamma)), repeat=pomdp.n_observations):
                cands.append(R[a] + g * sum(proj[o, i] for o, i in enumerate(combo)))
        cands = np.array(cands)
        best = np.unique(np.argmax(beliefs @ cands.T, axis=1))
        gamma = np.unique(np.round(cands[best], 12), axis=0)
        value = float((gamma @ pomdp.initial_belief).max())
        if abs(value - prev) < tol:
            return value
        prev = value
    raise AssertionError("value iteration did not converge")


def random_two_state(seed: int) -> POMDP:
    rng = np.random.default_rng(seed)
    n_a, n_z = 2, 2
    T = rng.dirichlet(np.ones(2), size=(n_a, 2))
    Z = rng.dirichlet(np.ones(n_z) * 0.7, size=(n_a, 2))
    R = rng.uniform(-1, 1, size=(n_a, 2))
    b0 = rng.dirichlet(np.ones(2))
    return POMDP.from_arrays(T, Z, R, 0.9, b0)


def test_tiger_reaches_its_known_optimum():
    result = solve_pomdp(parse_pomdp(TIGER), precision=1e-3, timeout=1e6, max_iterations=300)
    assert result.converged
    assert result.lower <= TIGER_OPTIMUM + 1e-3 <= result.upper + 2e-3
    assert result.lower == pytest.approx(TIGER_OPTIMUM, abs=1.5e-3)
    assert result.upper - result.lower <= 1e-3
    policy = result.policy
    assert isinstance(policy, AlphaVectorPolicy)
    assert policy.act(np.array([0.5, 0.5])) == 0  # listen when unsure
    assert policy.act(np.array([0.99, 0.01])) == 2  # tiger left: open right
    assert policy.value(np.array([0.5, 0.5])) == pytest.approx(result.lower)


def test_exact_value_of_tiger_matches_the_reference():
    assert exact_value(parse_pomdp(TIGER), grid=401, tol=1e-5) == pytest.approx(
        TIGER_OPTIMUM, abs=2e-3
    )


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_bounds_bracket_and_converge_to_exact_value(seed):
    pomdp = random_two_state(seed)
    exact = exact_value(pomdp)
    result = solve_pomdp(pomdp, precision=1e-4, timeout=1e6, report_every=0.0,
                         max_iterations=500)
    for snap in result.history:
        assert snap.lower <= snap.upper + 1e-9
        assert snap.lower <= exact + 1e-6
        assert snap.upper >= exact - 1e-6
    assert result.converged
    assert result.lower == pytest.approx(exact, abs=2e-4)


def test_bounds_are_monotone_on_hallway_like_random_problem():
    rng = np.random.default_rng(5)
    n_s, n_a, n_z = 6, 3, 3
    pomdp = POMDP.from_arrays(
        rng.dirichlet(np.ones(n_s) * 0.3, size=(n_a, n_s)),
        rng.dirichlet(np.ones(n_z) * 0.5, size=(n_a, n_s)),
        rng.uniform(-1, 1, size=(n_a, n_s)),
        0.9,
        np.full(n_s, 1 / n_s),
    )
    result = solve_pomdp(pomdp, precision=1e-6, timeout=1e6, report_every=0.0,
                         max_iterations=60)
    lows = np.array([h.lower for h in result.history])
    ups = np.array([h.upper for h in result.history])
    assert np.all(np.diff(lows) >= -1e-9) and np.all(np.diff(ups) <= 1e-9)
    assert np.all(lows <= ups + 1e-9)
