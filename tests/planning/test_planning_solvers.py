"""Solvers: Tiger's optimum, bounds that bracket and converge to exact value iteration, and the
MOMDP solver agreeing with the flat solver on an active-recognition problem written out flat."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from planning_fixtures import TIGER

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.io_pomdp import parse_pomdp
from rapomdp.planning.momdp import benchmark_problem, simulate_policy, to_flat_pomdp
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy
from rapomdp.planning.pomdp import POMDP
from rapomdp.planning.sarsop import solve_pomdp

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
    result = solve_pomdp(parse_pomdp(TIGER), precision=1e-3, timeout=60)
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
    result = solve_pomdp(pomdp, precision=1e-4, timeout=30, report_every=0.0)
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
    result = solve_pomdp(pomdp, precision=1e-6, timeout=3, report_every=0.0)
    lows = np.array([h.lower for h in result.history])
    ups = np.array([h.upper for h in result.history])
    assert np.all(np.diff(lows) >= -1e-9) and np.all(np.diff(ups) <= 1e-9)
    assert np.all(lows <= ups + 1e-9)


def test_momdp_and_flat_solvers_agree():
    problem = benchmark_problem(4, 2, seed=1)
    flat = solve_pomdp(to_flat_pomdp(problem), precision=1e-4, timeout=30)
    ar = solve_active_recognition(problem, precision=1e-4, timeout=30)
    assert flat.converged and ar.converged
    assert ar.lower == pytest.approx(flat.lower, abs=3e-4)
    assert ar.lower <= flat.upper + 1e-9 and flat.lower <= ar.upper + 1e-9


def test_momdp_bounds_bracket_the_simulated_return():
    problem = benchmark_problem(6, 3, seed=2)
    result = solve_active_recognition(problem, precision=1e-3, timeout=8)
    policy = result.policy
    assert isinstance(policy, ActiveRecognitionPolicy)
    sim = simulate_policy(problem, policy, n_runs=4000, seed=0).summary()
    # the lower bound is the policy's exact value: the mean return matches it within noise
    assert abs(sim["mean_discounted_return"] - result.lower) < 4 * sim["stderr"] + 1e-3
    assert result.lower <= result.upper + 1e-9
    assert result.lower > -10 * (2 / 3)  # better than declaring at once
