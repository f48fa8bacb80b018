"""``rapomdp dataset``: build the dataset stage, or preview it as a contact sheet."""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from rapomdp.cli.common import (
    ConfigOption,
    ForceOption,
    ReconfigureOption,
    WorkspaceOption,
    _fail,
    _guard,
    _require_existing,
    _run,
    _workspace_path,
    console,
)
from rapomdp.io import check_output_path

dataset_app = typer.Typer(
    help="Build the dataset stage (normalised meshes and split), or preview it.",
    invoke_without_command=True,
    rich_markup_mode="markdown",
)


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
        raise _fail("--workspace is required")
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


