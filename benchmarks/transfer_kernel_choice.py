"""What choosing ``ra_transfer``'s kernel on held-out data costs and gives, on a finished
workspace's observe artefact (read only): :func:`choose_transfer_kernel` over the evidence
groups (leave-one-group-out), the chosen kernel's held-out log-likelihood against the default
kernel's, the seconds the choice took, and — reported, never used to choose — both kernels'
log-likelihood and AUC on the test models.

    python benchmarks/transfer_kernel_choice.py -w W [--repeats 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import OBSERVATION_FILE, TIMING_FILE
from rapomdp.awareness.evidence import observed_probabilities, recorded_evidence
from rapomdp.awareness.quality import quality_from_probabilities
from rapomdp.awareness.transfer import (
    DEFAULT_TRANSFER_KERNEL,
    TRANSFER_KERNEL_GRID,
    TransferKernel,
    choose_transfer_kernel,
    transfer_confusion,
)
from rapomdp.io import read_json
from rapomdp.workspace import Workspace


def _name(kernel: TransferKernel | dict[str, float]) -> str:
    k = kernel.to_dict() if isinstance(kernel, TransferKernel) else kernel
    return f"(power {k['power']:g}, {k['bandwidth_deg']:g}°, prior {k['prior']:g})"


def _axis(values: list[float]) -> str:
    return "{" + ", ".join(f"{v:g}" for v in sorted(set(values))) + "}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of the choice")
    parser.add_argument("--pseudo-counts", type=float, nargs="*", default=[],
                        help="also the best held-out log-likelihood over the grid with each of "
                             "these confusion pseudo-counts (observe.confusion_pseudo_count, "
                             "the class confusion row ra_transfer shrinks to)")
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    observe = ws.require("observe")
    pseudo_count = ws.config().observe.confusion_pseudo_count
    with np.load(observe / OBSERVATION_FILE) as data:
        evidence = recorded_evidence(data)
        # stored as float32; the observe stage chose on its float64 original
        similarity = data["view_similarity"].astype(np.float64)
        directions = data["directions"]
        test_labels, test_predicted = data["test_labels"], data["test_predictions"]
    classes, views = similarity.shape[0], similarity.shape[1]
    print(f"workspace {args.workspace}: {classes} classes, {len(evidence.labels)} evidence rows "
          f"in {np.unique(evidence.groups).size} groups, {views} viewpoints; "
          f"pseudo-count {pseudo_count:g}; OMP_NUM_THREADS="
          f"{os.environ.get('OMP_NUM_THREADS', 'unset')}")
    grid = TRANSFER_KERNEL_GRID
    print(f"grid: power {_axis([k.power for k in grid])} x bandwidth "
          f"{_axis([k.bandwidth_deg for k in grid])}° x prior {_axis([k.prior for k in grid])}"
          f" ({len(grid)} kernels)")

    seconds = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        chosen, table = choose_transfer_kernel(evidence, similarity, directions, pseudo_count,
                                               grid)
        seconds.append(time.perf_counter() - start)
    timing = read_json(observe / TIMING_FILE) if (observe / TIMING_FILE).exists() else {}
    line = (f"choose_transfer_kernel: {statistics.median(seconds):.3f} s (median of "
            f"{args.repeats}; min {min(seconds):.3f} s)")
    if {"scores_s", "observation_models_s", "total_s"} <= set(timing):
        fitting = timing["observation_models_s"] - timing["scores_s"]
        line += (f"; the observe stage's held-out fitting took {fitting:.1f} s, the stage "
                 f"{timing['total_s']:.1f} s (timing.json, before the choice)")
    print(line)
    if not table:
        print(f"fewer than two folds: the default {_name(DEFAULT_TRANSFER_KERNEL)}")
        return
    held_out = {TransferKernel.from_dict(r): r["held_out_log_likelihood"] for r in table}
    print(f"chosen  {_name(chosen)}: held-out log-likelihood {held_out[chosen]:.4f}")
    print(f"default {_name(DEFAULT_TRANSFER_KERNEL)}: held-out log-likelihood "
          f"{held_out[DEFAULT_TRANSFER_KERNEL]:.4f}")
    ranked = sorted(table, key=lambda r: -r["held_out_log_likelihood"])
    print("best five held-out: " + "; ".join(
        f"{_name(r)} {r['held_out_log_likelihood']:.4f}" for r in ranked[:5]))
    for other in args.pseudo_counts:
        best, rows = choose_transfer_kernel(evidence, similarity, directions, other, grid)
        print(f"pseudo-count {other:g}: best {_name(best)}, held-out log-likelihood "
              f"{max(r['held_out_log_likelihood'] for r in rows):.4f}")
    print("test models, reported, not used:")
    for label, kernel in (("chosen ", chosen), ("default", DEFAULT_TRANSFER_KERNEL)):
        model = transfer_confusion(evidence, similarity, directions, pseudo_count, kernel)
        o, pc = observed_probabilities(model, test_labels, test_predicted)
        q = quality_from_probabilities(o, pc, test_predicted == test_labels[:, None])
        print(f"  {label} {_name(kernel)}: test log-likelihood {q['log_likelihood']:.4f}, "
              f"AUC {q['auc']:.4f}")


if __name__ == "__main__":
    main()
