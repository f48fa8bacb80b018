"""The stages in pipeline order; data flows one way, each stage reading only earlier ones."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from rapomdp.awareness.artefacts import volume_file
from rapomdp.awareness.figures import fig2
from rapomdp.awareness.report import FIGURES_DIR
from rapomdp.awareness.stage import (
    CROSSFIT_SECTIONS,
    OBSERVE_SECTIONS,
    SALIENCY_SECTIONS,
    VOLUME_SECTIONS,
    crossfit_fingerprint,
    run_crossfit_stage,
    run_observe_stage,
    run_saliency_stage,
    run_volume_stage,
)
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.config import Config, apply_overrides, config_from_dict, read_config_data
from rapomdp.context import RunContext
from rapomdp.data.dataset import dataset_fingerprint, run_dataset_stage
from rapomdp.data.training_views import load_training_views, run_render_stage
from rapomdp.experiment.evaluation import EVALUATE_SECTIONS, run_evaluate_stage
from rapomdp.experiment.report import REPORT_INPUTS, REPORT_SECTIONS, run_report_stage
from rapomdp.planning.stage import run_solve_stage
from rapomdp.recognition.stage import (
    EVAL_SECTIONS,
    TRAIN_SECTIONS,
    run_classifier_eval_stage,
    run_train_stage,
)
from rapomdp.recognition.vptree_stage import VPTREE_SECTIONS, run_vptree_stage
from rapomdp.robot.stage import run_robot_stage
from rapomdp.workspace import Stage, StageError, StageResult, Workspace, stage_key

STAGES: list[Stage] = [
    Stage(
        name="dataset",
        run=run_dataset_stage,
        sections=("seed", "dataset"),
        fingerprint=dataset_fingerprint,
        description="normalised meshes and the per-class train/volume/test split",
    ),
    Stage(
        name="render",
        run=run_render_stage,
        sections=("seed", "camera", "render"),
        inputs=("dataset",),
        description="depth images of every model over the training viewsphere",
    ),
    Stage(
        name="train",
        run=run_train_stage,
        sections=TRAIN_SECTIONS,
        inputs=("dataset", "render"),
        description="depth CNN classifier trained on the train models' renders",
    ),
    Stage(
        name="classifier_eval",
        run=run_classifier_eval_stage,
        sections=EVAL_SECTIONS,
        inputs=("dataset", "render", "train"),
        description="single-view accuracy on the test models, confusion, per viewpoint",
    ),
    Stage(
        name="saliency",
        run=run_saliency_stage,
        sections=SALIENCY_SECTIONS,
        inputs=("dataset", "render", "train"),
        description="2D saliency maps of each class's volume model over the training viewsphere",
    ),
    Stage(
        name="volume",
        run=run_volume_stage,
        sections=VOLUME_SECTIONS,
        inputs=("dataset", "render", "saliency"),
        description="3D dense saliency volume per class (voxel median of back-projected saliency)",
    ),
    Stage(
        name="robot",
        run=run_robot_stage,
        sections=("seed", "viewpoints", "robot"),
        description="Panda IK, reachability and manipulability per test viewpoint; energy E_M",
    ),
    Stage(
        name="crossfit",
        run=run_crossfit_stage,
        sections=CROSSFIT_SECTIONS,
        inputs=("dataset", "render"),
        fingerprint=crossfit_fingerprint,
        description="held-out evidence: k classifiers label the training models they did not see",
    ),
    Stage(
        name="observe",
        run=run_observe_stage,
        sections=OBSERVE_SECTIONS,
        inputs=("dataset", "render", "train", "volume", "crossfit"),
        version="2",  # 2: ra_transfer's kernel chosen per dataset on held-out evidence
        description="viewpoint scores, observation models P(o | class, x), self-awareness quality",
    ),
    Stage(
        name="vptree",
        run=run_vptree_stage,
        sections=VPTREE_SECTIONS,
        inputs=("dataset", "render"),
        description="VP-tree baseline: vocabulary-tree classifier, its confusion P(o | class, x)",
    ),
    Stage(
        name="solve",
        run=run_solve_stage,
        sections=("solve",),
        inputs=("observe", "vptree", "robot"),
        description="one active-recognition POMDP policy per observation model",
    ),
    Stage(
        name="evaluate",
        run=run_evaluate_stage,
        sections=EVALUATE_SECTIONS,
        inputs=("dataset", "train", "observe", "vptree", "robot", "solve"),
        description="closed-loop episodes of every method on the test models: Table 1, Fig. 3",
    ),
    Stage(
        name="report",
        run=run_report_stage,
        sections=REPORT_SECTIONS,
        inputs=REPORT_INPUTS,
        description="markdown + HTML report: Table 1, Figs. 1-3, classifier, robot, solver",
    ),
]

STAGE_NAMES = [stage.name for stage in STAGES]


def get_stage(name: str) -> Stage:
    for stage in STAGES:
        if stage.name == name:
            return stage
    raise KeyError(f"unknown stage '{name}'; stages are: {', '.join(STAGE_NAMES)}")


def stages_up_to(name: str) -> list[Stage]:
    """The stage and every stage before it (each needed stage, in order)."""
    get_stage(name)
    needed = {name}
    for stage in reversed(STAGES):
        if stage.name in needed:
            needed.update(stage.inputs)
    return [stage for stage in STAGES if stage.name in needed]


def planned_keys(config: Config, stages: Sequence[Stage] = STAGES) -> dict[str, str]:
    """Every stage's key as a run of ``config`` records it, computed without running: two
    configurations share exactly the stages whose planned keys are equal."""
    keys: dict[str, str] = {}
    for stage in stages:
        external = stage.fingerprint(config) if stage.fingerprint else None
        keys[stage.name] = stage_key(stage, config, {n: keys[n] for n in stage.inputs},
                                     external)
    return keys


def run_pipeline(
    config: Config,
    workspace: Workspace,
    until: str | None = None,
    force: Iterable[str] = (),
    on_result: Callable[[StageResult], None] | None = None,
    context: RunContext = RunContext(),
    share_from: Sequence[Workspace] = (),
) -> list[StageResult]:
    """Run every stage (or those ``until`` needs) in order, skipping current ones; a stage that
    a workspace of ``share_from`` already made with the same key is taken from it instead."""
    force = set(force)
    unknown = force - set(STAGE_NAMES)
    if unknown:
        raise KeyError(f"unknown stage(s) {sorted(unknown)}; stages are: {', '.join(STAGE_NAMES)}")
    stages = STAGES if until is None else stages_up_to(until)
    results = []
    with workspace.locked():
        for stage in stages:
            shared = None
            if stage.name not in force and not workspace.is_current(stage, config):
                shared = next((r for source in share_from
                               if (r := workspace.adopt(stage, config, source)) is not None),
                              None)
            result = shared or workspace.run(stage, config, force=stage.name in force,
                                             context=context)
            results.append(result)
            if on_result is not None:
                on_result(result)
        # Each stage that ran recorded the configuration; a run where every stage was cached
        # records it only if no recorded stage disagrees with it (it made no artefact).
        if not workspace.staleness(STAGES, config, external=False):
            workspace.record_config(config)
    return results


def write_fig2(config: Config, ws: Workspace, target: str, against: Sequence[str],
               epochs: int | None = None,
               on_result: Callable[[StageResult], None] | None = None,
               context: RunContext = RunContext()) -> tuple[Path, Path]:
    """Fig. 2: ``target``'s volume in one two-class problem per opponent (each with its own
    classifier, in ``W/fig2/<target>-vs-<other>``) and in the all-class problem (``W``)."""
    volumes, titles = [], []
    for other in against:
        if other == target:
            raise StageError(f"fig2: the opponent '{other}' is the target class itself")
        pair = config.model_copy(deep=True)
        pair.dataset.classes = [target, other]
        if epochs is not None:
            pair.train.epochs = epochs
        sub = Workspace(ws.root / "fig2" / f"{target}-vs-{other}")
        run_pipeline(pair, sub, until="volume", on_result=on_result, context=context)
        volumes.append(SaliencyVolume.load(sub.require("volume") / volume_file(target)))
        titles.append(f"{target} vs {other}")
    run_pipeline(config, ws, until="volume", on_result=on_result, context=context)
    classes = load_training_views(ws.require("render"), ws.require("dataset")).dataset.classes
    if target not in classes:
        raise StageError(f"class '{target}' is not in the workspace's dataset")
    volumes.append(SaliencyVolume.load(ws.require("volume") / volume_file(target)))
    titles.append(f"all {len(classes)} classes")
    out = ws.root / FIGURES_DIR
    return fig2(volumes, titles, target, out / "fig2.png", out / "fig2.html")


class ReconfigureError(StageError):
    """A configuration file would invalidate a workspace's artefacts without --reconfigure."""


