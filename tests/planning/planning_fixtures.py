"""Small problems and helpers shared by the planning tests."""

import numpy as np

from rapomdp.planning.grid_bound import grid_upper_bound
from rapomdp.planning.momdp import benchmark_problem
from rapomdp.planning.policy import ActiveRecognitionPolicy, ARAction
from rapomdp.planning.rules import (
    declare_value,
    declare_values,
    move_or_declare,
    unnormalised_declare_value,
)

TIGER = """\
# the tiger problem
discount: 0.95
values: reward
states: tiger-left tiger-right
actions: listen open-left open-right
observations: obs-left obs-right

T:listen
identity

T:open-left
uniform

T:open-right
uniform

O:listen
0.85 0.15
0.15 0.85

O:open-left
uniform

O:open-right
uniform

R:listen : * : * : * -1
R:open-left : tiger-left : * : * -100
R:open-left : tiger-right : * : * 10
R:open-right : tiger-left : * : * 10
R:open-right : tiger-right : * : * -100
"""


def grid_value(problem, resolution: int) -> float:
    g = grid_upper_bound(
        problem.observation_model, problem.move_cost(), problem.targets, problem.lambda_,
        problem.discount, resolution, tol=1e-9,
    )
    return float(g.evaluate(problem.start_belief[None], np.array([problem.start_viewpoint]))[0])


def small_arrays(n_v: int = 3, n_c: int = 2) -> tuple[np.ndarray, np.ndarray]:
    p = benchmark_problem(n_v, n_c, seed=3)
    return p.observation_model, p.move_energy


def reference_lookahead_act(policy: ActiveRecognitionPolicy, viewpoint: int,
                            belief: np.ndarray, observation_model: np.ndarray,
                            allowed: np.ndarray, forbidden: np.ndarray | None = None
                            ) -> ARAction:
    """``lookahead_act`` before the float32 screen (every move valued exactly, the plans
    sorted by target on every call): the reference the faster one must match, in the tests
    and in benchmarks/lookahead_speed.py."""
    b = np.asarray(belief, dtype=np.float64)
    ok = np.asarray(allowed, dtype=bool).copy()
    ok[viewpoint] = False
    if forbidden is not None:
        ok &= ~np.asarray(forbidden, dtype=bool)
    targets = np.flatnonzero(ok)
    dec = declare_value(b, policy.lambda_, policy.n_classes)
    k = int(np.argmax(declare_values(b, policy.lambda_, policy.n_classes)))
    if targets.size == 0:
        return ARAction("declare", k)
    u = b[None, None, :] * np.swapaxes(observation_model[targets], 1, 2)  # (J, O, S)
    prob = u.sum(axis=2)
    child = unnormalised_declare_value(u, policy.lambda_, policy.n_classes)  # (J, O)
    if len(policy.targets):
        order = np.argsort(policy.targets, kind="stable")
        first_targets, starts = np.unique(policy.targets[order], return_index=True)
        best = np.maximum.reduceat(u @ policy.betas[order].T, starts, axis=2)  # (J, O, T)
        best -= prob[..., None] * policy.move_energy[np.ix_(targets, first_targets)][:, None]
        child = np.maximum(child, best.max(axis=2))
    q = policy.discount * child.sum(axis=1) - policy.move_energy[viewpoint, targets]
    _, m = move_or_declare(q[None], np.asarray(dec)[None])
    if m[0] >= 0:
        return ARAction("move", int(targets[m[0]]))
    return ARAction("declare", k)
