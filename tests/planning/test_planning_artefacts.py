"""Policies as npz artefacts, the MOMDP model and belief update, the .pomdpx writer, the CLI
and the workspace entry points."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.cli import pomdp_app
from rapomdp.planning.io_pomdp import read_pomdp
from rapomdp.planning.io_pomdpx import format_pomdpx
from rapomdp.planning.momdp import (
    benchmark_problem,
    build_active_recognition_problem,
    to_flat_pomdp,
    update_beliefs,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy
from rapomdp.planning.pomdp import belief_update
from rapomdp.planning.workspace import solve_workspace_problems

runner = CliRunner()


def small_arrays(n_v: int = 3, n_c: int = 2) -> tuple[np.ndarray, np.ndarray]:
    p = benchmark_problem(n_v, n_c, seed=3)
    return p.observation_model, p.move_energy


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
    result = solve_active_recognition(problem, precision=1e-3, timeout=10)
    policy = result.policy
    assert set(policy.targets.tolist()) <= {0, 2, 3}
    rng = np.random.default_rng(0)
    for _ in range(200):
        v = int(rng.integers(4))
        act = policy.act(v, rng.dirichlet(np.ones(2)))
        if act.kind == "move":
            assert act.target != v and act.target != 1


def test_policies_round_trip_through_npz(tmp_path):
    problem = benchmark_problem(4, 3, seed=0)
    result = solve_active_recognition(problem, precision=1e-2, timeout=5)
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


def test_pomdpx_writer_structure():
    problem = benchmark_problem(3, 2, seed=0)
    root = ET.fromstring(format_pomdpx(problem).encode())
    view = root.find("Variable/StateVar[@vnamePrev='view_0']")
    assert view.get("fullyObs") == "true"
    assert view.find("ValueEnum").text.split() == ["v0", "v1", "v2", "done"]
    assert root.find("Discount").text == "0.95"
    actions = root.find("Variable/ActionVar/ValueEnum").text.split()
    assert actions == ["move0", "move1", "move2", "declare0", "declare1"]
    entries = root.findall("ObsFunction/CondProb/Parameter/Entry")
    assert len(entries) == 3 * 2 + 1
    first = [float(x) for x in entries[0].find("ProbTable").text.split()]
    np.testing.assert_allclose(first, problem.observation_model[0, 0])
    rewards = root.findall("RewardFunction/Func/Parameter/Entry")
    values = {e.find("Instance").text: float(e.find("ValueTable").text) for e in rewards}
    assert values["move1 v0 *"] == pytest.approx(-problem.move_energy[0, 1])
    assert values["declare0 v2 c1"] == -10.0


def test_cli_solve_prints_bounds_and_policy_size(tmp_path, benchmarks):
    out = tmp_path / "tiger.npz"
    res = runner.invoke(
        pomdp_app,
        ["solve", str(benchmarks / "Tiger.pomdp"), "--precision", "0.01", "--timeout", "30",
         "--out", str(out)],
    )
    assert res.exit_code == 0, res.output
    assert "lower=" in res.output and "upper=" in res.output
    assert "converged" in res.output and "alpha vectors" in res.output
    policy = AlphaVectorPolicy.load(out)
    assert policy.value(np.array([0.5, 0.5])) == pytest.approx(19.37, abs=0.02)


def test_cli_solve_reports_parse_errors_with_line(tmp_path):
    bad = tmp_path / "bad.pomdp"
    bad.write_text("discount: 0.9\nstates: 2\nactions: 2\nobservations: 2\nT: 7 : 0 : 0 1\n")
    res = runner.invoke(pomdp_app, ["solve", str(bad)])
    assert res.exit_code == 2
    assert "bad.pomdp:5" in res.output.replace("\n", "") and "out of range" in res.output


def test_cli_export_pomdpx_and_flat(tmp_path):
    P, E = small_arrays()
    arrays = tmp_path / "problem.npz"
    np.savez(arrays, observation_model=P, move_energy=E, reachable=np.ones(3, dtype=bool))
    res = runner.invoke(pomdp_app, ["export", "--problem", str(arrays), "--out",
                                    str(tmp_path / "ar.pomdpx")])
    assert res.exit_code == 0, res.output
    assert ET.parse(tmp_path / "ar.pomdpx").getroot().tag == "pomdpx"
    res = runner.invoke(pomdp_app, ["export", "--benchmark", "3x2", "--out",
                                    str(tmp_path / "ar.pomdp")])
    assert res.exit_code == 0, res.output
    flat = read_pomdp(tmp_path / "ar.pomdp")
    assert flat.n_states == 3 * 2 + 1 and flat.n_actions == 3 + 2
    res = runner.invoke(pomdp_app, ["export", "--out", str(tmp_path / "x.pomdpx")])
    assert res.exit_code == 2
    assert "exactly one of --problem, --benchmark and --workspace" in res.output


def test_solve_workspace_problems_writes_one_policy_per_model(tmp_path):
    P, E = small_arrays()
    models = {"ra": P, "classifier": np.full_like(P, 0.5)}
    paths = solve_workspace_problems(models, E, None, tmp_path, timeout=3)
    assert set(paths) == {"ra", "classifier"}
    summary = json.loads((tmp_path / "solve_summary.json").read_text())
    # an uninformative classifier: declaring at once (−5 for two classes) is optimal
    assert summary["classifier"]["lower"] == pytest.approx(-5.0)
    assert summary["ra"]["lower"] >= -5.0
    policy = ActiveRecognitionPolicy.load(paths["classifier"])
    assert policy.act(0, np.array([0.5, 0.5])).kind == "declare"


def test_an_iteration_budget_makes_solves_reproducible_in_any_process(tmp_path):
    from rapomdp.planning.momdp import benchmark_problem

    problem = benchmark_problem(24, 6, seed=4)
    models = {"a": problem.observation_model, "b": problem.observation_model[::-1].copy()}
    runs = []
    for name, workers in (("one", 1), ("again", 1), ("two", 2)):
        out = tmp_path / name
        out.mkdir()
        solve_workspace_problems(models, problem.move_energy, None, out, timeout=60,
                                 max_iterations=6, workers=workers)
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
