"""Policies as .npz artefacts."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import (
    benchmark_problem,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy


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
