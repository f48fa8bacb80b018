"""Policies as .npz artefacts."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import (
    benchmark_problem,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy, ARAction
from tests.planning.planning_fixtures import reference_lookahead_act


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


def _best_action(q, belief, lam):
    """The move of best value in ``q`` if it beats declaring the belief's argmax, else that."""
    best = max(q, key=q.__getitem__)
    if q[best] > -lam * (1.0 - belief.max()) + 1e-9:
        return ARAction("move", best)
    return ARAction("declare", int(np.argmax(belief)))


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
            expected = _best_action(
                _brute_force_lookahead(policy, problem, viewpoint, belief, allowed), belief, lam)
            for plans in (policy, shuffled):
                assert plans.lookahead_act(viewpoint, belief, problem.observation_model,
                                           allowed) == expected
            kinds.add(expected.kind)
    assert kinds == {"move", "declare"}  # both branches were exercised


TWIN, TWIN_OF = 15, 8  # two viewpoints with the same rows, energies and plans: moves tie


@pytest.fixture(scope="module")
def confusion_problem():
    """16 viewpoints, 6 classes: per-viewpoint confusions (accuracy and where mistakes go drawn
    per viewpoint, as a learned model's), two unreachable viewpoints, viewpoint 15 a copy of 8;
    solved to a few hundred plans with first-target groups of 1 to ~100 plans, then each plan
    of 8 or 15 copied to the other, so that moving to either is worth the same (to rounding:
    a plan's product can round differently at another place in the plans)."""
    import dataclasses

    from rapomdp.geometry import fibonacci_directions, geodesic_distance_matrix
    from rapomdp.planning.momdp import build_active_recognition_problem

    n_v, n_c = 16, 6
    rng = np.random.default_rng(2)
    energy = geodesic_distance_matrix(fibonacci_directions(n_v, hemisphere=True), 1.0) + 0.3
    accuracy = rng.uniform(0.3, 0.9, size=(n_v, n_c))
    model = (1 - accuracy)[..., None] * rng.dirichlet(np.full(n_c, 0.5), size=(n_v, n_c))
    model[:, np.arange(n_c), np.arange(n_c)] += accuracy
    model /= model.sum(axis=2, keepdims=True)
    model[TWIN] = model[TWIN_OF]
    energy[TWIN], energy[:, TWIN] = energy[TWIN_OF], energy[:, TWIN_OF]
    reachable = np.ones(n_v, dtype=bool)
    reachable[[5, 9]] = False
    energy[~reachable] = np.inf
    energy[:, ~reachable] = np.inf
    problem = build_active_recognition_problem(model, energy, reachable, lambda_=8.0)
    policy = solve_active_recognition(problem, precision=1e-3, timeout=1e6,
                                      max_iterations=30, grid=False).policy
    twins = np.isin(policy.targets, [TWIN, TWIN_OF])
    swapped = np.where(policy.targets[twins] == TWIN, TWIN_OF, TWIN)
    policy = dataclasses.replace(policy, betas=np.concatenate([policy.betas,
                                                               policy.betas[twins]]),
                                 targets=np.concatenate([policy.targets, swapped]))
    return problem, policy


