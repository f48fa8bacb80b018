"""Small problems and helpers shared by the planning tests."""

import numpy as np

from rapomdp.planning.grid_bound import grid_upper_bound
from rapomdp.planning.momdp import benchmark_problem

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
