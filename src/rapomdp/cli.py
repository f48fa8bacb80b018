"""The ``rapomdp`` command line: the whole pipeline, or one stage, on a workspace folder."""

from __future__ import annotations

import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, TypeVar

import typer
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.measure import Measurement
from rich.table import Table

from rapomdp.context import RunContext
from rapomdp.io import ArtefactError, check_output_path, check_plain_name, describe_os_error
from rapomdp.planning.cli import pomdp_app

if TYPE_CHECKING:
    from rapomdp.config import Config
    from rapomdp.study.report import StudyReport
    from rapomdp.study.spec import StudySpec
    from rapomdp.workspace import StageResult, Workspace

# Stage code (torch, the robot, rendering) is imported inside the commands that run it, so
# `rapomdp pomdp ...` and `--help` start without it.

app = typer.Typer(
    help=(
        "Active object recognition on depth images with recognition self-awareness (RA-POMDP).\n\n"
        "Every stage writes its artefacts into a workspace folder and is skipped when its "
        "configuration and inputs are unchanged. `rapomdp run` runs them all; `rapomdp STAGE` "
        "runs one stage and the stages it needs."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="markdown",  # docstrings are markdown: wrapped lines join, `code` shows
)
dataset_app = typer.Typer(
    help="Build the dataset stage (normalised meshes and split), or preview it.",
    invoke_without_command=True,
    rich_markup_mode="markdown",
)
app.add_typer(dataset_app, name="dataset")
app.add_typer(pomdp_app, name="pomdp")


def _print_version(value: bool) -> None:
    if value:
        from rapomdp import __version__

        sys.stdout.write(f"rapomdp {__version__}\n")
        raise typer.Exit()


@app.callback()
def _main(version: Annotated[bool, typer.Option(
        "--version", callback=_print_version, is_eager=True,
        help="Print the version and exit.")] = False) -> None:
    """Active object recognition on depth images with recognition self-awareness."""

console = Console(stderr=True)


def _user_errors() -> tuple[type[Exception], ...]:
    """The errors that are the user's to fix (imported when one is being handled)."""
    from rapomdp.config import ConfigError
    from rapomdp.data.layouts import DatasetLayoutError
    from rapomdp.data.meshes import MeshLoadError
    from rapomdp.data.splits import TooFewModelsError
    from rapomdp.parallel import WorkerError
    from rapomdp.recognition.classifier import CheckpointError
    from rapomdp.workspace import StageError

    return (ConfigError, StageError, MeshLoadError, DatasetLayoutError, TooFewModelsError,
            ArtefactError, CheckpointError, WorkerError)


T = TypeVar("T")

ConfigOption = Annotated[
    Path | None,
    typer.Option("--config", "-c", help="YAML configuration of a new workspace, or a new one "
                 "for this workspace (with --reconfigure). Default: the workspace's "
                 "config.yaml, else the embedded default."),
]
ReconfigureOption = Annotated[
    bool,
    typer.Option("--reconfigure", help="Accept a -c file that changes the configuration the "
                 "workspace's artefacts were made with (the stages it invalidates are redone)."),
]
OverridesArgument = Annotated[
    list[str] | None,
    typer.Argument(metavar="[KEY=VALUE]...", show_default=False,
                   help="Overrides of the configuration, e.g. train.epochs=5 "
                        "dataset.classes=[cup,mug] (YAML values, validated like the file)."),
]


def _workspace_path(text: str) -> Path:
    """The ``--workspace`` folder; an empty one (an unset shell variable?) is refused rather
    than taken for the current folder."""
    if not text.strip():
        raise _fail("--workspace is empty; give the workspace folder (-w . for the current "
                    "folder)")
    return Path(text)


WorkspaceOption = Annotated[
    Path, typer.Option("--workspace", "-w", parser=_workspace_path, metavar="DIR",
                       help="Workspace folder for the artefacts (a new or empty folder "
                            "becomes one).")
]
SchedulerOption = Annotated[
    str | None,
    typer.Option(help="A dask.distributed scheduler (tcp://host:port) for the independent "
                      "tasks (saliency, solve, evaluate); default: parallel.scheduler of the "
                      "configuration, else the local process pool. Same results either way."),
]
ForceOption = Annotated[bool, typer.Option("--force", "-f", help="Redo the stage even if cached.")]


def _fail(message: str) -> typer.Exit:
    """Print one error line (markup in the message shown as is); the exit to raise."""
    console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    return typer.Exit(2)


def _guard(action: Callable[[], T]) -> T:
    """Run ``action``; a user error prints one clear message and exits with status 2."""
    try:
        return action()
    except KeyboardInterrupt:  # first: the next clause imports, maybe a half-imported torch
        raise
    except _user_errors() as exc:
        raise _fail(str(exc)) from None
    except OSError as exc:  # a read-only folder, a full disk: the file and the cause
        raise _fail(f"{describe_os_error(exc)}; the earlier artefacts are intact") from None
    except KeyError as exc:
        raise _fail(str(exc.args[0])) from None
    except MemoryError:
        raise _fail("out of memory: a setting asks for more than this machine has (smaller "
                    "camera, fewer views or viewpoints?); the earlier artefacts are intact"
                    ) from None


def _require_existing(workspace: Path) -> None:
    """Exit 2 with a clear message when a command that only reads a workspace is given a
    folder that does not exist (a mistyped path), instead of reporting it empty."""
    if not Path(workspace).is_dir():
        raise _fail(f"workspace {workspace} does not exist (or is not a folder); "
                    f"`rapomdp run -w {workspace}` makes one")


def _report(result: StageResult, workspace: Workspace | None = None) -> None:
    state = "cached" if result.cached else f"done in {result.seconds:.1f} s"
    if result.shared_from is not None:
        state = f"shared from {Path(result.shared_from).name}"
    console.print(f"[green]✓[/] {result.name:<10} {state}  ({len(result.files)} files)")
    if result.name == "dataset" and not result.cached and workspace is not None:
        from rapomdp.data.dataset import role_count_lines, split_line, warning_lines

        folder = workspace.stage_dir("dataset")
        for line in [split_line(folder), *role_count_lines(folder)]:
            console.print(f"  {escape(line)}", highlight=False, soft_wrap=True)
        for line in warning_lines(folder):
            console.print(f"[yellow]warning:[/] {escape(line)}", highlight=False,
                          soft_wrap=True)


def _note(message: str) -> None:
    """Print one ``note:`` line (markup in the message shown as is)."""
    console.print(f"note: {escape(message)}", highlight=False, soft_wrap=True)


def _resolve(config_path: Path | None, workspace: Path, overrides: list[str] | None,
             reconfigure: bool) -> Config:
    """The workspace's configuration for this command (see :func:`resolve_config`); the
    recorded stages it will redo are listed first."""
    from rapomdp.pipeline import format_staleness, resolve_config
    from rapomdp.workspace import Workspace

    config, stale = resolve_config(Workspace(workspace), config_path, overrides or (),
                                   reconfigure, on_note=_note)
    if stale:
        console.print(f"[yellow]configuration changed[/]: {len(stale)} recorded stage(s) "
                      f"differ:\n{escape(format_staleness(stale))}", highlight=False,
                      soft_wrap=True)
    return config


def _run(config_path: Path | None, workspace: Path, until: str | None,
         force: list[str], context: RunContext | None = None,
         overrides: list[str] | None = None, reconfigure: bool = False) -> None:
    def action() -> None:
        from rapomdp.pipeline import run_pipeline
        from rapomdp.workspace import Workspace

        config = _resolve(config_path, workspace, overrides, reconfigure)
        run_context = context or RunContext()
        if run_context.scheduler is None and config.parallel.scheduler is not None:
            run_context = replace(run_context, scheduler=config.parallel.scheduler)
        if run_context.scheduler is not None:  # before any stage runs
            from rapomdp.parallel import check_scheduler

            check_scheduler(run_context.scheduler)
        ws = Workspace(workspace)
        run_pipeline(config, ws, until=until, force=force,
                     on_result=lambda result: _report(result, ws), context=run_context)
        recorded = ws.recorded_config()
        if recorded is not None and recorded != config:
            console.print(f"note: {ws.config_path} is unchanged: this command made no artefact "
                          "with the new values (run a stage they change to keep them)",
                          highlight=False, soft_wrap=True)

    _guard(action)


@app.command()
def run(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    force: Annotated[bool, typer.Option(
        "--force", "-f", help="Redo every stage it runs even if cached (as --force on a "
                              "stage's command redoes that stage).")] = False,
    redo: Annotated[
        list[str] | None,
        typer.Option("--redo", help="Redo this stage (by name, as `rapomdp status` lists "
                     "them) even if cached; repeatable."),
    ] = None,
    until: Annotated[
        str | None, typer.Option(help="Stop after this stage (and the stages it needs).")
    ] = None,
    workers: WorkersOption = None,
    reconfigure: ReconfigureOption = False,
    scheduler: SchedulerOption = None,
    overrides: OverridesArgument = None,
    threads: ThreadsOption = None,
) -> None:
    """Run every stage in order, skipping those whose inputs are unchanged; prints Table 1.

    The workspace keeps its configuration (W/config.yaml): `rapomdp run -w W` reruns what
    changed, `rapomdp run -w W train.epochs=5` changes one value.
    """
    if force:
        from rapomdp.pipeline import STAGE_NAMES as every_stage
    _run_and_summarise(config, workspace, until,
                       list(every_stage) if force else list(redo or []),
                       _context(threads, workers, scheduler), overrides, reconfigure)


def _run_and_summarise(config_path: Path | None, workspace: Path, until: str | None,
                       force: list[str], context: RunContext,
                       overrides: list[str] | None = None, reconfigure: bool = False,
                       began: float | None = None) -> None:
    """:func:`_run`, then Table 1 and the end-of-run summary (:func:`run_summary_lines`)."""
    began = time.perf_counter() if began is None else began
    _run(config_path, workspace, until, force, context, overrides, reconfigure)
    if until is None:
        _print_table1(workspace)
    lines = _guard(lambda: run_summary_lines(workspace, time.perf_counter() - began,
                                             peak_memory_gb(), until is None))
    for line in lines:
        console.print(escape(line), highlight=False)


def peak_memory_gb() -> tuple[float, float]:
    """The peak resident memory so far of this process and of its largest finished child
    process (a stage's worker), in GB (``resource.getrusage``; 0 where it cannot tell)."""
    try:
        import resource
    except ImportError:  # not a POSIX system
        return 0.0, 0.0
    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, else KiB
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return own * scale / 1e9, children * scale / 1e9


def _memory(gb: float) -> str:
    return f"{gb:.1f} GB" if gb >= 1 else f"{gb * 1000:.0f} MB"


def run_summary_lines(workspace: Path, seconds: float, peak_gb: tuple[float, float],
                      whole: bool = True) -> list[str]:
    """The lines that end a run: the report's path, the generated sentences of who won (the
    report's own story, ``metrics.table1_story``, from the same episodes and seed) and the
    paired differences with their 95 % intervals, when the run went to the end (``whole``)
    and made them; then the wall time and the peak memory (this process, its largest worker
    process)."""
    from rapomdp.workspace import Workspace

    lines = []
    root = Path(workspace)
    report_html = root / "report" / "report.html"
    if whole and report_html.is_file():
        lines.append(f"report: {report_html}")
        lines += _story(Workspace(root))
    own, worker = peak_gb
    memory = f"peak memory {_memory(own)}" + (
        f" (its largest worker process {_memory(worker)})" if worker > 0 else "")
    lines.append(f"wall time {_duration(seconds)}, {memory}")
    return lines


def _story(ws: Workspace) -> list[str]:
    """What Table 1 says, as the report says it (who won, which paired differences exclude 0),
    each paired difference with its interval, and the held-out comparison's sentence."""
    from rapomdp.config import METHOD_NAMES, Config
    from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
    from rapomdp.experiment.held_out import load_held_out_comparison
    from rapomdp.experiment.metrics import table1_story
    from rapomdp.experiment.report import evaluation_summaries, held_out_comparison_story

    folder = ws.stage_dir("evaluate")
    if not (folder / EPISODES_FILE).is_file():
        return []
    rows, paired, points, _ = evaluation_summaries(EpisodeTable.load(folder / EPISODES_FILE),
                                                   folder, ws.config(default=Config()).seed)
    lines = [table1_story(rows, paired, points)]
    if paired:
        reference = next(iter(paired.values())).reference
        lines.append(f"accuracy minus {METHOD_NAMES.get(reference, reference)}'s over the same "
                     "pairs [95 % interval]: " + "; ".join(
                         f"{METHOD_NAMES.get(m, m)} {p.difference:+.3f} "
                         f"[{p.low:+.3f}, {p.high:+.3f}]" for m, p in paired.items()))
    held_out = load_held_out_comparison(folder)
    if held_out is not None and held_out["methods"]:
        lines.append("held out, the forecast made before any test model was read: "
                     + held_out_comparison_story(held_out))
    return lines


@app.command()
def demo(
    workspace: Annotated[Path, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help="Workspace folder of the demo.")] = Path("runs/demo"),
    threads: ThreadsOption = None,
    workers: WorkersOption = None,
) -> None:
    """Run the demo: the dataset, its contact sheet, then every stage (what `make demo` runs).

    On the embedded procedural dataset with the default configuration (a workspace that has
    its own configuration keeps it). Writes W/contact_sheet.png and W/report/report.html, and
    ends like `rapomdp run`: Table 1, the report's path, who won, the wall time and memory.
    A second run finds every stage cached.
    """
    began = time.perf_counter()
    context = _context(threads, workers)
    _run(None, workspace, "dataset", [], context)
    _write_preview(workspace, None)
    _run_and_summarise(None, workspace, None, [], context, began=began)


