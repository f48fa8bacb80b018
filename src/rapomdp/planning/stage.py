"""The ``solve`` stage: one active-recognition policy per observation model of the workspace.

Reads ``W/observe/observation_models.npz`` (``models``: the names; per name an array (V, C, C) =
P(o | class, viewpoint); ``classes``), ``W/vptree/observation_model.npz`` (``vptree`` (V, C, C),
``classes``: the VP-tree baseline's model, tempered by the vptree stage as the observe stage
tempers its own) and ``W/robot/robot.npz`` (``energy`` (V, V) E_M, ``reachable`` (V,),
``distance_m``). Writes ``policy_<model>.npz`` and ``solve_summary.json``.

Moves to or from an unreachable viewpoint are not actions (the robot stage gives them +inf);
the energy goes to the problem builder as it is, which handles those entries
(:func:`~rapomdp.planning.momdp.finite_move_energy`).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path

import numpy as np
from rich.console import Console

from rapomdp.awareness.artefacts import (
    DECLARED_PREFIX,
    DECLARED_THRESHOLD_PREFIX,
    DECLARED_THRESHOLDS,
    OBSERVATION_FILE,
)
from rapomdp.config import Config, SolveConfig
from rapomdp.context import RunContext
from rapomdp.io import load_npz
from rapomdp.planning.artefacts import load_solve_summary
from rapomdp.planning.memory import MemoryCapError
from rapomdp.planning.momdp import ActiveRecognitionProblem, build_active_recognition_problem
from rapomdp.planning.workspace import solve_workspace_problems
from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE as VPTREE_FILE
from rapomdp.robot.artefacts import ROBOT_ARRAYS
from rapomdp.workspace import StageError, StageInputs


def declared_temperatures(observe_dir: Path, offered: Collection[str],
                          vptree_dir: Path | None = None,
                          stop_threshold: float | None = None) -> dict[str, float]:
    """Each ``offered`` model's (by name; a dict of models will do) declared-confidence
    temperature (the observe stage's ``declared_temperature_<name>``, the vptree stage's
    ``declared_temperature``): what a policy with that belief reports is its belief ** a.
    With ``stop_threshold`` (a policy that stops once its belief reaches it: Random), the a
    fitted at that threshold, interpolated between the thresholds fitted (the pooled a where a
    stage fitted none). 1 where none was fitted (one held-out group)."""
    observe = load_npz(Path(observe_dir) / OBSERVATION_FILE)
    vptree: dict[str, np.ndarray] = (load_npz(Path(vptree_dir) / VPTREE_FILE)
                                     if vptree_dir is not None else {})
    arrays = {name: (observe.get(f"{DECLARED_PREFIX}{name}"),
                     observe.get(f"{DECLARED_THRESHOLD_PREFIX}{name}"),
                     observe.get(DECLARED_THRESHOLDS)) for name in offered}
    if "vptree" in offered:
        arrays["vptree"] = (vptree.get("declared_temperature"),
                            vptree.get("declared_threshold_temperatures"),
                            vptree.get("declared_thresholds"))
    out = {}
    for name, (pooled, per_threshold, thresholds) in arrays.items():
        if pooled is None:
            out[name] = 1.0
        elif stop_threshold is None or per_threshold is None or thresholds is None:
            out[name] = float(np.asarray(pooled))
        else:
            out[name] = float(np.interp(stop_threshold, thresholds, per_threshold))
    return out


def offered_observation_models(observe_dir: Path, vptree_dir: Path | None = None
                               ) -> tuple[dict[str, np.ndarray], list[str]]:
    """Every observation model a workspace offers, by name, and the class names.

    The observe stage's models, plus ``vptree`` from the vptree stage when ``vptree_dir`` is
    given (its classes and viewpoints must match the observe stage's).
    """
    observe = load_npz(Path(observe_dir) / OBSERVATION_FILE)
    classes = [str(c) for c in observe["classes"]]
    offered = {str(name): observe[str(name)] for name in observe["models"]}
    if vptree_dir is not None:
        path = Path(vptree_dir) / VPTREE_FILE
        vptree = load_npz(path)
        if "vptree" not in vptree or "classes" not in vptree:
            raise StageError(f"{path}: expected arrays 'vptree' and 'classes'")
        theirs = [str(c) for c in vptree["classes"]]
        if theirs != classes:
            raise StageError(f"{path}: the VP-tree's classes {theirs} differ from the observe "
                             f"stage's {classes}: run both on the same dataset")
        first = next(iter(offered.values()), None)
        if first is not None and vptree["vptree"].shape[0] != first.shape[0]:
            raise StageError(
                f"{path}: the VP-tree model covers {vptree['vptree'].shape[0]} viewpoints, the "
                f"observe stage's {first.shape[0]}: run both with the same viewpoints.count")
        offered["vptree"] = vptree["vptree"]
    return offered, classes


def workspace_arrays(
    observe_dir: Path, robot_dir: Path, vptree_dir: Path | None = None,
    models: Sequence[str] | None = None,
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, list[str]]:
    """The observation models to solve, as the solve stage reads them from a workspace.

    Args:
        observe_dir: The observe stage's folder.
        robot_dir: The robot stage's folder.
        vptree_dir: The vptree stage's folder (None: no ``vptree`` model offered).
        models: The models' names (``solve.models``; None: every model offered, see
            :func:`offered_observation_models`).

    Returns:
        The models by name, each (V, C, C) = P(o | class, viewpoint); E_M (V, V) in metres as
        the robot stage wrote it (+inf to and from unreachable viewpoints); the reachable
        mask (V,); the class names (C).

    Raises:
        StageError: A model not offered, or arrays over different viewpoints.
    """
    offered, classes = offered_observation_models(observe_dir, vptree_dir)
    robot = load_npz(Path(robot_dir) / ROBOT_ARRAYS)
    available = list(offered)
    wanted = list(models) if models is not None else available
    unknown = [name for name in wanted if name not in available]
    if unknown:
        hint = (" (the vptree stage makes 'vptree': run `rapomdp vptree`)"
                if "vptree" in unknown and vptree_dir is None else "")
        raise StageError(
            f"solve.models names {', '.join(unknown)}; the workspace offers "
            f"{', '.join(available)}{hint}"
        )
    chosen = {name: offered[name] for name in wanted}
    reachable = robot["reachable"].astype(bool)
    for name, array in chosen.items():
        if array.shape[0] != reachable.size:
            raise StageError(
                f"observation model '{name}' covers {array.shape[0]} viewpoints, the robot "
                f"stage {reachable.size}: run both with the same viewpoints.count"
            )
    return chosen, robot["energy"], reachable, classes


def start_viewpoint(reachable: np.ndarray) -> int:
    """The reachable viewpoint nearest the pole (viewpoints are ordered from the pole down)."""
    return int(np.flatnonzero(reachable)[0])


def workspace_problem(observe_dir: Path, robot_dir: Path, model: str,
                      vptree_dir: Path | None = None,
                      solve: SolveConfig | None = None) -> ActiveRecognitionProblem:
    """One observation model's MOMDP, as the solve stage builds it (for export).

    Args:
        observe_dir: The observe stage's folder.
        robot_dir: The robot stage's folder.
        model: The observation model's name (``ra``, ``classifier``, ``vptree``...).
        vptree_dir: The vptree stage's folder (None: no ``vptree`` model offered).
        solve: The ``solve`` section: ``models`` (which the workspace must offer), λ
            (``wrong_declaration_cost_m``, metres) and the discount (None: the defaults).

    Returns:
        The :class:`~rapomdp.planning.momdp.ActiveRecognitionProblem` over the workspace's
        V viewpoints and C classes, starting at :func:`start_viewpoint`.

    Raises:
        StageError: ``model`` not among ``solve.models``, or the stages' arrays disagree.
    """
    solve = SolveConfig() if solve is None else solve
    models, energy, reachable, classes = workspace_arrays(observe_dir, robot_dir, vptree_dir,
                                                          solve.models)
    if model not in models:
        raise StageError(f"no observation model '{model}'; available: {', '.join(models)}")
    return build_active_recognition_problem(
        models[model], energy, reachable, solve.wrong_declaration_cost_m,
        solve.discount, start_viewpoint(reachable), class_names=classes,
    )


def run_solve_stage(config: Config, inputs: StageInputs, out: Path,
                    context: RunContext) -> None:
    """Solve the workspace's active-recognition problem once per observation model.

    The solve stage: the observe stage's observation models and the robot stage's movement
    energy make one MOMDP per model (λ, discount and budget from the ``solve`` section);
    each is solved by :func:`~rapomdp.planning.ar_solver.solve_active_recognition`.

    Args:
        config: The configuration (its ``solve`` section, the start viewpoint's rule).
        inputs: The folders of the observe and robot stages (and vptree's, when its model
            is evaluated).
        out: The stage's folder: ``policy_<model>.npz`` per model and ``solve_summary.json``
            (bounds, CPU seconds, policy size, the memory plan's note).
        context: Workers and scheduler the solves are spread over.

    Raises:
        StageError: A problem does not fit ``solve.memory_gb``.

    Example:
        The stage as the pipeline runs it (``rapomdp solve -w W``)::

            from rapomdp.pipeline import run_pipeline
            run_pipeline(config, Workspace("runs/demo"), until="solve")
    """
    models, energy, reachable, classes = workspace_arrays(inputs.observe, inputs.robot,
                                                          inputs.vptree_dir, config.solve.models)
    try:
        solve_workspace_problems(
            models, energy, reachable, out,
            lambda_=config.solve.wrong_declaration_cost_m,
            discount=config.solve.discount,
            start_viewpoint=start_viewpoint(reachable),
            precision=config.solve.precision,
            timeout=config.solve.timeout_s,
            max_iterations=config.solve.iterations,
            workers=context.worker_count,
            allow_stay=False,
            class_names=classes,
            memory_gb=config.solve.memory_gb,
            scheduler=context.scheduler,
            pool=context.pool,
        )
    except MemoryCapError as exc:
        raise StageError(f"solve: {exc}") from None
    summary = load_solve_summary(out)
    for name, row in summary.items():
        if row.get("note"):
            Console(stderr=True).print(f"solve {name}: {row['note']}", highlight=False,
                                       soft_wrap=True)
