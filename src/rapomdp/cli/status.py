"""``rapomdp status`` and ``rapomdp config``: what a workspace holds and the configuration it
resolves to; nothing is written."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from rapomdp.cli.common import (
    ConfigOption,
    OverridesArgument,
    WorkspaceOption,
    _duration,
    _fail,
    _guard,
    _note,
    _require_existing,
    _workspace_path,
    console,
)

if TYPE_CHECKING:
    from rapomdp.config import Config


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


def _finished(recorded: str | None) -> str:
    """A record's ``finished`` time to the minute (``2026-12-02 15:21``), as recorded."""
    if not recorded:
        return "-"
    return recorded[:16].replace("T", " ")


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


