"""The ``rapomdp`` command line: the whole pipeline, or one stage, on a workspace folder."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, TypeVar

import typer
from rich.console import Console
from rich.table import Table

from rapomdp.config import Config, ConfigError, load_config
from rapomdp.data.layouts import DatasetLayoutError
from rapomdp.data.meshes import MeshLoadError
from rapomdp.data.splits import TooFewModelsError
from rapomdp.io import ArtefactError, atomic_path
from rapomdp.pipeline import STAGE_NAMES, STAGES, run_pipeline
from rapomdp.planning.cli import pomdp_app
from rapomdp.recognition.classifier import CheckpointError
from rapomdp.workspace import StageError, StageResult, Workspace

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
)
dataset_app = typer.Typer(
    help="Build the dataset stage (normalised meshes and split), or preview it.",
    invoke_without_command=True,
)
app.add_typer(dataset_app, name="dataset")
app.add_typer(pomdp_app, name="pomdp")

console = Console(stderr=True)
USER_ERRORS = (
    ConfigError,
    StageError,
    MeshLoadError,
    DatasetLayoutError,
    TooFewModelsError,
    ArtefactError,
    CheckpointError,
)
T = TypeVar("T")

ConfigOption = Annotated[
    Path | None,
    typer.Option("--config", "-c", help="YAML configuration (default: the embedded default)."),
]
WorkspaceOption = Annotated[
    Path, typer.Option("--workspace", "-w", help="Workspace folder for the artefacts.")
]
ForceOption = Annotated[bool, typer.Option("--force", help="Redo the stage even if cached.")]


def _guard(action: Callable[[], T]) -> T:
    """Run ``action``; a user error prints one clear message and exits with status 2."""
    try:
        return action()
    except USER_ERRORS as exc:
        console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        raise typer.Exit(2) from None
    except KeyError as exc:
        console.print(f"[bold red]error:[/] {exc.args[0]}", highlight=False, soft_wrap=True)
        raise typer.Exit(2) from None


def _report(result: StageResult, workspace: Workspace | None = None) -> None:
    state = "cached" if result.cached else f"done in {result.seconds:.1f} s"
    console.print(f"[green]✓[/] {result.name:<10} {state}  ({len(result.files)} files)")
    if result.name == "dataset" and not result.cached and workspace is not None:
        from rapomdp.data.dataset import role_count_lines

        for line in role_count_lines(workspace.stage_dir("dataset")):
            console.print(f"  {line}", highlight=False, soft_wrap=True)


def _save_config(config: Config, workspace: Workspace) -> None:
    workspace.root.mkdir(parents=True, exist_ok=True)
    with atomic_path(workspace.root / "config.yaml") as tmp:
        tmp.write_text(config.to_yaml())


def _run(config_path: Path | None, workspace: Path, until: str | None,
         force: list[str]) -> None:
    def action() -> None:
        config = load_config(config_path)
        ws = Workspace(workspace)
        _save_config(config, ws)
        run_pipeline(config, ws, until=until, force=force,
                     on_result=lambda result: _report(result, ws))

    _guard(action)


@app.command()
def run(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    force: Annotated[
        list[str] | None,
        typer.Option("--force", "-f", help=f"Redo a stage ({', '.join(STAGE_NAMES)}); repeatable."),
    ] = None,
    until: Annotated[
        str | None, typer.Option(help="Stop after this stage (and the stages it needs).")
    ] = None,
    workers: WorkersOption = None,
) -> None:
    """Run every stage in order, skipping those whose inputs are unchanged; prints Table 1."""
    _set_workers(workers)
    _run(config, workspace, until, list(force or []))
    if until is None:
        _print_table1(workspace)


@dataset_app.callback()
def dataset(
    ctx: typer.Context,
    workspace: Annotated[Path | None, typer.Option("--workspace", "-w")] = None,
    config: ConfigOption = None,
    force: ForceOption = False,
) -> None:
    """Build the dataset stage: load or generate meshes, normalise them, split each class."""
    if ctx.invoked_subcommand is not None:
        return
    if workspace is None:
        console.print("[bold red]error:[/] --workspace is required")
        raise typer.Exit(2)
    _run(config, workspace, "dataset", ["dataset"] if force else [])


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

    def action() -> Path:
        from rapomdp.data.dataset import load_dataset
        from rapomdp.data.preview import contact_sheet
        from rapomdp.geometry.camera import xtion_intrinsics

        ws = Workspace(workspace)
        dataset = load_dataset(ws.require("dataset"))
        target = out or ws.root / "contact_sheet.png"
        height = max(8, round(width * 3 / 4))
        return contact_sheet(dataset, xtion_intrinsics(width, height), target,
                             elevation_deg=elevation_deg)

    path = _guard(action)
    console.print(f"[green]✓[/] contact sheet written to {path}")


@app.command()
def render(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False) -> None:
    """Render every model's depth images over the training viewsphere (and build the dataset)."""
    _run(config, workspace, "render", ["render"] if force else [])