def _recorded_beliefs(problem, policy, count, seed):
    """(viewpoint, belief, allowed, forbidden): beliefs after one to four Bayes updates with
    random labels, random visited sets and allowed masks; then uniform, near-certain and
    two-class-tie beliefs, and pairs straddling the switch from moving to declaring."""
    from rapomdp.planning.momdp import update_beliefs

    model, reachable = problem.observation_model, problem.reachable
    n_v, n_s, n_o = model.shape
    rng = np.random.default_rng(seed)
    cases = []
    for i in range(count):
        views = rng.choice(np.flatnonzero(reachable), 4, replace=False)
        b = np.full(n_s, 1.0 / n_s)
        for v in views[: rng.integers(1, 5)]:
            b = update_beliefs(model, b, int(v), int(rng.integers(n_o)))
        forbidden = np.zeros(n_v, dtype=bool)
        forbidden[views[: rng.integers(1, 5)]] = True
        allowed = reachable & (rng.random(n_v) < 0.9) if i % 3 == 0 else reachable.copy()
        cases.append((int(views[0]), b, allowed, forbidden))
    for k in range(n_s):
        for eps in (0.0, 1e-12, 1e-9, 1e-6, 1e-3):
            b = np.full(n_s, eps / (n_s - 1))
            b[k] = 1.0 - eps
            cases.append((0, b, reachable, None))
        b = np.full(n_s, 0.1 / (n_s - 2))
        b[[k, (k + 1) % n_s]] = 0.45
        cases.append((int(rng.choice(np.flatnonzero(reachable))), b, reachable, None))
    cases.append((0, np.full(n_s, 1.0 / n_s), reachable, None))
    # beliefs either side of the move/declare switch on segments towards certainty
    for k in range(n_s):
        start = cases[k][1]
        end = np.eye(n_s)[k]
        kind = [reference_lookahead_act(policy, 0, (1 - t) * start + t * end, model,
                                         reachable).kind for t in (0.0, 1.0)]
        if kind[0] == kind[1]:
            continue
        lo, hi = 0.0, 1.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            act = reference_lookahead_act(policy, 0, (1 - mid) * start + mid * end, model,
                                           reachable)
            lo, hi = (mid, hi) if act.kind == kind[0] else (lo, mid)
        cases += [(0, (1 - t) * start + t * end, reachable, None) for t in (lo, hi)]
    return cases


def test_the_lookahead_returns_the_reference_actions_on_recorded_beliefs(confusion_problem):
    problem, policy = confusion_problem
    sizes = np.bincount(policy.targets)
    assert (sizes > 8).sum() >= 2 and ((sizes > 0) & (sizes % 4 != 0)).any()  # single plans
    cases = _recorded_beliefs(problem, policy, 300, seed=0)
    assert len(cases) > 330
    kinds, ties, straddles = set(), 0, 0
    for viewpoint, b, allowed, forbidden in cases:
        expected = reference_lookahead_act(policy, viewpoint, b, problem.observation_model,
                                            allowed, forbidden)
        assert policy.lookahead_act(viewpoint, b, problem.observation_model, allowed,
                                    forbidden) == expected
        kinds.add(expected.kind)
        ties += expected in (ARAction("move", TWIN_OF), ARAction("move", TWIN))
    for a, b in zip(cases[-12::2], cases[-11::2], strict=True):  # the switch pairs
        straddles += reference_lookahead_act(policy, 0, a[1], problem.observation_model,
                                              a[2]).kind != reference_lookahead_act(
            policy, 0, b[1], problem.observation_model, b[2]).kind
    assert kinds == {"move", "declare"} and ties > 0 and straddles > 0
    # a policy without plans (children valued by declaring alone), one with a single plan, and
    # infinite energies to the unreachable viewpoints with every viewpoint allowed
    import dataclasses

    energy = policy.move_energy.copy()
    energy[~problem.reachable] = np.inf
    energy[:, ~problem.reachable] = np.inf
    everywhere = np.ones(problem.reachable.size, dtype=bool)
    for variant, allowed_all in ((dict(betas=policy.betas[:0], targets=policy.targets[:0]), 0),
                                 (dict(betas=policy.betas[:1], targets=policy.targets[:1]), 0),
                                 (dict(move_energy=energy), 1)):
        other = dataclasses.replace(policy, **variant)
        for viewpoint, b, allowed, forbidden in cases[:60]:
            allowed = everywhere if allowed_all else allowed
            assert other.lookahead_act(viewpoint, b, problem.observation_model, allowed,
                                       forbidden) == reference_lookahead_act(
                other, viewpoint, b, problem.observation_model, allowed, forbidden)


