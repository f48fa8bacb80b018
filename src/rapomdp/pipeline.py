"""The stages in pipeline order; data flows one way, each stage reading only earlier ones."""

from __future__ import annotations

from collections.abc import Callable, Iterable

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
from rapomdp.config import Config
from rapomdp.data.dataset import dataset_fingerprint, run_dataset_stage
from rapomdp.data.training_views import run_render_stage
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
from rapomdp.workspace import Stage, StageResult, Workspace

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


def run_pipeline(
    config: Config,
    workspace: Workspace,
    until: str | None = None,
    force: Iterable[str] = (),
    on_result: Callable[[StageResult], None] | None = None,
) -> list[StageResult]:
    """Run every stage (or those ``until`` needs) in order, skipping current ones."""
    force = set(force)
    unknown = force - set(STAGE_NAMES)
    if unknown:
        raise KeyError(f"unknown stage(s) {sorted(unknown)}; stages are: {', '.join(STAGE_NAMES)}")
    stages = STAGES if until is None else stages_up_to(until)
    results = []
    for stage in stages:
        result = workspace.run(stage, config, force=stage.name in force)
        results.append(result)
        if on_result is not None:
            on_result(result)
    return results
