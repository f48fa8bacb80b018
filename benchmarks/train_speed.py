"""Training throughput of the train stage's loop with two source trees, on a workspace's own
training renders and configuration (``--epochs`` of them), alternating the trees so both see
the same load; and whether they train the same weights (SHA-256 of the state dict).

    git archive <commit> src | tar -x -C /tmp/before
    python benchmarks/train_speed.py -w W --before /tmp/before/src [--epochs 3] \
        [--threads 1 2] [--rounds 2]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from tree_run import run_json  # benchmarks/, the script's own folder

#: Runs inside the tree's process: the train stage's loop on W's renders, its seconds and hash.
TRAIN = r"""
import hashlib, json, sys, time
from pathlib import Path
import torch
from rapomdp.data.training_views import load_training_views
from rapomdp.recognition.training import collect_views, train_classifier, validation_mask
from rapomdp.data.splits import class_seed
from rapomdp.workspace import Workspace
ws = Workspace(Path(sys.argv[1])); threads, epochs = int(sys.argv[2]), int(sys.argv[3])
config = ws.config()
torch.set_num_threads(threads)
views = load_training_views(ws.require("render"), ws.require("dataset"))
data = collect_views(views, "train")
held = validation_mask(data, config.train.validation_fraction,
                       class_seed(config.train_seed, "train/validation"))
cfg = config.train.model_copy(update={"epochs": epochs})
start = time.perf_counter()
classifier, history = train_classifier(
    data.subset(~held), data.subset(held), views.dataset.classes, cfg, views.intrinsics.fx,
    views.intrinsics.fy, config.train_seed, torch.device("cpu"), config.render.noise,
    progress=False)
wall = time.perf_counter() - start
digest = hashlib.sha256()
for tensor in classifier.network.state_dict().values():
    digest.update(tensor.numpy().tobytes())
print(json.dumps({"images_per_s": int((~held).sum()) * epochs / wall, "wall_s": wall,
                  "sha256": digest.hexdigest(), "val": history.val_accuracy[-1]}))
"""


def train_with(src: Path, workspace: Path, threads: int, epochs: int) -> dict[str, object]:
    """The train stage's loop on ``workspace`` with the code of ``src``: images/s, wall
    seconds, the weights' SHA-256 and the last validation accuracy."""
    return run_json(src, TRAIN, str(workspace), str(threads), str(epochs), threads=threads)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--before", type=Path, required=True, help="the old tree's src/")
    parser.add_argument("--after", type=Path, default=Path("src"), help="the new tree's src/")
    parser.add_argument("--epochs", type=int, default=3)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    print(f"{args.workspace}: {args.epochs} epochs of its train stage, rounds alternate the "
          "trees")
    print(f"{'threads':>7}{'round':>6}{'before img/s':>14}{'after img/s':>13}{'ratio':>7}"
          "  same weights")
    for threads in args.threads:
        for r in range(args.rounds):
            before = train_with(args.before, args.workspace, threads, args.epochs)
            after = train_with(args.after, args.workspace, threads, args.epochs)
            same = before["sha256"] == after["sha256"]
            b_rate, a_rate = float(before["images_per_s"]), float(after["images_per_s"])
            print(f"{threads:>7}{r + 1:>6}{b_rate:>14.0f}{a_rate:>13.0f}{a_rate / b_rate:>7.2f}  "
                  f"{'yes' if same else 'NO'}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