@dataset_app.callback()
def dataset(
    ctx: typer.Context,
    workspace: Annotated[Path | None, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR")] = None,
    config: ConfigOption = None,
    force: ForceOption = False,
    reconfigure: ReconfigureOption = False,
) -> None:
    """Build the dataset stage: load or generate meshes, normalise them, split each class."""
    if ctx.invoked_subcommand is not None:
        return
    if workspace is None:
        console.print("[bold red]error:[/] --workspace is required")
        raise typer.Exit(2)
    _run(config, workspace, "dataset", ["dataset"] if force else [], None, None, reconfigure)


def _dataset_build_help() -> str:
    from rapomdp.data.build import describe

    return ("Write a dataset's mesh folder (one folder a class, one mesh file a model) for "
            "`dataset: {source: folder}`. Never from a held-back source (sweethome3d*: refused "
            "by name).\n\n"
            + describe())


@dataset_app.command("build", help=_dataset_build_help())
def dataset_build(
    name: Annotated[str, typer.Argument(help="real-cad or mesh-set.", metavar="NAME")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The mesh folder to (re)build; "
                                      "replaced whole when done.", metavar="FOLDER")],
    which: Annotated[str | None, typer.Option("--set", help="real-cad: first (default) or "
                                              "second.")] = None,
    cache: Annotated[Path | None, typer.Option(help="real-cad: where the .deb and its "
                                               "extraction are kept (default "
                                               "runs/real-cad-dev/cache).")] = None,
    deb: Annotated[Path | None, typer.Option(help="real-cad: a downloaded .deb of "
                                             "kicad-packages3d (no apt-get).")] = None,
    source: Annotated[Path | None, typer.Option(help="real-cad: the package already "
                                                "unpacked (no apt-get, no dpkg-deb).")] = None,
    max_per_class: Annotated[int | None, typer.Option(help="real-cad: models kept a class, "
                                                      "0 for all (default 16).")] = None,
    models: Annotated[int | None, typer.Option(help="mesh-set: models a class (default "
                                               "11).")] = None,
    seed: Annotated[int | None, typer.Option(help="mesh-set: the set's seed (default 7).")
                    ] = None,
) -> None:
    from rapomdp.data.build import DatasetBuildError, build

    console.print(f"building {escape(name)} into {escape(str(out))} ...", highlight=False)
    try:
        text = _guard(partial(build, name, out, which=which, cache=cache, deb=deb,
                              source=source, max_per_class=max_per_class,
                              models_per_class=models, seed=seed))
    except DatasetBuildError as exc:
        raise _fail(str(exc)) from None
    console.print(escape(text), highlight=False, soft_wrap=True)


