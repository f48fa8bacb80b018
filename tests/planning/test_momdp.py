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


def _typed(problem, atypical: np.ndarray, weight: float):
    """The problem with a second instance type whose rows are ``atypical`` (V, C, C), prior
    (1 - weight, weight) over the types."""
    P = problem.observation_model
    c = problem.n_classes
    prior = np.concatenate([np.full(c, (1 - weight) / c), np.full(c, weight / c)])
    return build_active_recognition_problem(np.concatenate([P, atypical], axis=1),
                                            problem.move_energy, problem.reachable,
                                            problem.lambda_, problem.discount,
                                            problem.start_viewpoint, prior, allow_stay=True)


def test_a_type_that_changes_nothing_leaves_the_value_and_the_policy_unchanged():
    """Two instance types with the same rows are one model: the typed MOMDP's bounds, its
    policy's actions and its simulated accuracy are the untyped one's."""
    problem = benchmark_problem(5, 3, seed=5)
    typed = _typed(problem, problem.observation_model, 0.3)
    assert (typed.n_states, typed.n_classes, typed.types) == (6, 3, 2)
    assert typed.state_class().tolist() == [0, 1, 2, 0, 1, 2]
    plain = solve_active_recognition(problem, precision=1e-4, timeout=1e6, max_iterations=60,
                                     grid=4)
    both = solve_active_recognition(typed, precision=1e-4, timeout=1e6, max_iterations=60,
                                    grid=4)
    assert both.lower == pytest.approx(plain.lower, abs=2e-3)
    # an upper bound on the same value (the grid over six states is coarser than over three)
    assert plain.lower - 1e-3 <= both.upper <= plain.upper + 0.15
    rng = np.random.default_rng(0)
    for b in rng.dirichlet(np.ones(3), size=20):  # each bounds the other's value everywhere
        state = np.concatenate([0.7 * b, 0.3 * b])
        assert both.policy.value(0, state) <= plain.policy.upper(0, b) + 1e-9
        assert plain.policy.value(0, b) <= both.policy.upper(0, state) + 1e-9
    assert both.policy.n_states == 6 and both.policy.n_classes == 3
    sim = simulate_policy(typed, both.policy, n_runs=2000, seed=1).summary()
    assert abs(sim["mean_discounted_return"] - both.lower) < 4 * sim["stderr"] + 1e-3


def test_the_typed_momdp_is_the_flat_pomdp_with_type_and_class_hidden():
    problem = benchmark_problem(3, 2, seed=6)
    atypical = np.broadcast_to(np.array([[0.5, 0.5], [0.9, 0.1]]), (3, 2, 2)).copy()
    typed = _typed(problem, atypical, 0.25)
    flat = to_flat_pomdp(typed)
    assert flat.n_states == 3 * 4 + 1 and flat.n_observations == 3 * 2 + 1
    flat_result = solve_pomdp(flat, precision=1e-4, timeout=1e6, max_iterations=40)
    ar = solve_active_recognition(typed, precision=1e-4, timeout=1e6, max_iterations=40, grid=8)
    assert ar.lower == pytest.approx(flat_result.lower, abs=5e-4)
    assert ar.lower <= flat_result.upper + 1e-9 and flat_result.lower <= ar.upper + 1e-9
    # declaring class 1 is right in (typical, 1) and (atypical, 1) alike
    declare = [a for a, name in enumerate(flat.action_names) if name == "declare_class1"][0]
    states = np.flatnonzero(flat.R[declare] == 0.0)
    assert [flat.state_names[s] for s in states[:-1]] == [
        "v0_class1_t0", "v0_class1_t1", "v1_class1_t0", "v1_class1_t1", "v2_class1_t0",
        "v2_class1_t1"]
    # Eq. 5 over (type, class): the flat update and the MOMDP's agree
    b = typed.start_belief
    post = typed.update(b, viewpoint=1, label=0)
    b_flat = np.zeros(flat.n_states)
    b_flat[0:4] = b
    a = int(np.flatnonzero(typed.targets == 1)[0])
    np.testing.assert_allclose(belief_update(flat.T, flat.Z, b_flat, a, 1 * 2 + 0)[4:8], post)


def test_a_typed_model_must_hold_whole_types_and_a_prior_over_its_states():
    P = benchmark_problem(3, 2, seed=7).observation_model
    with pytest.raises(ValueError, match=r"\(V, T\*C, C\) with T instance types, got "
                                         r"\(3, 3, 2\)"):
        build_active_recognition_problem(np.concatenate([P, P[:, :1]], axis=1), np.ones((3, 3)))
    with pytest.raises(ValueError, match="start belief must be a distribution over 4 states"):
        build_active_recognition_problem(np.concatenate([P, P], axis=1), np.ones((3, 3)),
                                         start_belief=np.array([0.5, 0.5]))
