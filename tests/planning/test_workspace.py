"""The solve stage's entry point on plain arrays: one policy per model, reproducible budgets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rapomdp.planning.momdp import (
    benchmark_problem,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.workspace import solve_problem_sets, solve_workspace_problems
from tests.planning.planning_fixtures import small_arrays


def test_solve_workspace_problems_writes_one_policy_per_model(tmp_path):
    P, E = small_arrays()
    models = {"ra": P, "classifier": np.full_like(P, 0.5)}
    paths = solve_workspace_problems(models, E, None, tmp_path, lambda_=10.0, timeout=1e6,
                                     max_iterations=25)
    assert set(paths) == {"ra", "classifier"}
    summary = json.loads((tmp_path / "solve_summary.json").read_text())
    # an uninformative classifier: declaring at once (−5 for two classes) is optimal
    assert summary["classifier"]["lower"] == pytest.approx(-5.0)
    assert summary["ra"]["lower"] >= -5.0
    policy = ActiveRecognitionPolicy.load(paths["classifier"])
    assert policy.act(0, np.array([0.5, 0.5])).kind == "declare"


def test_an_iteration_budget_makes_solves_reproducible_in_any_process(tmp_path):

    problem = benchmark_problem(24, 6, seed=4)
    models = {"a": problem.observation_model, "b": problem.observation_model[::-1].copy()}
    runs = []
    for name, workers in (("one", 1), ("again", 1), ("two", 2)):
        out = tmp_path / name
        out.mkdir()
        solve_workspace_problems(models, problem.move_energy, None, out, lambda_=10.0,
                                 timeout=60, max_iterations=6, workers=workers)
        runs.append(out)
    summary = json.loads((runs[0] / "solve_summary.json").read_text())
    assert {row["iterations"] for row in summary.values()} == {6}
    assert not any(row["timed_out"] for row in summary.values())
    for name in models:
        first = ActiveRecognitionPolicy.load(runs[0] / f"policy_{name}.npz")
        for other in runs[1:]:
            again = ActiveRecognitionPolicy.load(other / f"policy_{name}.npz")
            assert np.array_equal(first.betas, again.betas)
            assert np.array_equal(first.targets, again.targets)
            assert np.array_equal(first.upper_values, again.upper_values)


def _arrays(folder) -> dict[str, np.ndarray]:
    return {f"{p.name}:{k}": v for p in sorted(folder.glob("*.npz"))
            for k, v in np.load(p).items()}


def _without_time(folder) -> dict:
    summary = json.loads((folder / "solve_summary.json").read_text())
    return {name: {k: v for k, v in row.items() if k != "seconds"}
            for name, row in summary.items()}


@pytest.mark.parametrize("workers", [1, 2])
def test_problem_sets_in_one_pool_write_what_one_call_per_folder_writes(tmp_path, workers):
    P, E = small_arrays()
    models = {"a": P, "b": P[::-1].copy()}
    sets = [(tmp_path / "pool" / "lambda_3", 3.0, models),
            (tmp_path / "pool" / "lambda_12", 12.0, {"b": models["b"]})]
    paths = solve_problem_sets(sets, E, None, timeout=1e6, max_iterations=25,
                               workers=workers, cost={"a": 1.0, "b": 2.0})
    assert paths == {folder: {n: folder / f"policy_{n}.npz" for n in ms}
                     for folder, _, ms in sets}
    for folder, lam, ms in sets:
        alone = tmp_path / "alone" / folder.name
        solve_workspace_problems(ms, E, None, alone, lambda_=lam, timeout=1e6,
                                 max_iterations=25)
        assert list(_without_time(folder)) == list(ms)  # the models' order, not the pool's
        assert _without_time(folder) == _without_time(alone)
        mine, theirs = _arrays(folder), _arrays(alone)
        assert mine.keys() == theirs.keys()
        assert all(np.array_equal(mine[k], theirs[k]) for k in mine)