#: The tile widths `dataset preview --width` accepts, in pixels.
MIN_TILE_PX, MAX_TILE_PX = 8, 2048


@dataset_app.command("preview")
def dataset_preview(
    workspace: WorkspaceOption,
    out: Annotated[
        Path | None, typer.Option(help="PNG path (default W/contact_sheet.png).")
    ] = None,
    width: Annotated[int, typer.Option(help="Tile width in pixels (4:3 tiles).")] = 320,
    elevation_deg: Annotated[float, typer.Option(help="Camera elevation above the floor.")] = 30.0,
) -> None:
    """Write a labelled contact sheet: one depth render per model of the workspace's dataset."""
    if not MIN_TILE_PX <= width <= MAX_TILE_PX:
        raise _fail(f"--width must be {MIN_TILE_PX} to {MAX_TILE_PX} pixels, got {width}")
    if not (math.isfinite(elevation_deg) and -90.0 <= elevation_deg <= 90.0):
        raise _fail(f"--elevation-deg must be a finite angle in [-90, 90], got {elevation_deg}")
    _require_existing(workspace)
    _write_preview(workspace, out, width, elevation_deg)


def _write_preview(workspace: Path, out: Path | None, width: int = 320,
                   elevation_deg: float = 30.0) -> None:
    """The contact sheet of the workspace's dataset (``dataset preview``)."""
    if out is not None:
        _guard(partial(check_output_path, out))

    def action() -> Path:
        from rapomdp.data.dataset import load_dataset
        from rapomdp.data.preview import contact_sheet
        from rapomdp.geometry.camera import xtion_intrinsics
        from rapomdp.workspace import Workspace

        ws = Workspace(workspace)
        dataset = load_dataset(ws.require("dataset"))
        target = out or ws.root / "contact_sheet.png"
        height = max(8, round(width * 3 / 4))
        return contact_sheet(dataset, xtion_intrinsics(width, height), target,
                             elevation_deg=elevation_deg)

    path = _guard(action)
    console.print(f"[green]✓[/] contact sheet written to {escape(str(path))}")


