"""The active-recognition MOMDP: validation, Eq. 5 against the flat model, forbidden moves,
the structured and flat solvers agreeing, bounds bracketing the simulated return."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import (
    benchmark_problem,
    build_active_recognition_problem,
    simulate_policy,
    to_flat_pomdp,
    update_beliefs,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.pomdp import belief_update
from rapomdp.planning.sarsop import solve_pomdp
from tests.planning.planning_fixtures import small_arrays


def test_momdp_and_flat_solvers_agree():
    problem = benchmark_problem(4, 2, seed=1)
    flat = solve_pomdp(to_flat_pomdp(problem), precision=1e-4, timeout=1e6, max_iterations=200)
    ar = solve_active_recognition(problem, precision=1e-4, timeout=1e6, max_iterations=100)
    assert flat.converged and ar.converged
    assert ar.lower == pytest.approx(flat.lower, abs=3e-4)
    assert ar.lower <= flat.upper + 1e-9 and flat.lower <= ar.upper + 1e-9


def test_momdp_bounds_bracket_the_simulated_return():
    problem = benchmark_problem(6, 3, seed=2)
    result = solve_active_recognition(problem, precision=1e-3, timeout=1e6, max_iterations=100)
    policy = result.policy
    assert isinstance(policy, ActiveRecognitionPolicy)
    sim = simulate_policy(problem, policy, n_runs=4000, seed=0).summary()
    # the lower bound is the policy's exact value: the mean return matches it within noise
    assert abs(sim["mean_discounted_return"] - result.lower) < 4 * sim["stderr"] + 1e-3
    assert result.lower <= result.upper + 1e-9
    assert result.lower > -10 * (2 / 3)  # better than declaring at once


def test_momdp_belief_update_matches_flat_eq5():
    problem = benchmark_problem(5, 3, seed=0)
    flat = to_flat_pomdp(problem)
    b = np.array([0.2, 0.5, 0.3])
    post = problem.update(b, viewpoint=2, label=1)
    b_flat = np.zeros(flat.n_states)
    b_flat[0:3] = b  # at viewpoint 0
    a = int(np.flatnonzero(problem.targets == 2)[0])
    post_flat = belief_update(flat.T, flat.Z, b_flat, a, 2 * 3 + 1)
    np.testing.assert_allclose(post_flat[6:9], post)
    # batch form
    many = update_beliefs(problem.observation_model, np.stack([b, b]), np.array([2, 4]),
                          np.array([1, 0]))
    np.testing.assert_allclose(many[0], post)
    assert many.sum(axis=1) == pytest.approx([1, 1])


def test_problem_validation_messages():
    P, E = small_arrays()
    with pytest.raises(ValueError, match="no viewpoint is reachable"):
        build_active_recognition_problem(P, E, np.zeros(3, dtype=bool))
    bad = P.copy()
    bad[1, 0, 0] += 0.5
    with pytest.raises(ValueError, match=r"observation_model\[1, 0, :\] sums to"):
        build_active_recognition_problem(bad, E)
    with pytest.raises(ValueError, match="move_energy must have shape"):
        build_active_recognition_problem(P, E[:2])


def test_forbidden_stay_and_unreachable_targets_are_never_chosen():
    P, E = small_arrays(4, 2)
    reach = np.array([True, False, True, True])
    problem = build_active_recognition_problem(P, E, reach, lambda_=20.0)
    result = solve_active_recognition(problem, precision=1e-3, timeout=1e6, max_iterations=50)
    policy = result.policy
    assert set(policy.targets.tolist()) <= {0, 2, 3}
    rng = np.random.default_rng(0)
    for _ in range(200):
        v = int(rng.integers(4))
        act = policy.act(v, rng.dirichlet(np.ones(2)))
        if act.kind == "move":
            assert act.target != v and act.target != 1


def test_the_robot_stages_inf_energies_are_taken_and_the_rest_refused() -> None:
    from rapomdp.planning.momdp import finite_move_energy

    reachable = np.array([True, False, True])
    energy = np.array([[0.5, np.inf, 1.0], [np.inf, 0.5, np.inf], [1.0, np.inf, 0.5]])
    model = np.full((3, 2, 2), 0.5)
    problem = build_active_recognition_problem(model, energy, reachable)
    assert np.array_equal(problem.move_energy, np.where(np.isinf(energy), 1.0, energy))
    assert np.array_equal(finite_move_energy(energy, reachable)[1], [1.0, 0.5, 1.0])
    bad = energy.copy()
    bad[0, 2] = np.inf
    with pytest.raises(ValueError, match=r"move_energy\[0, 2\] is infinite although viewpoints "
                                         r"0 and 2 are both reachable"):
        build_active_recognition_problem(model, bad, reachable)
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="NaN or negative"):
        build_active_recognition_problem(model, bad, reachable)


def test_one_default_lambda_everywhere() -> None:
    import inspect

    from rapomdp.config import Config
    from rapomdp.planning import DEFAULT_LAMBDA
    from rapomdp.planning.momdp import ActiveRecognitionProblem
    from rapomdp.planning.workspace import solve_workspace_problems

    assert Config().solve.wrong_declaration_cost_m == DEFAULT_LAMBDA == 8.0
    model = np.full((2, 2, 2), 0.5)
    assert build_active_recognition_problem(model, np.ones((2, 2))).lambda_ == DEFAULT_LAMBDA
    assert ActiveRecognitionProblem(model, np.ones((2, 2)), np.ones(2, bool)).lambda_ == 8.0
    default = inspect.signature(solve_workspace_problems).parameters["lambda_"].default
    assert default == DEFAULT_LAMBDA
