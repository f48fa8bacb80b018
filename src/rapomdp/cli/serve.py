"""``rapomdp serve``: a finished workspace's method as a local server for a robot program."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rapomdp.cli.common import _guard, _require_existing, _workspace_path, console


def serve(
    workspace: Annotated[Path, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help="A workspace whose stages up to solve have run.")] = Path("runs/demo"),
    method: Annotated[str, typer.Option(
        help="The method to run: ra, classifier, vptree (solved by the solve stage), random, "
             "static or learned.")] = "ra",
    host: Annotated[str, typer.Option(
        help="The address to bind; the default serves this machine only.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=0, max=65535,
                                      help="The TCP port (0: one the system picks).")] = 8765,
    threads: Annotated[int, typer.Option(min=1, help="PyTorch's CPU threads.")] = 1,
) -> None:
    """Serve a finished workspace's method to a robot program (docs/robot-api.md).

    Length-prefixed msgpack messages over TCP: info, reset, observe (a depth image and its
    camera pose), next_view (the next viewpoint's pose, Panda joints and energy, or the
    declaration). One client at a time; Ctrl-C stops it.
    """
    _require_existing(workspace)

    def start() -> None:
        from rapomdp.robot_api.recognizer import ActiveRecognizer
        from rapomdp.robot_api.server import RecognizerServer

        recognizer = ActiveRecognizer.load(workspace, method, threads=threads)
        server = RecognizerServer(recognizer, host, port)
        bound_host, bound_port = server.address
        console.print(f"serving {method} of {workspace} on {bound_host}:{bound_port} "
                      "(Ctrl-C stops)", highlight=False, soft_wrap=True)
        server.serve_forever()

    _guard(start)