@app.command()
def render(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False, reconfigure: ReconfigureOption = False,
           overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """Render every model's depth images over the training viewsphere (and build the dataset)."""
    _run(config, workspace, "render", ["render"] if force else [], _context(workers=workers),
         overrides, reconfigure)


@app.command()
def xrho(workspace: WorkspaceOption, config: ConfigOption = None,
         force: ForceOption = False, reconfigure: ReconfigureOption = False,
         overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """Render the volume and test models at X_rho once, for every stage that reads them."""
    _run(config, workspace, "xrho", ["xrho"] if force else [], _context(workers=workers),
         overrides, reconfigure)


ThreadsOption = Annotated[
    int | None,
    typer.Option(help="CPU threads for PyTorch (default: $RAPOMDP_THREADS, else half the cores)."),
]


def _context(threads: int | None = None, workers: int | None = None,
             scheduler: str | None = None) -> RunContext:
    """The run context of the CLI's ``--threads``, ``--workers`` and ``--scheduler`` (progress
    bars on; without ``--scheduler``, the configuration's ``parallel.scheduler`` applies)."""
    for name, value in (("workers", workers), ("threads", threads)):
        if value is not None and value < 1:
            raise _fail(f"--{name} must be at least 1, got {value}")
    return RunContext(workers=workers, threads=threads, scheduler=scheduler)


@app.command()
def train(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
          reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
          threads: ThreadsOption = None, workers: WorkersOption = None) -> None:
    """Train the depth classifier on the training renders (and build what it needs); an
    ensemble (train.ensemble > 1) trains a share of its members per worker process."""
    _run(config, workspace, "train", ["train"] if force else [], _context(threads, workers),
         overrides, reconfigure)


@app.command("classifier_eval")
@app.command("evaluate-classifier", hidden=True)  # its former name, kept as an alias
def classifier_eval(workspace: WorkspaceOption, config: ConfigOption = None,
                    force: ForceOption = False, reconfigure: ReconfigureOption = False,
                    overrides: OverridesArgument = None,
                    threads: ThreadsOption = None, workers: WorkersOption = None) -> None:
    """Single-view accuracy on the test models: per class, confusion, per viewpoint."""
    _run(config, workspace, "classifier_eval", ["classifier_eval"] if force else [],
         _context(threads, workers), overrides, reconfigure)
    from rapomdp.recognition.artefacts import load_single_view_metrics
    from rapomdp.workspace import Workspace

    metrics = _guard(lambda: load_single_view_metrics(
        Workspace(workspace).require("classifier_eval")))
    for part, label in ((metrics.xrho, "test viewpoints X_rho"), (metrics.sphere, "whole sphere")):
        console.print(f"  single-view accuracy, {label}: {part.accuracy:.1%} "
                      f"(chance {part.chance:.1%})", highlight=False)


@app.command()
def saliency(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
             reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
             threads: ThreadsOption = None, scheduler: SchedulerOption = None) -> None:
    """2D saliency maps of each class's volume model (method: config saliency.method)."""
    _run(config, workspace, "saliency", ["saliency"] if force else [],
         _context(threads, scheduler=scheduler), overrides, reconfigure)


@app.command()
def volume(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
           reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
           threads: ThreadsOption = None) -> None:
    """The 3D dense saliency volume of every class (and the stages it needs)."""
    _run(config, workspace, "volume", ["volume"] if force else [], _context(threads), overrides,
         reconfigure)


@app.command()
def crossfit(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
             reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
             threads: ThreadsOption = None) -> None:
    """Held-out evidence: k small classifiers label the training models they did not see."""
    _run(config, workspace, "crossfit", ["crossfit"] if force else [], _context(threads),
         overrides, reconfigure)


@app.command()
def observe(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
            reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
            threads: ThreadsOption = None) -> None:
    """Observation models P(o | class, viewpoint) and the self-awareness quality table."""
    _run(config, workspace, "observe", ["observe"] if force else [], _context(threads),
         overrides, reconfigure)
    from rapomdp.awareness.artefacts import QUALITY_MD

    table = Path(workspace) / "observe" / QUALITY_MD
    if table.exists():
        sys.stdout.write(table.read_text())


@app.command()
def vptree(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False, reconfigure: ReconfigureOption = False,
           overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """The VP-tree baseline: vocabulary-tree classifier and its per-viewpoint confusion."""
    _run(config, workspace, "vptree", ["vptree"] if force else [], _context(workers=workers),
         overrides, reconfigure)
    from rapomdp.recognition.artefacts import load_vptree_summary
    from rapomdp.workspace import Workspace

    data = _guard(lambda: load_vptree_summary(Workspace(workspace).require("vptree")))
    test = data.accuracy_test_xrho
    shown = "n/a (no test models)" if test is None else f"{test:.1%}"
    console.print(f"  VP-tree single-view accuracy, test models at X_rho: {shown} "
                  f"(volume models {data.accuracy_volume_xrho:.1%}, chance "
                  f"{data.chance:.1%})", highlight=False)
    if data.temperature is not None:
        console.print(f"  its belief's likelihood temperature (held out): "
                      f"{data.temperature:.3f}", highlight=False)


FIG2_TARGET = "bicycle"
FIG2_AGAINST = ("teapot", "eyeglasses", "motorbike")
figure_app = typer.Typer(help="Figures of recognition self-awareness (paper Figs. 1 and 2).",
                         rich_markup_mode="markdown")
app.add_typer(figure_app, name="figure")


@figure_app.command("fig1")
def figure_fig1(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    class_name: Annotated[str | None, typer.Option("--class", help="Class (default: first).")]
    = None,
    view: Annotated[int | None, typer.Option(
        help="The volume model's training view shown in (a)-(c) (default: the one nearest the "
             "test viewpoint of highest score; where every score is equal, the one with the "
             "most object pixels).")] = None,
    threads: ThreadsOption = None,
    reconfigure: ReconfigureOption = False,
    overrides: OverridesArgument = None,
) -> None:
    """Fig. 1: depth, 2D saliency, 3D volume and viewpoint scores of one class (PNG + HTML)."""
    _run(config, workspace, "observe", [], _context(threads), overrides, reconfigure)

    def action() -> tuple[Path, Path]:
        from rapomdp.awareness.report import write_fig1
        from rapomdp.workspace import Workspace

        return write_fig1(Workspace(workspace), class_name, view)

    png, html = _guard(action)
    console.print(f"[green]✓[/] Fig. 1 written to {png} and {html}")


@figure_app.command("fig2")
def figure_fig2(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    target: Annotated[str, typer.Option(help="The class whose volume is shown.")] = FIG2_TARGET,
    against: Annotated[str, typer.Option(help="Comma-separated opponents, one two-class "
                                               "problem each.")] = ",".join(FIG2_AGAINST),
    epochs: Annotated[int | None, typer.Option(help="Training epochs of the two-class "
                                                    "classifiers (default: the config's).")]
    = None,
    threads: ThreadsOption = None,
    reconfigure: ReconfigureOption = False,
    overrides: OverridesArgument = None,
) -> None:
    """Fig. 2: the target's volume in two-class problems and in the all-class problem.

    Each two-class problem trains its own classifier in `W/fig2/TARGET-vs-OTHER`.
    """
    def action() -> tuple[Path, Path]:
        from rapomdp.pipeline import write_fig2
        from rapomdp.workspace import Workspace

        opponents = [a.strip() for a in against.split(",") if a.strip()]
        for name in (target, *opponents):  # they name folders W/fig2/<target>-vs-<other>
            check_plain_name(name, "class", "fig2")
        resolved = _resolve(config, workspace, overrides, reconfigure)
        with Workspace(workspace).locked():
            return write_fig2(resolved, Workspace(workspace), target, opponents, epochs,
                              on_result=_report, context=_context(threads))

    png, html = _guard(action)
    console.print(f"[green]✓[/] Fig. 2 written to {png} and {html}")


@app.command()
def robot(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False, reconfigure: ReconfigureOption = False,
          overrides: OverridesArgument = None) -> None:
    """Solve the Panda's IK at every test viewpoint: reachability, manipulability, energy."""
    _run(config, workspace, "robot", ["robot"] if force else [], None, overrides, reconfigure)

    def summary() -> str:
        from rapomdp.robot.artefacts import describe, load_robot_summary
        from rapomdp.workspace import Workspace

        return describe(load_robot_summary(Workspace(workspace).require("robot")))

    console.print(f"  {_guard(summary)}", highlight=False, soft_wrap=True)


@app.command()
def solve(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False, reconfigure: ReconfigureOption = False,
          overrides: OverridesArgument = None, scheduler: SchedulerOption = None) -> None:
    """Solve one active-recognition POMDP per observation model (policies as .npz)."""
    _run(config, workspace, "solve", ["solve"] if force else [], _context(scheduler=scheduler),
         overrides, reconfigure)

    def summary() -> dict:
        from rapomdp.planning.artefacts import load_solve_summary
        from rapomdp.workspace import Workspace

        return load_solve_summary(Workspace(workspace).require("solve"))

    for name, bounds in _guard(summary).items():
        console.print(
            f"  {name:<11} value in [{bounds['lower']:.4f}, {bounds['upper']:.4f}] after "
            f"{bounds['seconds']:.1f} s of CPU time, {bounds['vectors']} vectors"
            + (f"; {bounds['note']}" if bounds.get("note") else ""), highlight=False)


@app.command()
def learn(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
          reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
          workers: WorkersOption = None) -> None:
    """The learned baseline: MaskablePPO policies trained on the held-out models' recorded
    evidence, one per λ (only when evaluate.methods lists 'learned': configs/learned.yaml)."""
    _run(config, workspace, "learn", ["learn"] if force else [], _context(workers=workers),
         overrides, reconfigure)

    def summary() -> dict:
        from rapomdp.experiment.learn_stage import load_learn_summary
        from rapomdp.workspace import Workspace

        return load_learn_summary(Workspace(workspace).require("learn"))

    data = _guard(summary)
    if not data.get("trained"):
        console.print(f"  nothing trained: {data.get('reason', '')}", highlight=False)
    for row in data.get("held_out", []):
        console.print(f"  held out, {row['method']} at {row['parameter']} {row['value']:g}: "
                      f"accuracy {row['accuracy']:.3f}, energy {row['mean_energy']:.3f} m",
                      highlight=False)


WorkersOption = Annotated[
    int | None,
    typer.Option(help="Processes for the stages that spread tasks (render, train's ensemble "
                      "members, classifier_eval, vptree, saliency, solve, learn, evaluate; "
                      "default: 2, or 1 on a single core); the results do not depend on it."),
]


def _print_table1(workspace: Path) -> None:
    """Table 1 (``W/evaluate/table1.md``) on the console, as a table that fits its width, and
    the notes under it."""
    from rapomdp.experiment.episode_table import TABLE1_MD

    path = Path(workspace) / "evaluate" / TABLE1_MD
    if not path.exists():
        return
    lines = path.read_text(encoding="utf-8").splitlines()
    cells = [[escape(c.strip()) for c in line.strip().strip("|").split("|")]
             for line in lines if line.startswith("|") and not set(line) <= set("|-: ")]
    out = Console()
    if cells:
        table = Table(title="Table 1 (closed-loop episodes on the test models)",
                      title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
        for name in cells[0]:  # a header's interval or unit on a line of its own
            table.add_column(name.replace(" [", "\n[").replace(" (", "\n("))
        for row in cells[1:]:
            table.add_row(*row)
        wide = Measurement.get(out, out.options.update_width(10**6), table).maximum <= out.width
        for column in table.columns[:-1]:  # the cells whole where the table fits
            column.no_wrap = wide
        out.print(table)
    for line in lines:
        if line.strip() and not line.startswith("|"):
            out.print(escape(line), highlight=False)


@app.command()
def evaluate(workspace: WorkspaceOption, config: ConfigOption = None,
             force: ForceOption = False, reconfigure: ReconfigureOption = False,
             overrides: OverridesArgument = None, threads: ThreadsOption = None,
             workers: WorkersOption = None, scheduler: SchedulerOption = None) -> None:
    """Closed-loop episodes of every method on every test model (paper Sec. 5.2).

    Each test model starts from evaluate.starts_per_model seeded reachable viewpoints; every
    method (evaluate.methods) runs one episode from each. Prints Table 1 and writes
    W/evaluate/: table1.md|csv, per_class.md|csv, episodes.npz|csv, fig3.png, trajectories.png.
    """
    _run(config, workspace, "evaluate", ["evaluate"] if force else [],
         _context(threads, workers, scheduler), overrides, reconfigure)
    _print_table1(workspace)


@app.command()
def report(workspace: WorkspaceOption, config: ConfigOption = None,
           threads: ThreadsOption = None,
           fig2: Annotated[bool, typer.Option(
               "--fig2", help="Make Fig. 2 first, as `rapomdp figure fig2` with its defaults "
                              "(trains three two-class classifiers: minutes).")] = False,
           workers: WorkersOption = None, reconfigure: ReconfigureOption = False,
           overrides: OverridesArgument = None,
           readme: Annotated[Path | None, typer.Option(
               "--readme", help="Also replace the generated-results block of this README "
                                "with the workspace's numbers and figures.")] = None,
           readme_figures: Annotated[Path | None, typer.Option(
               "--readme-figures", help="Where --readme copies its figures (default: "
                                        "docs/figures beside the README).")] = None) -> None:
    """Write W/report/report.html and report.md (and their figures) from the stages' results.

    The report is always rebuilt (it is cheap): it also shows optional artefacts that are not
    among its inputs (Fig. 2 from `rapomdp figure fig2` or --fig2). With --readme the README's
    results block is generated from the same workspace (`make readme` does it for the demo).
    """
    context = _context(threads, workers)
    if readme is not None:  # refused before the stages run
        _guard(partial(check_output_path, readme))
    if fig2:
        def make_fig2() -> tuple[Path, Path]:
            from rapomdp.pipeline import write_fig2
            from rapomdp.workspace import Workspace

            resolved = _resolve(config, workspace, overrides, reconfigure)
            with Workspace(workspace).locked():
                return write_fig2(resolved, Workspace(workspace), FIG2_TARGET,
                                  list(FIG2_AGAINST), None, on_result=_report, context=context)

        _guard(make_fig2)
    _run(config, workspace, "report", ["report"], context, overrides, reconfigure)
    folder = Path(workspace) / "report"
    for name in ("report.html", "report.md"):
        sys.stdout.write(f"{folder / name}\n")
    if readme is not None:
        def write_readme() -> Path:
            from rapomdp.experiment.readme import update_readme
            from rapomdp.workspace import Workspace

            return update_readme(Workspace(workspace), readme, readme_figures)

        sys.stdout.write(f"{_guard(write_readme)}\n")


@app.command()
def study(
    folder: Annotated[Path, typer.Option(
        "--study", "-s", help="Study folder: one workspace per configuration and seed "
                              "(`S/CONFIGURATION/seed-N`), the report in `S/report`.")],
    config: Annotated[list[Path] | None, typer.Option(
        "--config", "-c", help="A configuration (dataset) of a new study; repeatable, each "
                               "named by its file's stem. Default: the study's study.yaml, "
                               "else the embedded default.")] = None,
    seeds: Annotated[int | None, typer.Option(
        min=1, help="How many seeds (default 3, or the study's own): first-seed, "
                    "first-seed + 1, ...")] = None,
    first_seed: Annotated[int, typer.Option(min=0, help="The first seed.")] = 0,
    vary: Annotated[str | None, typer.Option(
        help="What a seed changes: 'all' (the run seed: split, models, classifier, starts) "
             "or 'train' (the classifier's own seed: the same models and starts). "
             "Default: all, or the study's own.")] = None,
    reconfigure: Annotated[bool, typer.Option(
        "--reconfigure", help="Accept configurations or seeds that differ from the study's "
                              "study.yaml (changed seeds' stages are redone).")] = False,
    report_only: Annotated[bool, typer.Option(
        "--report-only", help="Only rewrite the report from the finished seeds.")] = False,
    readme: Annotated[Path | None, typer.Option(
        "--readme", help="Also replace this README's generated study block with the "
                         "study's pooled results.")] = None,
    workers: WorkersOption = None,
    threads: ThreadsOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Run the pipeline over seeds and configurations, then write the pooled report.

    Each seed is a normal cached, resumable workspace; stages whose key another seed or
    configuration already holds are shared (hard links), so `--vary train` trains only the
    classifiers again, and configurations that differ from the train stage on share what
    comes before it. The
    report pools Table 1 over seeds with intervals that resample seeds and test models. With
    --scheduler each seed is one Dask task.
    """
    context = _context(threads, workers, scheduler)

    def resolve() -> StudySpec:
        from rapomdp.config import ConfigError
        from rapomdp.study.spec import StudyDataset, StudySpec, read_study

        recorded = read_study(folder)
        base = recorded or StudySpec()
        given = StudySpec(
            tuple(StudyDataset.from_file(c) for c in config) if config else base.datasets,
            tuple(range(first_seed, first_seed + seeds)) if seeds is not None else base.seeds,
            vary or base.vary)
        if recorded is not None and given != recorded and not reconfigure:
            raise ConfigError(
                f"{folder}: the study was made with seeds {list(recorded.seeds)}, vary "
                f"{recorded.vary} and configurations "
                f"{', '.join(d.name for d in recorded.datasets)}; pass --reconfigure to change "
                "them, or use another study folder")
        return given

    def action() -> StudyReport:
        from rapomdp.study.report import update_study_readme, write_study_report
        from rapomdp.study.runner import run_study

        spec = resolve()
        if not report_only:
            def show(dataset: str, seed: int, result: StageResult) -> None:
                console.print(f"[dim]{dataset} seed {seed}[/]", end=" ", highlight=False)
                _report(result)

            run_study(spec, folder, context, on_result=show)
        written = write_study_report(spec, folder)
        if readme is not None:
            sys.stdout.write(f"{update_study_readme(spec, folder, readme)}\n")
        return written

    written = _guard(action)
    for story in written.stories.values():
        console.print(story, highlight=False)
    sys.stdout.write(f"{written.html}\n{written.markdown}\n")


@app.command("config")
def show_config(
    config: ConfigOption = None,
    workspace: Annotated[Path | None, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help="Show this workspace's configuration.")] = None,
    overrides: OverridesArgument = None,
    plain: Annotated[bool, typer.Option(
        "--plain", help="Without the comments (descriptions, units).")] = False,
) -> None:
    """Print the resolved configuration as YAML: the file's, else the workspace's, else the
    default, with any KEY=VALUE overrides, each section and key with a short comment and its
    unit; nothing is written."""
    if workspace is not None and workspace.exists() and not workspace.is_dir():
        raise _fail(f"workspace {workspace} is a file, not a folder")

    def action() -> Config:
        from rapomdp.config import apply_overrides, config_from_dict, read_config_data
        from rapomdp.pipeline import resolve_config
        from rapomdp.workspace import Workspace

        if workspace is None:
            data = read_config_data(config) if config is not None else {}
            source = str(config) if config is not None else "the default configuration"
            if overrides:
                source += f" with {' '.join(o[:60] for o in overrides)}"
            return config_from_dict(apply_overrides(data, overrides or ()), source)
        return resolve_config(Workspace(workspace), config, overrides or (), True,
                              on_note=_note)[0]

    resolved = _guard(action)
    sys.stdout.write(resolved.to_yaml() if plain else resolved.to_commented_yaml())


def _duration(seconds: float) -> str:
    """A duration as a person reads it: ``0.4 s``, ``12 s``, ``3 min 05 s``, ``1 h 02 min``."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    whole = round(seconds)
    if whole < 60:
        return f"{whole} s"
    if whole < 3600:
        return f"{whole // 60} min {whole % 60:02d} s"
    return f"{whole // 3600} h {whole % 3600 // 60:02d} min"


def _finished(recorded: str | None) -> str:
    """A record's ``finished`` time to the minute (``2026-12-02 15:21``), as recorded."""
    if not recorded:
        return "-"
    return recorded[:16].replace("T", " ")


@app.command()
def status(
    workspace: WorkspaceOption,
    as_json: Annotated[bool, typer.Option(
        "--json", help="Print the status as JSON (one object: the workspace, whether its "
                       "config.yaml is missing, and per stage its state, reasons, files, key, "
                       "seconds and finish time as the manifest records them).")] = False,
) -> None:
    """Show which stages a workspace holds, when they ran, and which are stale and why.

    Staleness is judged against W/config.yaml, the stages' code and their input files; it reads
    the manifest and the input files' sizes and times, and loads no stage code.
    """
    from rapomdp.config import Config
    from rapomdp.pipeline import STAGES, format_staleness
    from rapomdp.workspace import Workspace

    _require_existing(workspace)

    def action() -> tuple[list, bool]:
        ws = Workspace(workspace)
        ws.check()  # a folder that is not a workspace is named, not shown as "not run"
        config = ws.recorded_config()
        rows = ws.status(STAGES, config if config is not None else Config())
        return rows, config is not None and not ws.config_path.exists()

    rows, rebuilt = _guard(action)
    if as_json:
        from dataclasses import asdict

        sys.stdout.write(json.dumps({"workspace": str(workspace), "config_missing": rebuilt,
                                     "stages": [asdict(r) for r in rows]}, indent=2) + "\n")
        return
    table = Table(title=escape(str(workspace)), title_justify="left")
    table.add_column("stage", no_wrap=True)
    table.add_column("state", no_wrap=True)
    table.add_column("files", justify="right", no_wrap=True)
    table.add_column("took", justify="right", no_wrap=True)
    table.add_column("finished", no_wrap=True)
    styles = {"current": "[green]current[/]", "stale": "[yellow]stale[/]", "not run": "not run"}
    for row in rows:
        state = styles[row.state] + (" (shared)" if row.shared_from else "")
        table.add_row(row.name, state, "-" if row.files is None else str(row.files),
                      "-" if row.seconds is None else _duration(row.seconds),
                      _finished(row.finished))
    Console().print(table)
    stale = {row.name: row.reasons for row in rows if row.state == "stale"}
    if rebuilt:
        _note(f"{Path(workspace) / 'config.yaml'} is missing; staleness is judged against "
              "the configuration the stage records hold")
    if stale:
        console.print(f"{len(stale)} stale stage(s), `rapomdp run -w {escape(str(workspace))}` "
                      f"redoes them:\n{escape(format_staleness(stale))}", highlight=False)


#: The exit status of a run stopped by Ctrl-C (128 + SIGINT), as typer gives it.
INTERRUPTED = 130


def main() -> None:
    """The console script: the app, then a quiet exit.

    roboticstoolbox's nanobind extension (spatialgeometry) reports the scene objects still alive
    at interpreter shutdown as dozens of "leaked instance" lines once PyTorch is loaded too:
    harmless, but they would bury Table 1. After a command that loaded it, everything is
    written (atomically) and flushed, so the process ends without the interpreter's teardown.
    """
    try:
        app()
        code = 0
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            code = exc.code or 0
        else:
            sys.stderr.write(f"{exc.code}\n")
            code = 1
    except KeyboardInterrupt:  # outside a command (typer handles it inside one)
        code = INTERRUPTED
    if code == INTERRUPTED:  # Ctrl-C: typer exits 130 with an empty line
        sys.stderr.write("error: interrupted\n")
    if "roboticstoolbox" in sys.modules:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    main()
