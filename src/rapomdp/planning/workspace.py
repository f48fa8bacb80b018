"""The pipeline's entry points for the solve stage, on plain arrays.

The observe stage provides, per observation model (RA, Classifier, black-box...), an array
``P`` (V, C, C) of P(o | class, viewpoint); the robot stage provides ``move_energy`` (V, V)
and ``reachable`` (V,). :func:`solve_workspace_problems` solves one MOMDP per observation model
and writes one policy ``.npz`` each, plus a JSON summary of the bounds.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.io_pomdp import atomic_write_text
from rapomdp.planning.momdp import ActiveRecognitionProblem, build_active_recognition_problem
from rapomdp.planning.sarsop import ProgressCallback

PROBLEM_KEYS = ("observation_model", "move_energy", "reachable")


def load_problem_arrays(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read ``observation_model`` (V, C, C), ``move_energy`` (V, V) and optionally
    ``reachable`` (V,) from an ``.npz`` (no pickle); a clear ValueError when one is missing."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read problem arrays ({exc})") from None
    for key in PROBLEM_KEYS[:2]:
        if key not in arrays:
            raise ValueError(f"{path}: missing array {key!r} (has {sorted(arrays)})")
    return arrays


def solve_workspace_problems(
    observation_models: Mapping[str, np.ndarray],
    move_energy: np.ndarray,
    reachable: np.ndarray | None,
    out_dir: str | os.PathLike[str],
    lambda_: float = 10.0,
    discount: float = 0.95,
    start_viewpoint: int = 0,
    precision: float = 1e-3,
    timeout: float = 30.0,
    allow_stay: bool = False,
    class_names: list[str] | None = None,
    callback: ProgressCallback | None = None,
) -> dict[str, Path]:
    """Solve one active-recognition MOMDP per observation model; returns name → policy path.

    Writes ``out_dir/policy_<name>.npz`` (atomically) and ``out_dir/solve_summary.json`` with
    the bounds reached, the time and the policy size of each.
    """
    out = Path(out_dir)
    paths: dict[str, Path] = {}
    summary: dict[str, dict[str, float | int | bool]] = {}
    for name, P in observation_models.items():
        problem: ActiveRecognitionProblem = build_active_recognition_problem(
            P, move_energy, reachable, lambda_, discount, start_viewpoint,
            allow_stay=allow_stay, class_names=class_names,
        )
        result = solve_active_recognition(problem, precision, timeout, callback)
        paths[name] = result.policy.save(out / f"policy_{name}.npz")  # type: ignore[attr-defined]
        summary[name] = {
            "lower": result.lower,
            "upper": result.upper,
            "seconds": result.elapsed,
            "iterations": result.iterations,
            "converged": result.converged,
            "vectors": int(len(result.policy.targets)),  # type: ignore[attr-defined]
        }
    atomic_write_text(out / "solve_summary.json", json.dumps(summary, indent=2) + "\n")
    return paths
