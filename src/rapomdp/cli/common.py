"""The options, the console and the one error style every command shares: a user's error is
one ``error:`` line and exit status 2 (:func:`_guard`), and a stage command runs the pipeline
up to its stage (:func:`_run`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, TypeVar

import typer
from rich.console import Console
from rich.markup import escape

from rapomdp.context import RunContext
from rapomdp.io import ArtefactError, describe_os_error

if TYPE_CHECKING:
    from rapomdp.config import Config
    from rapomdp.workspace import StageResult, Workspace


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



WorkersOption = Annotated[
    int | None,
    typer.Option(help="Processes for the stages that spread tasks (render, train's ensemble "
                      "members, classifier_eval, vptree, saliency, solve, learn, evaluate; "
                      "default: 2, or 1 on a single core); the results do not depend on it."),
]



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


