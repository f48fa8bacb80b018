"""Wall time of the evaluate stage's held-out closed loop (where the declared confidence is
fitted) with one worker process and with ``--workers`` (the same fits, checked).

    python benchmarks/held_out_loop_speed.py -w W [--workers 2]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rapomdp.context import RunContext
from rapomdp.experiment.held_out import closed_loop_declared
from rapomdp.pipeline import get_stage
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    methods = [m for m in config.evaluate.methods if m not in ("static", "random")]
    seconds, fits = {}, {}
    for workers in (1, args.workers):
        with tempfile.TemporaryDirectory() as tmp:
            began = time.perf_counter()
            fits[workers] = closed_loop_declared(config, ws.inputs(get_stage("evaluate")),
                                                 methods, Path(tmp),
                                                 RunContext(workers=workers, progress=False))
            seconds[workers] = time.perf_counter() - began
    same = all(fits[1][m].to_dict() == fits[args.workers][m].to_dict() for m in fits[1])
    episodes = sum(f.episodes for f in fits[1].values())
    print(f"held-out closed loop of {', '.join(fits[1])} ({episodes} episodes): "
          f"1 worker {seconds[1]:.1f} s, {args.workers} workers {seconds[args.workers]:.1f} s, "
          f"ratio {seconds[1] / seconds[args.workers]:.2f}; same fits: {same}")


if __name__ == "__main__":
    main()
