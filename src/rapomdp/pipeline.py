"""The stages in pipeline order; data flows one way, each stage reading only earlier ones.

The stage graph (names, sections, inputs, versions, fingerprints) is read from light modules; a
stage's code (torch, the robot, rendering) is imported when the stage runs, so that reading the
graph (``rapomdp status``, staleness, planned keys) loads none of it.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterable, Sequence
from functools import partial
from pathlib import Path

from rapomdp.awareness.artefacts import (
    OBSERVE_SECTIONS,
    SALIENCY_SECTIONS,
    VOLUME_SECTIONS,
    volume_file,
)
from rapomdp.config import Config, apply_overrides, config_from_dict, read_config_data
from rapomdp.context import RunContext
from rapomdp.data.layouts import dataset_fingerprint
from rapomdp.data.sections import XRHO_SECTIONS
from rapomdp.experiment.sections import (
    EVALUATE_SECTIONS,
    LEARN_SECTIONS,
    REPORT_INPUTS,
    REPORT_SECTIONS,
    learn_fingerprint,
)
from rapomdp.parallel import pooled
from rapomdp.recognition.artefacts import EVAL_SECTIONS, TRAIN_SECTIONS, VPTREE_SECTIONS
from rapomdp.workspace import Stage, StageError, StageInputs, StageResult, Workspace, stage_key

StageRun = Callable[[Config, StageInputs, Path, RunContext], None]


def stage_code(name: str) -> StageRun:
    """The function that runs stage ``name``, imported now (not with the stage graph)."""
    if name == "dataset":
        from rapomdp.data.dataset import run_dataset_stage as run
    elif name == "render":
        from rapomdp.data.training_views import run_render_stage as run
    elif name == "train":
        from rapomdp.recognition.stage import run_train_stage as run
    elif name == "xrho":
        from rapomdp.data.test_views import run_xrho_stage as run
    elif name == "classifier_eval":
        from rapomdp.recognition.stage import run_classifier_eval_stage as run
    elif name == "saliency":
        from rapomdp.awareness.stage import run_saliency_stage as run
    elif name == "volume":
        from rapomdp.awareness.stage import run_volume_stage as run
    elif name == "robot":
        from rapomdp.robot.stage import run_robot_stage as run
    elif name == "observe":
        from rapomdp.awareness.observe_stage import run_observe_stage as run
    elif name == "vptree":
        from rapomdp.recognition.vptree_stage import run_vptree_stage as run
    elif name == "solve":
        from rapomdp.planning.stage import run_solve_stage as run
    elif name == "learn":
        from rapomdp.experiment.learn_stage import run_learn_stage as run
    elif name == "evaluate":
        from rapomdp.experiment.evaluation import run_evaluate_stage as run
    elif name == "report":
        from rapomdp.experiment.report import run_report_stage as run
    else:
        raise KeyError(unknown_stages_message([name]))
    return run


def _run_stage(name: str, config: Config, inputs: StageInputs, out: Path,
               context: RunContext) -> None:
    stage_code(name)(config, inputs, out, context)


def _deferred(name: str) -> StageRun:
    """A stage's ``run``: :func:`stage_code` of ``name``, called when the stage runs."""
    return partial(_run_stage, name)


