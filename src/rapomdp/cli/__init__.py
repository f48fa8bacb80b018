"""The ``rapomdp`` command line: the whole pipeline, or one stage, on a workspace folder.

The app and its console script (:func:`main`) live here; the commands live by topic:
:mod:`~rapomdp.cli.stages` (``run``, ``demo`` and one command per stage),
:mod:`~rapomdp.cli.dataset` (``dataset`` and ``dataset preview``),
:mod:`~rapomdp.cli.report` (``report`` and ``figure``), :mod:`~rapomdp.cli.study` (``study``),
:mod:`~rapomdp.cli.status` (``status`` and ``config``), :mod:`~rapomdp.cli.serve` (``serve``),
:mod:`~rapomdp.cli.record` (``record``, ``replay``) and
:mod:`rapomdp.planning.cli` (``pomdp``), with the options and the one error style they share in
:mod:`~rapomdp.cli.common`.
"""

from __future__ import annotations

import os
import sys
from typing import Annotated

import typer

from rapomdp.cli import report as _report_commands
from rapomdp.cli import stages as _stage_commands
from rapomdp.cli.common import _duration as _duration
from rapomdp.cli.dataset import dataset_app
from rapomdp.cli.pretrain import pretrain
from rapomdp.cli.record import record, replay
from rapomdp.cli.report import figure_app
from rapomdp.cli.serve import serve
from rapomdp.cli.stages import _story as _story
from rapomdp.cli.stages import peak_memory_gb, run_summary_lines
from rapomdp.cli.status import show_config, status
from rapomdp.cli.study import study
from rapomdp.planning.cli import pomdp_app

# Stage code (torch, the robot, rendering) is imported inside the commands that run it, so
# `rapomdp pomdp ...` and `--help` start without it.

__all__ = ["app", "main", "peak_memory_gb", "run_summary_lines"]

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


# The commands, in the order `rapomdp --help` lists them.
app.command()(_stage_commands.run)
app.command()(_stage_commands.demo)
app.command()(_stage_commands.render)
app.command()(_stage_commands.xrho)
app.command()(_stage_commands.train)
app.command("classifier_eval")(_stage_commands.classifier_eval)
# its former name, kept as an alias
app.command("evaluate-classifier", hidden=True)(_stage_commands.classifier_eval)
app.command()(_stage_commands.saliency)
app.command()(_stage_commands.volume)
app.command()(_stage_commands.observe)
app.command()(_stage_commands.vptree)
app.add_typer(figure_app, name="figure")
app.command()(_stage_commands.robot)
app.command()(_stage_commands.solve)
app.command()(_stage_commands.learn)
app.command()(_stage_commands.evaluate)
app.command()(_report_commands.report)
app.command()(study)
app.command()(pretrain)
app.command()(serve)
app.command()(record)
app.command()(replay)
app.command("config")(show_config)
app.command()(status)


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

