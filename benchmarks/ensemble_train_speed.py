"""The train stage of an ensemble in one process and with its members shared over worker
processes, on a workspace's own renders (``--epochs`` per member, ``--members`` of them): wall
seconds of each and their ratio, and whether the two wrote the same checkpoint (they must).

    python benchmarks/ensemble_train_speed.py -w W [--members 3] [--epochs 5] [--workers 2]

Each run writes into a temporary folder; the workspace is only read.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rapomdp.context import RunContext
from rapomdp.recognition.stage import run_train_stage
from rapomdp.workspace import StageInputs, Workspace


def train_seconds(workspace: Workspace, members: int, epochs: int, context: RunContext,
                  out: Path) -> float:
    """Wall seconds of the train stage with ``members`` of ``epochs`` epochs into ``out``."""
    config = workspace.config()
    config = config.model_copy(update={"train": config.train.model_copy(
        update={"ensemble": members, "epochs": epochs})})
    inputs = StageInputs.of("train", {"dataset": workspace.require("dataset"),
                                      "render": workspace.require("render")})
    start = time.perf_counter()
    run_train_stage(config, inputs, out, context)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--members", type=int, default=3)
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    workspace = Workspace(args.workspace)
    with tempfile.TemporaryDirectory() as tmp:
        one = train_seconds(workspace, args.members, args.epochs,
                            RunContext(workers=1, threads=1, progress=False), Path(tmp) / "one")
        shared = train_seconds(workspace, args.members, args.epochs,
                               RunContext(workers=args.workers, threads=1, progress=False),
                               Path(tmp) / "shared")
        same = ((Path(tmp) / "one" / "classifier.pt").read_bytes()
                == (Path(tmp) / "shared" / "classifier.pt").read_bytes())
    print(f"train stage, {args.members} members x {args.epochs} epochs on {args.workspace}")
    print(f"  one process, 1 thread:          {one:7.1f} s")
    print(f"  {args.workers} worker processes, 1 thread: {shared:7.1f} s")
    print(f"  speed-up: {one / shared:.2f}x; the same checkpoint: {same}")


if __name__ == "__main__":
    main()