STAGES: list[Stage] = [
    Stage(
        name="dataset",
        run=_deferred("dataset"),
        sections=("seed", "dataset"),
        fingerprint=dataset_fingerprint,
        description="normalised meshes and the per-class train/volume/test split",
    ),
    Stage(
        name="render",
        run=_deferred("render"),
        sections=("seed", "camera", "render"),
        inputs=("dataset",),
        description="depth images of every model over the training viewsphere",
    ),
    Stage(
        name="train",
        run=_deferred("train"),
        sections=TRAIN_SECTIONS,
        inputs=("dataset", "render"),
        description="depth CNN classifier trained on the train models' renders",
    ),
    Stage(
        name="xrho",
        run=_deferred("xrho"),
        sections=XRHO_SECTIONS,
        inputs=("dataset",),
        description="the volume and test models' depth images at the test viewpoints X_rho, "
                    "rendered once for every stage that reads them",
    ),
    Stage(
        name="classifier_eval",
        run=_deferred("classifier_eval"),
        sections=EVAL_SECTIONS,
        inputs=("dataset", "render", "train", "xrho"),
        description="single-view accuracy on the test models, confusion, per viewpoint",
    ),
    Stage(
        name="saliency",
        run=_deferred("saliency"),
        sections=SALIENCY_SECTIONS,
        inputs=("dataset", "render", "train"),
        description="2D saliency maps of each class's volume model over the training viewsphere",
    ),
    Stage(
        name="volume",
        run=_deferred("volume"),
        sections=VOLUME_SECTIONS,
        inputs=("dataset", "render", "saliency"),
        description="3D dense saliency volume per class (voxel median of back-projected saliency)",
    ),
    Stage(
        name="robot",
        run=_deferred("robot"),
        sections=("seed", "viewpoints", "robot"),
        description="Panda IK, reachability and manipulability per test viewpoint; energy E_M",
    ),
    Stage(
        name="observe",
        run=_deferred("observe"),
        sections=OBSERVE_SECTIONS,
        inputs=("dataset", "train", "xrho", "classifier_eval", "volume"),
        version="6",  # 2: ra_transfer's kernel chosen per dataset on held-out evidence; 3: the
        # declared confidence fitted where held-out walks stop; 4: by the confidence's
        # cross-entropy, and at each stop threshold; 5: ra_viewpoint's stacked term centred,
        # ra_region fitted; 6: auto leaves the robust default only if it does so without
        # each group too (auto and its check retired since, docs/decisions/0006)
        description="viewpoint scores, observation models P(o | class, x), self-awareness quality",
    ),
    Stage(
        name="vptree",
        run=_deferred("vptree"),
        sections=VPTREE_SECTIONS,
        inputs=("dataset", "render", "xrho"),
        version="3",  # 2: the declared confidence fitted where held-out walks stop; 3: by the
        # confidence's cross-entropy, and at each stop threshold
        description="VP-tree baseline: vocabulary-tree classifier, its confusion P(o | class, x)",
    ),
    Stage(
        name="solve",
        run=_deferred("solve"),
        sections=("solve",),
        inputs=("observe", "vptree", "robot"),
        description="one active-recognition POMDP policy per observation model",
    ),
    Stage(
        name="learn",
        run=_deferred("learn"),
        sections=LEARN_SECTIONS,
        inputs=("dataset", "classifier_eval", "observe", "robot"),
        fingerprint=learn_fingerprint,
        description="learned baseline: MaskablePPO on held-out recorded evidence (when "
        "evaluate.methods lists 'learned')",
    ),
    Stage(
        name="evaluate",
        run=_deferred("evaluate"),
        version="3",  # 2: the learned baseline reports with its held-out closed-loop a;
        # 3: every method's held-out closed loop compared (held_out/comparison.json)
        sections=EVALUATE_SECTIONS,
        inputs=("dataset", "train", "classifier_eval", "observe", "vptree", "robot", "solve",
                "learn"),
        description="closed-loop episodes of every method on the test models: Table 1, Fig. 3",
    ),
    Stage(
        name="report",
        run=_deferred("report"),
        sections=REPORT_SECTIONS,
        inputs=REPORT_INPUTS,
        description="markdown + HTML report: Table 1, Figs. 1-3, classifier, robot, solver",
    ),
]

STAGE_NAMES = [stage.name for stage in STAGES]


def unknown_stages_message(names: Iterable[str]) -> str:
    """``unknown stage 'evalute' (did you mean 'evaluate'?); stages are: ...``."""
    parts = []
    for name in names:
        close = difflib.get_close_matches(name, STAGE_NAMES, n=1, cutoff=0.6)
        parts.append(f"'{name}'" + (f" (did you mean '{close[0]}'?)" if close else ""))
    return (f"unknown stage{'s' if len(parts) > 1 else ''} {', '.join(parts)}; stages are: "
            f"{', '.join(STAGE_NAMES)}")