def test_the_lookahead_screen_bounds_its_error_and_keeps_few_moves(confusion_problem):
    """The float32 values are within their stated error of the exact ones, the exact values of
    some moves do not depend on the others valued with them, and on recorded beliefs the
    screen leaves few moves to value exactly."""
    problem, policy = confusion_problem
    model = problem.observation_model
    kept = []
    for viewpoint, b, allowed, forbidden in _recorded_beliefs(problem, policy, 100, seed=1):
        ok = allowed.copy()
        ok[viewpoint] = False
        if forbidden is not None:
            ok &= ~forbidden
        targets = np.flatnonzero(ok)
        exact = policy._lookahead_values(viewpoint, b, model, targets)
        rough, error = policy._screen_values(viewpoint, b, model, targets)
        assert np.all(np.abs(rough - exact) <= error)
        assert np.all(error < 1e-4)
        some = targets[::3]
        assert np.array_equal(policy._lookahead_values(viewpoint, b, model, some), exact[::3])
        twins = np.isin(targets, [TWIN, TWIN_OF])
        if twins.sum() == 2:
            assert exact[twins][0] == pytest.approx(exact[twins][1], abs=1e-12)
        kept.append(int((rough + error >= (rough - error).max()).sum()) / targets.size)
    assert np.mean(kept) < 0.2


def test_the_lookahead_returns_the_reference_actions_with_instance_types(confusion_problem):
    """States (type, class), type-major: the screen reads the class marginal of a child."""
    from rapomdp.planning.momdp import build_active_recognition_problem

    problem, _ = confusion_problem
    model = problem.observation_model
    n_c = model.shape[2]
    atypical = np.roll(model, 1, axis=2) * 0.5 + model * 0.5  # errors that repeat
    prior = np.concatenate([np.full(n_c, 0.8 / n_c), np.full(n_c, 0.2 / n_c)])
    typed = build_active_recognition_problem(
        np.concatenate([model, atypical], axis=1), problem.move_energy, problem.reachable,
        problem.lambda_, problem.discount, 0, prior)
    policy = solve_active_recognition(typed, precision=1e-3, timeout=1e6, max_iterations=20,
                                      grid=False).policy
    assert policy.n_states == 2 * n_c and policy.n_classes == n_c
    kinds = set()
    for viewpoint, b, allowed, forbidden in _recorded_beliefs(typed, policy, 150, seed=3):
        expected = reference_lookahead_act(policy, viewpoint, b, typed.observation_model,
                                            allowed, forbidden)
        assert policy.lookahead_act(viewpoint, b, typed.observation_model, allowed,
                                    forbidden) == expected
        kinds.add(expected.kind)
    assert kinds == {"move", "declare"}


def test_the_lookahead_matches_the_reference_with_children_of_probability_zero(
        confusion_problem):
    """Labels a belief cannot produce at some viewpoints (zeros in the model where the belief
    has its mass): the children of probability 0 are valued exactly, as in the reference
    (which declares whenever one meets a plan group of infinite energy, the viewpoint's own:
    0 · inf is NaN; kept as it is, and the RuntimeWarning with it)."""
    problem, policy = confusion_problem
    model = problem.observation_model.copy()
    model[::2, :2, :2] = 0.0  # classes 0 and 1 never labelled 0 or 1 at even viewpoints
    model /= model.sum(axis=2, keepdims=True)
    rng = np.random.default_rng(4)
    for _ in range(40):
        b = np.zeros(model.shape[1])
        b[:2] = rng.dirichlet([1.0, 1.0])
        b[2:] = rng.choice([0.0, 1e-3]) * rng.dirichlet(np.ones(model.shape[1] - 2))
        b /= b.sum()
        viewpoint = int(rng.choice(np.flatnonzero(problem.reachable)))
        with np.errstate(invalid="ignore"):
            assert policy.lookahead_act(viewpoint, b, model, problem.reachable) == \
                reference_lookahead_act(policy, viewpoint, b, model, problem.reachable)
