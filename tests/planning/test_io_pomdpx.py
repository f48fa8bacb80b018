"""Exports: the .pomdpx tables and the flat .pomdp re-read give back the same problem, and the
reference SARSOP toolkit (when its ``pomdpsol`` is on this machine) loads and solves both."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rapomdp.planning import (
    build_active_recognition_problem,
    read_pomdp,
    solve_active_recognition,
    to_flat_pomdp,
    write_pomdp,
    write_pomdpx,
)
from rapomdp.planning.io_pomdpx import format_pomdpx
from rapomdp.planning.momdp import (
    FORBIDDEN_REWARD,
    benchmark_problem,
)


def general_problem() -> object:
    """A problem with full confusion matrices, an unreachable viewpoint and no stays."""
    rng = np.random.default_rng(4)
    n_v, n_c = 5, 3
    P = rng.dirichlet(np.ones(n_c), size=(n_v, n_c))
    E = rng.uniform(0.3, 1.0, size=(n_v, n_v))
    reach = np.array([True, True, False, True, True])
    return build_active_recognition_problem(P, E, reach, 4.0, 0.9, 1,
                                            start_belief=np.array([0.5, 0.3, 0.2]))


def pomdpx_tables(text: str) -> dict[str, object]:
    """The arrays a .pomdpx of ours encodes, read back from its XML entries."""
    root = ET.fromstring(text.encode())
    views = root.find("Variable/StateVar[@vnamePrev='view_0']/ValueEnum").text.split()
    classes = root.find("Variable/StateVar[@vnamePrev='class_0']/ValueEnum").text.split()
    actions = root.find("Variable/ActionVar/ValueEnum").text.split()
    n_v, n_c = len(views) - 1, len(classes)
    P = np.full((n_v, n_c, n_c), np.nan)
    done_row = None
    for e in root.findall("ObsFunction/CondProb/Parameter/Entry"):
        _, v, c, _ = e.find("Instance").text.split()
        row = [float(x) for x in e.find("ProbTable").text.split()]
        if v == "done":
            done_row = row
        else:
            P[views.index(v), classes.index(c)] = row
    moves = [a for a in actions if a.startswith("move")]
    reward = {e.find("Instance").text: float(e.find("ValueTable").text)
              for e in root.findall("RewardFunction/Func/Parameter/Entry")}
    cost = np.zeros((n_v, len(moves)))
    for a, m in enumerate(moves):
        for v in range(n_v):
            cost[v, a] = -reward.get(f"{m} v{v} *", 0.0)
    b0 = [float(x) for x in root.findall("InitialStateBelief/CondProb")[1]
          .find("Parameter/Entry/ProbTable").text.split()]
    start = root.findall("InitialStateBelief/CondProb")[0].find("Parameter/Entry/Instance").text
    return {"P": P, "done_row": done_row, "targets": [int(m[4:]) for m in moves],
            "cost": cost, "b0": np.array(b0), "start": views.index(start),
            "discount": float(root.find("Discount").text),
            "lambda": -reward[f"declare0 v0 {classes[1]}"]}


def test_pomdpx_tables_give_back_the_problem() -> None:
    problem = general_problem()
    text = format_pomdpx(problem)
    assert "uniform" not in text  # pomdpsol accepts the keyword only in the initial belief
    back = pomdpx_tables(text)
    np.testing.assert_array_equal(back["P"], problem.observation_model)
    assert back["done_row"] == [1.0, 0.0, 0.0]
    assert back["targets"] == problem.targets.tolist() == [0, 1, 3, 4]
    cost = problem.move_cost()
    expected = np.where(np.isfinite(cost), cost, -FORBIDDEN_REWARD)
    np.testing.assert_array_equal(back["cost"], expected)
    np.testing.assert_array_equal(back["b0"], problem.start_belief)
    assert (back["start"], back["discount"], back["lambda"]) == (1, 0.9, 4.0)


def test_flat_pomdp_export_reads_back_as_the_same_problem(tmp_path: Path) -> None:
    problem = general_problem()
    flat = to_flat_pomdp(problem)
    back = read_pomdp(write_pomdp(flat, tmp_path / "ar.pomdp"))
    # the reader renormalises rows: equal to the last bits
    np.testing.assert_allclose(back.T, flat.T, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.Z, flat.Z, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(back.R, flat.R)
    np.testing.assert_array_equal(back.initial_belief, flat.initial_belief)
    assert back.discount == flat.discount
    assert back.state_names == flat.state_names and back.action_names == flat.action_names
    # sparse entries: one line per non-zero, not n_states numbers per row
    lines = (tmp_path / "ar.pomdp").read_text().splitlines()
    assert len(lines) < 2 * (np.count_nonzero(flat.T) + np.count_nonzero(flat.Z[0]))


def pomdpsol() -> Path | None:
    """The reference toolkit's solver: $RAPOMDP_POMDPSOL, else ``pomdpsol`` on the PATH."""
    env = os.environ.get("RAPOMDP_POMDPSOL")
    if env:
        return Path(env) if Path(env).is_file() else None
    found = shutil.which("pomdpsol")
    return Path(found) if found else None


ROW = re.compile(r"^\s*[\d.]+\s+\d+\s+\d+\s+(-?[\d.e+-]+)\s+(-?[\d.e+-]+)\s", re.M)


@pytest.mark.skipif(pomdpsol() is None, reason="the reference SARSOP toolkit's pomdpsol is not "
                    "here: build it with benchmarks/sarsop_reference.py and set RAPOMDP_POMDPSOL")
@pytest.mark.parametrize("suffix", [".pomdpx", ".pomdp"])
def test_the_reference_toolkit_loads_and_solves_our_exports(tmp_path: Path, suffix: str) -> None:
    problem = general_problem()
    path = (write_pomdpx(problem, tmp_path / "ar.pomdpx") if suffix == ".pomdpx"
            else write_pomdp(to_flat_pomdp(problem), tmp_path / "ar.pomdp"))
    out = subprocess.run([str(pomdpsol()), str(path), "--timeout", "2", "--precision", "1e-4",
                          "-o", str(tmp_path / "out.policy")],
                         capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert "ERROR" not in out.stdout
    rows = ROW.findall(out.stdout)
    assert rows, out.stdout[-2000:]
    theirs = tuple(float(x) for x in rows[-1])
    ours = solve_active_recognition(problem, precision=1e-4, timeout=1e6, max_iterations=200)
    # both solvers' bounds bracket the same optimum
    assert theirs[0] <= ours.upper + 1e-3 and ours.lower <= theirs[1] + 1e-3
    assert theirs[0] == pytest.approx(ours.lower, abs=2e-2)


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