ThreadsOption = Annotated[
    int | None,
    typer.Option(help="CPU threads for PyTorch (default: $RAPOMDP_THREADS, else half the cores)."),
]


def _set_threads(threads: int | None) -> None:
    from rapomdp.recognition import stage

    stage.threads = threads


@app.command()
def train(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
          threads: ThreadsOption = None) -> None:
    """Train the depth classifier on the training renders (and build what it needs)."""
    _set_threads(threads)
    _run(config, workspace, "train", ["train"] if force else [])


@app.command("evaluate-classifier")
def evaluate_classifier(workspace: WorkspaceOption, config: ConfigOption = None,
                        force: ForceOption = False, threads: ThreadsOption = None) -> None:
    """Single-view accuracy on the test models: per class, confusion, per viewpoint."""
    _set_threads(threads)
    _run(config, workspace, "classifier_eval", ["classifier_eval"] if force else [])
    metrics = Path(workspace) / "classifier_eval" / "metrics.json"
    if metrics.exists():
        from rapomdp.io import read_json

        data = read_json(metrics)
        for key, label in (("xrho", "test viewpoints X_rho"), ("sphere", "whole sphere")):
            console.print(f"  single-view accuracy, {label}: {data[key]['accuracy']:.1%} "
                          f"(chance {data[key]['chance']:.1%})", highlight=False)


@app.command()
def saliency(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
             threads: ThreadsOption = None) -> None:
    """2D saliency maps of each class's volume model (method: config saliency.method)."""
    _set_threads(threads)
    _run(config, workspace, "saliency", ["saliency"] if force else [])


@app.command()
def volume(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
           threads: ThreadsOption = None) -> None:
    """The 3D dense saliency volume of every class (and the stages it needs)."""
    _set_threads(threads)
    _run(config, workspace, "volume", ["volume"] if force else [])


@app.command()
def crossfit(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
             threads: ThreadsOption = None) -> None:
    """Held-out evidence: k small classifiers label the training models they did not see."""
    _set_threads(threads)
    _run(config, workspace, "crossfit", ["crossfit"] if force else [])


@app.command()
def observe(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
            threads: ThreadsOption = None) -> None:
    """Observation models P(o | class, viewpoint) and the self-awareness quality table."""
    _set_threads(threads)
    _run(config, workspace, "observe", ["observe"] if force else [])
    table = Path(workspace) / "observe" / "quality.md"
    if table.exists():
        sys.stdout.write(table.read_text())


@app.command()
def vptree(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False) -> None:
    """The VP-tree baseline: vocabulary-tree classifier and its per-viewpoint confusion."""
    _run(config, workspace, "vptree", ["vptree"] if force else [])
    summary = Path(workspace) / "vptree" / "vptree.json"
    if summary.exists():
        from rapomdp.io import read_json

        data = read_json(summary)
        test = data["accuracy_test_xrho"]
        shown = "n/a (no test models)" if test is None else f"{test:.1%}"
        console.print(f"  VP-tree single-view accuracy, test models at X_rho: {shown} "
                      f"(volume models {data['accuracy_volume_xrho']:.1%}, chance "
                      f"{data['chance']:.1%})", highlight=False)


FIG2_TARGET = "bicycle"
FIG2_AGAINST = ("teapot", "eyeglasses", "motorbike")
figure_app = typer.Typer(help="Figures of recognition self-awareness (paper Figs. 1 and 2).")
app.add_typer(figure_app, name="figure")


@figure_app.command("fig1")
def figure_fig1(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    class_name: Annotated[str | None, typer.Option("--class", help="Class (default: first).")]
    = None,
    view: Annotated[int | None, typer.Option(help="Training view (default: most pixels).")]
    = None,
    threads: ThreadsOption = None,
) -> None:
    """Fig. 1: depth, 2D saliency, 3D volume and viewpoint scores of one class (PNG + HTML)."""
    _set_threads(threads)
    _run(config, workspace, "observe", [])

    def action() -> tuple[Path, Path]:
        from rapomdp.awareness.report import write_fig1

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
) -> None:
    """Fig. 2: the target's volume in two-class problems and in the all-class problem.

    Each two-class problem trains its own classifier in W/fig2/<target>-vs-<other>.
    """
    _set_threads(threads)

    def action() -> tuple[Path, Path]:
        from rapomdp.awareness.report import write_fig2

        return write_fig2(load_config(config), Workspace(workspace), target,
                          [a.strip() for a in against.split(",") if a.strip()], epochs,
                          on_result=_report)

    png, html = _guard(action)
    console.print(f"[green]✓[/] Fig. 2 written to {png} and {html}")


