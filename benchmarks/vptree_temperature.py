"""The VP-tree's belief temperature on a workspace's saved volume labels: the fitted t, its
held-out walk calibration and the seconds the fit adds to the vptree stage (median of
``--repeats``; one thread). Reads ``W/vptree/observation_model.npz`` only.

    OMP_NUM_THREADS=1 python benchmarks/vptree_temperature.py --workspace W
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rapomdp.data.splits import class_seed
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import load_npz, read_json
from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE, VPTREE_SUMMARY_FILE
from rapomdp.recognition.vptree_stage import vptree_observation
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    stage = ws.require("vptree")
    saved = load_npz(stage / VPTREE_OBSERVATION_FILE)
    if "volume_predictions" not in saved:
        raise SystemExit(f"{args.workspace}: its vptree stage predates the saved volume labels: "
                         "rapomdp run -w W --redo vptree")
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    seconds = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        fitted = vptree_observation(saved["volume_labels"], saved["volume_predictions"],
                                    saved["volume_groups"], len(saved["classes"]),
                                    config.vptree, directions,
                                    class_seed(config.seed, "vptree/temperature"))
        seconds.append(time.perf_counter() - start)
    held = fitted.held_out_belief
    total = read_json(stage / VPTREE_SUMMARY_FILE)["seconds"]["total"]
    print(f"{len(saved['volume_labels'])} volume models in "
          f"{len(np.unique(saved['volume_groups']))} groups, {len(saved['classes'])} classes, "
          f"{directions.shape[0]} viewpoints")
    print(f"t = {fitted.temperature:.4f} (saved: {float(saved['temperature']):.4f})")
    if held:
        print(f"held-out walks: log loss {held['log_loss_naive']:.3f} naive -> "
              f"{held['log_loss_tempered']:.3f} tempered; ECE after the last step "
              f"{held['ece_last_naive']:.3f} -> {held['ece_last_tempered']:.3f}, after the first "
              f"{held['ece_first_naive']:.3f} -> {held['ece_first_tempered']:.3f}")
    print(f"fit: {np.median(seconds):.3f} s (median of {args.repeats}); the vptree stage "
          f"took {total:.1f} s")


if __name__ == "__main__":
    main()
