"""Speed of the closed-loop episode on one core: render + classify + belief update + act.

Needs a workspace where ``rapomdp run`` has reached the ``solve`` stage. Times, on one thread,
each part of a step on every test model's X_rho views, then whole episodes of every configured
method (as the evaluate stage runs them), and prints images (steps) per second of CPU time.

Usage: OMP_NUM_THREADS=1 python benchmarks/episode_loop.py --workspace runs/demo
Writes benchmarks/results/episode_loop.txt.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.context import default_workers
from rapomdp.experiment.evaluation import ClosedLoop
from rapomdp.io import write_text_atomic
from rapomdp.pipeline import get_stage
from rapomdp.workspace import Workspace

RESULTS = Path(__file__).parent / "results" / "episode_loop.txt"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, default=Path("runs/demo"))
    parser.add_argument("--views", type=int, default=24, help="viewpoints timed per test model")
    args = parser.parse_args()
    torch.set_num_threads(1)
    ws = Workspace(args.workspace)
    config = ws.config()
    loop = ClosedLoop.load(config, ws.inputs(get_stage("evaluate")), threads=1)
    cnn = loop.recognisers["cnn"]
    pomdp = next(m for k, m in loop.methods.items() if k not in ("static", "random"))
    rng = np.random.default_rng(0)
    reachable = np.flatnonzero(loop.motion.reachable)[: args.views]
    parts = {"render": 0.0, "classify (CNN)": 0.0, "update + act": 0.0}
    if "vptree" in loop.recognisers:
        parts["classify (VP-tree)"] = 0.0
    n = 0
    for model in loop.dataset.with_role("test"):
        scene = loop.scene(model)
        pomdp.reset(int(reachable[0]), rng)
        for v in reachable:
            t0 = time.process_time()
            depth = scene.look(int(v), rng)
            t1 = time.process_time()
            output = cnn.predict(depth[None])[0]
            t2 = time.process_time()
            pomdp.observe(int(v), output)
            pomdp.act(int(v))
            t3 = time.process_time()
            if "vptree" in loop.recognisers:
                loop.recognisers["vptree"].predict(depth[None])
                parts["classify (VP-tree)"] += time.process_time() - t3
            parts["render"] += t1 - t0
            parts["classify (CNN)"] += t2 - t1
            parts["update + act"] += t3 - t2
            n += 1
    lines = [f"workspace {ws.root}, {config.camera.width}x{config.camera.height} px, "
             f"{torch.get_num_threads()} thread, {n} steps timed (CPU time per step):"]
    for name, seconds in parts.items():
        lines.append(f"  {name:<20} {1e3 * seconds / n:7.2f} ms")
    step = sum(v for k, v in parts.items() if "VP-tree" not in k) / n
    lines.append(f"  one CNN step         {1e3 * step:7.2f} ms = {1 / step:6.1f} steps/s")
    records = [r for model in loop.dataset.with_role("test") for r in loop.run_model(model)]
    images = sum(r.episode.viewpoints.size for r in records)
    cpu = sum(r.cpu_seconds for r in records)
    lines.append(f"whole episodes (every method, {default_workers()} would run in "
                 f"parallel): {images} images in {cpu:.1f} s CPU = {images / cpu:.1f} "
                 "steps/s on one core")
    text = "\n".join(lines)
    print(text)
    write_text_atomic(RESULTS, text + "\n")


if __name__ == "__main__":
    main()
