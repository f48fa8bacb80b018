"""``rapomdp report`` and ``rapomdp figure``: the report of a workspace and the paper's
Figs. 1 and 2."""

from __future__ import annotations

import sys
from functools import partial
from pathlib import Path
from typing import Annotated

import typer

from rapomdp.cli.common import (
    ConfigOption,
    OverridesArgument,
    ReconfigureOption,
    ThreadsOption,
    WorkersOption,
    WorkspaceOption,
    _context,
    _guard,
    _report,
    _resolve,
    _run,
    console,
)
from rapomdp.io import check_output_path, check_plain_name

FIG2_TARGET = "bicycle"
FIG2_AGAINST = ("teapot", "eyeglasses", "motorbike")
figure_app = typer.Typer(help="Figures of recognition self-awareness (paper Figs. 1 and 2).",
                         rich_markup_mode="markdown")


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