def get_stage(name: str) -> Stage:
    for stage in STAGES:
        if stage.name == name:
            return stage
    raise KeyError(unknown_stages_message([name]))


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
    a workspace of ``share_from`` already made with the same key is taken from it instead.

    The library's ``rapomdp run``: the whole pipeline from the meshes to Table 1, cached stage by
    stage in ``workspace`` (a stage whose configuration sections and inputs are unchanged is
    not run again), holding the workspace's lock for the whole run.

    Args:
        config: The configuration (:class:`~rapomdp.config.Config`; ``Config()`` is the
            default, the embedded procedural dataset).
        workspace: Where the artefacts go; a new or empty folder becomes a workspace.
        until: Stop after this stage (and the stages it needs); None runs them all.
        force: Names of stages to redo even when cached.
        on_result: Called with each stage's result as soon as it is known (a progress line).
        context: Workers, threads, scheduler and progress bars of the run.
        share_from: Workspaces whose identical artefacts (the same key) are taken as hard links
            instead of running the stage (a study's other seeds).

    Returns:
        One result per stage run or skipped, in pipeline order: its name, its key, whether it
        was cached (or shared) and its wall time in seconds.

    Raises:
        KeyError: ``force`` names a stage that does not exist (with the nearest name).
        StageError: A stage cannot run (a missing input, bad data it names).
        WorkspaceBusyError: Another run holds the workspace.

    Example:
        The dataset stage of the default configuration (seconds), then again (cached)::

            from rapomdp.config import Config
            from rapomdp.pipeline import run_pipeline
            from rapomdp.workspace import Workspace

            ws = Workspace("runs/demo")
            results = run_pipeline(Config(), ws, until="dataset")
            [(r.name, r.cached) for r in results]  # [('dataset', False)]
            [(r.name, r.cached) for r in run_pipeline(Config(), ws, until="dataset")]
            # [('dataset', True)]
            run_pipeline(Config(), ws)  # every stage: Table 1 in runs/demo/evaluate/table1.md
    """
    force = set(force)
    unknown = force - set(STAGE_NAMES)
    if unknown:
        raise KeyError(unknown_stages_message(sorted(unknown)))
    stages = STAGES if until is None else stages_up_to(until)
    results = []
    with workspace.locked(), pooled(context) as context:
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
    from rapomdp.awareness.figures import fig2
    from rapomdp.awareness.report import FIGURES_DIR
    from rapomdp.awareness.volume import SaliencyVolume
    from rapomdp.data.training_views import load_training_views

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
                   overrides: Sequence[str] = (), reconfigure: bool = False,
                   on_note: Callable[[str], None] | None = None
                   ) -> tuple[Config, dict[str, list[str]]]:
    """The configuration a command runs with, and the recorded stages it would redo (why).

    A folder that is not a workspace (:meth:`Workspace.check`) is refused first. The
    workspace owns its configuration: without ``config_path`` it is ``W/config.yaml``;
    when that is missing but stages are recorded, the configuration their records hold (never
    the default, which would redo them; ``on_note`` is told); the default for a new
    workspace. ``overrides`` (``train.epochs=5``) apply on top and are validated with it. A
    file that would invalidate recorded stages needs ``reconfigure``; overrides are explicit,
    so the stages they invalidate are only reported.
    """
    workspace.check()  # a folder that is not a workspace is named before it is read
    rebuilt = None
    if config_path is None and not workspace.config_path.exists():
        rebuilt = workspace.records_config_data()
    if config_path is not None:
        data, source = read_config_data(config_path), str(config_path)
    elif rebuilt is not None:
        data, source = rebuilt, workspace.records_source()
        if on_note is not None:
            on_note(f"{workspace.config_path} is missing: the configuration is rebuilt from the "
                    f"stage records of {workspace.manifest_path}, not the default (a section no "
                    "recorded stage reads is the default)")
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
