"""``rapomdp record`` and ``rapomdp replay``: a recorded sequence of depth images from the
simulator's closed loop, and a method run on a recorded sequence (docs/robot-api.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rapomdp.cli.common import _guard, _require_existing, _workspace_path, console

_WORKSPACE_HELP = "A workspace whose stages up to solve have run."
_METHOD_HELP = ("The method: ra, classifier, vptree (solved by the solve stage), random, static "
                "or learned.")


def record(
    out: Annotated[Path, typer.Argument(
        metavar="OUT", help="The recording's folder: new, empty, or an earlier recording.")],
    workspace: Annotated[Path, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help=_WORKSPACE_HELP)] = Path("runs/demo"),
    method: Annotated[str, typer.Option(help=_METHOD_HELP)] = "ra",
    model: Annotated[str | None, typer.Option(
        help="A test model's file or id (default: the first test model).")] = None,
    start: Annotated[int | None, typer.Option(
        min=0, help="The start viewpoint (default: the evaluate stage's first for the "
                    "model).")] = None,
    seed: Annotated[int | None, typer.Option(
        help="Seeds the episode's draws (default: the evaluate stage's own episode).")] = None,
) -> None:
    """Record one closed-loop episode of the simulator: the depth images the camera took and
    their camera poses, in the recorded-sequence format of docs/robot-api.md."""
    _require_existing(workspace)

    def go() -> None:
        from rapomdp.robot_api.recording import record_episode

        recording, episode = record_episode(workspace, out, method, model, start, seed)
        console.print(f"recorded {len(recording)} frames of {recording.source['model']} "
                      f"({recording.true_class}) into {out}: viewpoints "
                      f"{', '.join(map(str, episode.viewpoints))}, declared "
                      f"{recording.source['declared_class']} at "
                      f"{recording.source['declared_confidence']:.3f}",
                      highlight=False, soft_wrap=True)

    _guard(go)


def replay(
    folder: Annotated[Path, typer.Argument(metavar="FOLDER", help="A recording's folder.")],
    workspace: Annotated[Path, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help=_WORKSPACE_HELP)] = Path("runs/demo"),
    method: Annotated[str, typer.Option(help=_METHOD_HELP)] = "ra",
    out: Annotated[Path | None, typer.Option(
        help="The JSON table to write (default: FOLDER/replay-METHOD.json).")] = None,
    seed: Annotated[int | None, typer.Option(
        help="Seeds the method's draws (default: the recording's).")] = None,
) -> None:
    """Run a method on a recorded sequence, frame by frame, as a robot program would: what it
    believes after each frame and where it would look next, or what it declares."""
    _require_existing(workspace)

    def go() -> None:
        from rapomdp.robot_api.recognizer import ActiveRecognizer
        from rapomdp.robot_api.recording import (
            load_recording,
            replay_rng,
            replay_summary,
            replay_table,
            write_replay_table,
        )
        from rapomdp.robot_api.recording import replay as run_replay

        recording = load_recording(folder)
        recognizer = ActiveRecognizer.load(workspace, method)
        result = run_replay(recognizer, recording, replay_rng(recognizer, recording, seed))
        table = replay_table(result, recognizer, recording)
        path = out if out is not None else folder / f"replay-{method}.json"
        write_replay_table(path, table)
        for line in replay_summary(table):
            console.print(line, highlight=False, soft_wrap=True)
        console.print(f"table: {path}", highlight=False, soft_wrap=True)

    _guard(go)