def format_staleness(stale: dict[str, list[str]]) -> str:
    """One line per stale stage: ``  train: train.epochs 25 -> 5``."""
    return "\n".join(f"  {name}: {'; '.join(reasons)}" for name, reasons in stale.items())


def resolve_config(workspace: Workspace, config_path: str | Path | None = None,
                   overrides: Sequence[str] = (), reconfigure: bool = False
                   ) -> tuple[Config, dict[str, list[str]]]:
    """The configuration a command runs with, and the recorded stages it would redo (why).

    The workspace owns its configuration: without ``config_path`` it is ``W/config.yaml`` (the
    default for a new workspace); ``overrides`` (``train.epochs=5``) apply on top and are
    validated with it. A file that would invalidate recorded stages needs ``reconfigure``;
    overrides are explicit, so the stages they invalidate are only reported.
    """
    if config_path is not None:
        data, source = read_config_data(config_path), str(config_path)
    elif workspace.config_path.exists():
        data, source = read_config_data(workspace.config_path), str(workspace.config_path)
    else:
        data, source = {}, "the default configuration"
    if overrides:
        data = apply_overrides(data, overrides)
        source = f"{source} with {' '.join(o[:60] for o in overrides)}"
    config = config_from_dict(data, source)
    stale = workspace.staleness(STAGES, config, external=False)
    recorded = workspace.recorded_config()
    if recorded is not None and stale:  # stages already stale before this change are left out
        before = workspace.staleness(STAGES, recorded, external=False)
        stale = {name: why for name, why in stale.items() if name not in before}
    if config_path is not None and stale and not reconfigure:
        raise ReconfigureError(
            f"{config_path} differs from {workspace.config_path}, the configuration the "
            f"artefacts were made with: pass --reconfigure to redo {len(stale)} stage(s), or "
            f"drop -c to keep the workspace's configuration:\n{format_staleness(stale)}")
    return config, stale
