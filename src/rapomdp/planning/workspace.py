"""The pipeline's entry points for the solve stage, on plain arrays.

The observe stage provides, per observation model (RA, Classifier, black-box...), an array
``P`` (V, C, C) of P(o | class, viewpoint); the robot stage provides ``move_energy`` (V, V)
and ``reachable`` (V,). :func:`solve_workspace_problems` solves one MOMDP per observation model
and writes one policy ``.npz`` each, plus a JSON summary of the bounds.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rapomdp.io import write_text_atomic
from rapomdp.parallel import run_tasks
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.artefacts import SOLVE_SUMMARY, policy_file
from rapomdp.planning.memory import DEFAULT_MEMORY_GB
from rapomdp.planning.momdp import (
    DEFAULT_LAMBDA,
    ActiveRecognitionProblem,
    build_active_recognition_problem,
)
from rapomdp.planning.sarsop import ProgressCallback
from rapomdp.processes import WorkerPool


def _solve_one(P: np.ndarray, move_energy: np.ndarray, reachable: np.ndarray | None,
               out: Path, name: str, lambda_: float, discount: float, start_viewpoint: int,
               precision: float, timeout: float, max_iterations: int | None, allow_stay: bool,
               class_names: list[str] | None, memory_gb: float = DEFAULT_MEMORY_GB,
               start_belief: np.ndarray | None = None,
               callback: ProgressCallback | None = None) -> dict[str, float | int | bool | str]:
    """Solve one observation model's MOMDP (from ``start_belief`` over its hidden states,
    uniform when None) and write its policy; returns its summary row."""
    problem: ActiveRecognitionProblem = build_active_recognition_problem(
        P, move_energy, reachable, lambda_, discount, start_viewpoint, start_belief,
        allow_stay=allow_stay, class_names=class_names,
    )
    result = solve_active_recognition(problem, precision, timeout, callback,
                                      max_iterations=max_iterations, memory_gb=memory_gb)
    result.policy.save(out / policy_file(name))
    return {
        "lower": result.lower,
        "upper": result.upper,
        "seconds": result.elapsed,
        "iterations": result.iterations,
        "converged": result.converged,
        # the CPU-time limit, not the iteration count, stopped it: not reproducible
        "timed_out": bool(not result.converged and (max_iterations is None
                                                    or result.iterations < max_iterations)),
        "vectors": int(len(result.policy.targets)),
        "note": result.note,
    }


def solve_workspace_problems(
    observation_models: Mapping[str, np.ndarray],
    move_energy: np.ndarray,
    reachable: np.ndarray | None,
    out_dir: str | os.PathLike[str],
    lambda_: float = DEFAULT_LAMBDA,
    discount: float = 0.95,
    start_viewpoint: int = 0,
    precision: float = 1e-3,
    timeout: float = 30.0,
    allow_stay: bool = False,
    class_names: list[str] | None = None,
    callback: ProgressCallback | None = None,
    max_iterations: int | None = None,
    workers: int = 1,
    memory_gb: float = DEFAULT_MEMORY_GB,
    scheduler: str | None = None,
    start_beliefs: Mapping[str, np.ndarray | None] | None = None,
    pool: WorkerPool | None = None,
) -> dict[str, Path]:
    """Solve one active-recognition MOMDP per observation model; returns name → policy path.
    ``start_beliefs``: a model's start belief over its hidden states (a typed model's prior
    over (instance type, class); absent or None: uniform).

    Each solve stops at ``precision``, after ``max_iterations`` iterations (reproducible) or
    after ``timeout`` seconds of process CPU time (not), whichever comes first, within
    ``memory_gb`` each (:class:`~rapomdp.planning.memory.MemoryCapError` when a problem cannot
    fit); models are solved over ``workers`` processes (``pool``'s when it has as many), or on
    the Dask ``scheduler`` when one is named. Writes ``out_dir/policy_<name>.npz`` (atomically)
    and ``out_dir/solve_summary.json`` with the bounds reached, the time, the policy size and
    the memory plan's note.

    Args:
        observation_models: ``{name: (V, S, C) P(label | hidden state, viewpoint)}``.
        move_energy: (V, V) E_M in metres (+inf to or from unreachable viewpoints).
        reachable: (V,) bool, or None for all.
        out_dir: Where the policies and the summary go.
        lambda_: The cost of a wrong declaration, metres.
        discount: The discount factor.
        start_viewpoint: The first image's viewpoint.
        precision: The gap at the start at which a solve stops.
        timeout: CPU seconds per solve.
        allow_stay: Whether moving to the current viewpoint is an action.
        class_names: The classes' names.
        callback: Progress of each solve (solves run in this process then).
        max_iterations: Sampling rounds per solve (None: until precision or timeout).
        workers: Processes to spread the models over.
        memory_gb: The memory cap per solve, GB.
        scheduler: A Dask scheduler address, or None.
        start_beliefs: ``{name: (S,) start belief}`` (absent or None: uniform).
        pool: A pool of worker processes to reuse.

    Returns:
        ``{name: path of its policy .npz}``.

    Example:
        Two models of one problem: a sharp one and a blurred one (seconds)::

            P = benchmark_problem(16, 4).observation_model
            E = benchmark_problem(16, 4).move_energy
            blurred = 0.5 * P + 0.5 / 4
            paths = solve_workspace_problems({"sharp": P, "blurred": blurred}, E, None, "out",
                                             max_iterations=50)
            ActiveRecognitionPolicy.load(paths["sharp"])
    """
    out = Path(out_dir)
    names = list(observation_models)
    common = (lambda_, discount, start_viewpoint, precision, timeout, max_iterations, allow_stay,
              class_names, memory_gb)
    start = start_beliefs or {}
    if (workers > 1 or scheduler is not None) and callback is None:
        rows = run_tasks(_solve_one, [(observation_models[n], move_energy, reachable, out, n,
                                       *common, start.get(n)) for n in names], workers,
                         "solve: POMDPs", scheduler=scheduler, unit="solves", pool=pool)
    else:
        rows = [_solve_one(observation_models[n], move_energy, reachable, out, n, *common,
                           start.get(n), callback) for n in names]
    summary = dict(zip(names, rows, strict=True))
    write_text_atomic(out / SOLVE_SUMMARY, json.dumps(summary, indent=2) + "\n")
    return {name: out / policy_file(name) for name in names}


def solve_problem_sets(
    sets: Sequence[tuple[str | os.PathLike[str], float, Mapping[str, np.ndarray]]],
    move_energy: np.ndarray,
    reachable: np.ndarray | None,
    *,
    discount: float = 0.95,
    start_viewpoint: int = 0,
    precision: float = 1e-3,
    timeout: float = 30.0,
    allow_stay: bool = False,
    class_names: list[str] | None = None,
    max_iterations: int | None = None,
    workers: int = 1,
    memory_gb: float = DEFAULT_MEMORY_GB,
    scheduler: str | None = None,
    cost: Mapping[str, float] | None = None,
    description: str = "solve: POMDPs",
    start_beliefs: Mapping[str, np.ndarray | None] | None = None,
    pool: WorkerPool | None = None,
) -> dict[Path, dict[str, Path]]:
    """Several :func:`solve_workspace_problems` calls, (folder, λ, models) each, in one pool.

    ``start_beliefs`` as for :func:`solve_workspace_problems` (by model name). Every folder
    gets the files and the summary one call would write it, but all the problems
    share the ``workers`` processes, started in decreasing order of λ and then of ``cost[name]``
    (a relative estimate of a model's solve time; larger λ, deeper plans, longer solves), so the
    longest start first instead of one folder's tail holding up the next folder. The order
    decides only the wall time: each solve is the one it would be alone. ``description``
    labels the progress bar (which counts solves).
    """
    common = (discount, start_viewpoint, precision, timeout, max_iterations, allow_stay,
              class_names, memory_gb)
    jobs = [(Path(folder), lam, name, models[name])
            for folder, lam, models in sets for name in models]
    weights = cost or {}
    order = sorted(range(len(jobs)),
                   key=lambda i: (-jobs[i][1], -weights.get(jobs[i][2], 0.0)))
    start = start_beliefs or {}
    tasks = [(jobs[i][3], move_energy, reachable, jobs[i][0], jobs[i][2], jobs[i][1], *common,
              start.get(jobs[i][2])) for i in order]
    solved = run_tasks(_solve_one, tasks, workers, description, scheduler=scheduler,
                       unit="solves", pool=pool)
    rows = dict(zip(order, solved, strict=True))
    paths: dict[Path, dict[str, Path]] = {}
    for folder, _, models in sets:
        out = Path(folder)
        summary = {name: rows[i] for i, (f, _, name, _) in enumerate(jobs) if f == out}
        write_text_atomic(out / SOLVE_SUMMARY, json.dumps(summary, indent=2) + "\n")
        paths[out] = {name: out / policy_file(name) for name in models}
    return paths