@app.command()
def robot(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False) -> None:
    """Solve the Panda's IK at every test viewpoint: reachability, manipulability, energy."""
    _run(config, workspace, "robot", ["robot"] if force else [])

    def summary() -> str:
        from rapomdp.io import read_json
        from rapomdp.robot.stage import describe

        return describe(read_json(Workspace(workspace).require("robot") / "robot.json"))

    console.print(f"  {_guard(summary)}", highlight=False, soft_wrap=True)


@app.command()
def solve(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False) -> None:
    """Solve one active-recognition POMDP per observation model (policies as .npz)."""
    _run(config, workspace, "solve", ["solve"] if force else [])

    def summary() -> dict:
        from rapomdp.io import read_json

        return read_json(Workspace(workspace).require("solve") / "solve_summary.json")

    for name, bounds in _guard(summary).items():
        console.print(
            f"  {name:<11} value in [{bounds['lower']:.4f}, {bounds['upper']:.4f}] after "
            f"{bounds['seconds']:.1f} s, {bounds['vectors']} vectors", highlight=False)


WorkersOption = Annotated[
    int | None,
    typer.Option(help="Processes for saliency maps and episodes (default: 2, or 1 on a "
                      "single core); the results do not depend on it."),
]


def _print_table1(workspace: Path) -> None:
    table = Path(workspace) / "evaluate" / "table1.md"
    if table.exists():
        sys.stdout.write("\nTable 1 (closed-loop episodes on the test models):\n\n"
                         + table.read_text())


@app.command()
def evaluate(workspace: WorkspaceOption, config: ConfigOption = None,
             force: ForceOption = False, threads: ThreadsOption = None,
             workers: WorkersOption = None) -> None:
    """Closed-loop episodes of every method on every test model (paper Sec. 5.2).

    Each test model starts from evaluate.starts_per_model seeded reachable viewpoints; every
    method (evaluate.methods) runs one episode from each. Prints Table 1 and writes
    W/evaluate/: table1.md|csv, per_class.md|csv, episodes.npz|csv, fig3.png, trajectories.png.
    """
    _set_threads(threads)
    _set_workers(workers)
    _run(config, workspace, "evaluate", ["evaluate"] if force else [])
    _print_table1(workspace)


def _set_workers(workers: int | None) -> None:
    from rapomdp import parallel

    parallel.workers = workers


@app.command()
def report(workspace: WorkspaceOption, config: ConfigOption = None,
           threads: ThreadsOption = None,
           fig2: Annotated[bool, typer.Option(
               "--fig2", help="Make Fig. 2 first, as `rapomdp figure fig2` with its defaults "
                              "(trains three two-class classifiers: minutes).")] = False,
           workers: WorkersOption = None) -> None:
    """Write W/report/report.html and report.md (and their figures) from the stages' results.

    The report is always rebuilt (it is cheap): it also shows optional artefacts that are not
    among its inputs (Fig. 2 from `rapomdp figure fig2` or --fig2).
    """
    _set_threads(threads)
    _set_workers(workers)
    if fig2:
        def make_fig2() -> tuple[Path, Path]:
            from rapomdp.awareness.report import write_fig2

            return write_fig2(load_config(config), Workspace(workspace), FIG2_TARGET,
                              list(FIG2_AGAINST), None, on_result=_report)

        _guard(make_fig2)
    _run(config, workspace, "report", ["report"])
    folder = Path(workspace) / "report"
    for name in ("report.html", "report.md"):
        sys.stdout.write(f"{folder / name}\n")


@app.command("config")
def show_config(config: ConfigOption = None) -> None:
    """Print the resolved configuration as YAML (the default when no file is given)."""
    resolved = _guard(lambda: load_config(config))
    sys.stdout.write(resolved.to_yaml())


@app.command()
def status(workspace: WorkspaceOption) -> None:
    """Show which stages a workspace holds, and when they ran."""
    manifest = _guard(lambda: Workspace(workspace).manifest())
    table = Table(title=str(workspace))
    for column in ("stage", "files", "seconds", "finished", "key"):
        table.add_column(column)
    for stage in STAGES:
        record = manifest["stages"].get(stage.name)
        if record is None:
            table.add_row(stage.name, "-", "-", "not run", "-")
        else:
            table.add_row(stage.name, str(len(record["files"])), str(record["seconds"]),
                          record["finished"], record["key"][:12])
    Console().print(table)


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
    if "roboticstoolbox" in sys.modules:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    main()
