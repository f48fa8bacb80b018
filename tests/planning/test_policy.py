"""Policies as .npz artefacts."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import (
    benchmark_problem,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy, ARAction


def test_policies_round_trip_through_npz(tmp_path):
    problem = benchmark_problem(4, 3, seed=0)
    result = solve_active_recognition(problem, precision=1e-2, timeout=1e6, max_iterations=50)
    policy = result.policy
    path = policy.save(tmp_path / "p.npz")
    loaded = ActiveRecognitionPolicy.load(path)
    b = problem.start_belief
    assert loaded.value(0, b) == pytest.approx(result.lower)
    assert loaded.upper(0, b) == pytest.approx(result.upper)
    assert loaded.act(0, b) == policy.act(0, b)
    certain = np.array([0.0, 1.0, 0.0])
    assert loaded.act(0, certain).kind == "declare" and loaded.act(0, certain).target == 1
    assert not list(tmp_path.glob(".p.npz*"))  # no temporary left behind
    with pytest.raises(ValueError, match="expected a 'rapomdp.alpha-vector-policy.v1'"):
        AlphaVectorPolicy.load(path)


def _brute_force_lookahead(policy, problem, viewpoint, belief, allowed):
    """Q of every allowed move by explicit loops over labels (Eq. 5 and the policy's value)."""
    P, E = problem.observation_model, problem.move_energy
    q = {}
    for j in np.flatnonzero(allowed):
        if j == viewpoint:
            continue
        total = 0.0
        for o in range(P.shape[2]):
            joint = belief * P[j, :, o]
            p_o = joint.sum()
            if p_o > 0:
                total += p_o * policy.value(int(j), joint / p_o)
        q[int(j)] = -E[viewpoint, j] + policy.discount * total
    return q


def test_the_lookahead_takes_the_move_of_best_one_step_backup():
    problem = benchmark_problem(6, 3, seed=2, lambda_=10.0)
    policy = solve_active_recognition(problem, precision=1e-2, timeout=1e6,
                                      max_iterations=5).policy
    allowed = np.ones(6, dtype=bool)
    for belief in (np.full(3, 1 / 3), np.array([0.5, 0.3, 0.2]), np.array([0.45, 0.45, 0.1])):
        q = _brute_force_lookahead(policy, problem, 0, belief, allowed)
        best = max(q, key=q.__getitem__)
        declare = -10.0 * (1.0 - belief.max())
        assert q[best] > declare  # at λ = 10 m moving pays from these beliefs
        assert policy.lookahead_act(0, belief, problem.observation_model, allowed) == \
            ARAction("move", best)
    # visited and unreachable viewpoints are never targets; with none left it declares
    belief = np.full(3, 1 / 3)
    forbidden = np.zeros(6, dtype=bool)
    forbidden[[1, 2]] = True
    allowed[3] = False
    q = _brute_force_lookahead(policy, problem, 0, belief, allowed & ~forbidden)
    action = policy.lookahead_act(0, belief, problem.observation_model, allowed, forbidden)
    assert action == ARAction("move", max(q, key=q.__getitem__)) and action.target in (4, 5)
    nothing = np.zeros(6, dtype=bool)
    nothing[0] = True
    assert policy.lookahead_act(0, np.array([0.2, 0.7, 0.1]), problem.observation_model,
                                nothing) == ARAction("declare", 1)
    # a certain belief is declared at once
    assert policy.lookahead_act(0, np.array([0.0, 0.0, 1.0]), problem.observation_model,
                                allowed) == ARAction("declare", 2)



def test_the_lookahead_is_the_brute_force_backup_whatever_the_order_of_the_plans():
    import dataclasses

    lam = 30.0
    problem = benchmark_problem(6, 3, seed=5, lambda_=lam)
    policy = solve_active_recognition(problem, precision=1e-2, timeout=1e6,
                                      max_iterations=10).policy
    targets, counts = np.unique(policy.targets, return_counts=True)
    assert counts.max() > 1 and targets.size > 1  # plans share first targets: groups are used
    order = np.random.default_rng(0).permutation(len(policy.targets))
    shuffled = dataclasses.replace(policy, betas=policy.betas[order],
                                   targets=policy.targets[order])
    allowed = np.ones(6, dtype=bool)
    rng = np.random.default_rng(1)
    kinds = set()
    for viewpoint in range(6):
        for _ in range(10):
            belief = rng.dirichlet(np.full(3, 0.7))
            q = _brute_force_lookahead(policy, problem, viewpoint, belief, allowed)
            best = max(q, key=q.__getitem__)
            expected = (ARAction("move", best) if q[best] > -lam * (1.0 - belief.max()) + 1e-9
                        else ARAction("declare", int(np.argmax(belief))))
            for plans in (policy, shuffled):
                assert plans.lookahead_act(viewpoint, belief, problem.observation_model,
                                           allowed) == expected
            kinds.add(expected.kind)
    assert kinds == {"move", "declare"}  # both branches were exercised
