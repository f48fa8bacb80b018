"""What the classifier's first convolution sees (``train.input_features``), judged on held-out
instances only: the volume models at X_rho (never trained on; the test models are not read).
Rule: ``benchmarks/results/input_normals_rule.md``.

For each workspace (its dataset, render and xrho stages are enough) it trains, in this
process, the workspace's recipe with ``depth`` and with each ``--candidate`` on the same
training views, split and seed (paired: only the input differs), and writes one JSON line a
network to ``--out``: single-view accuracy, mean true-class log-probability, the share of
objects right by the majority of their views and the share right on under 10 % of them
(``instance_count_curve.volume_scores``), and the training seconds. ``--summary`` reads such
files and prints, per set (a workspace's parent folder), the mean over its seeds of each
figure and of the candidate's paired difference, and the rule's verdict.

    OMP_NUM_THREADS=1 python benchmarks/input_features.py -w S/default/seed-0 ... --out F.jsonl
    python benchmarks/input_features.py --summary F.jsonl [F2.jsonl ...]

Measured: ``benchmarks/results/input_normals.txt``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from instance_count_curve import train_recipe, volume_scores  # noqa: E402

from rapomdp.config import Config, apply_overrides, config_from_dict  # noqa: E402
from rapomdp.data.test_views import load_xrho_views  # noqa: E402
from rapomdp.data.training_views import load_training_views  # noqa: E402
from rapomdp.recognition.classifier import configure_torch  # noqa: E402
from rapomdp.recognition.training import collect_views  # noqa: E402
from rapomdp.workspace import Workspace  # noqa: E402

BASELINE = "depth"
FIGURES = ("view_accuracy", "log_p_true", "majority", "objects_under_10")
#: The rule's bars on the mean paired difference of every set (input_normals_rule.md).
LEAD_BARS = {"majority": 0.02, "view_accuracy": 0.02, "log_p_true": 0.0}


def with_input(config: Config, features: str) -> Config:
    """``config`` with ``train.input_features`` set, as the command line's override sets it."""
    return config_from_dict(apply_overrides(config.model_dump(mode="json"),
                                            [f"train.input_features={features}"]))


def measure(root: Path, features: list[str], threads: int) -> list[dict[str, Any]]:
    """One row per input: the volume models' figures under a network trained on it."""
    config = Workspace(root).config()
    views = load_training_views(root / "render", root / "dataset")
    xrho = load_xrho_views(root / "xrho", root / "dataset")
    dataset = views.dataset
    data = collect_views(views, "train")
    volume = dataset.with_role("volume")
    labels = [dataset.label(m) for m in volume]
    device = configure_torch("cpu", threads)
    keep = np.ones(data.labels.shape[0], dtype=bool)
    rows = []
    for name in features:
        start = time.perf_counter()
        classifier, trained = train_recipe(with_input(config, name), views, data, keep, device)
        seconds = time.perf_counter() - start
        probabilities = [classifier.predict(xrho.load(m).sensed) for m in volume]
        rows.append({"set": root.parent.name, "workspace": str(root), "seed": config.seed,
                     "input_features": name, "trained_views": trained,
                     "volume_objects": len(volume), "seconds": round(seconds, 1),
                     **volume_scores(probabilities, labels)})
    return rows


def summarise(rows: list[dict[str, Any]], candidate: str) -> list[str]:
    """Per set: the mean of each figure over its seeds, the candidate's mean paired
    difference, and whether every set clears the rule's bars."""
    lines = []
    verdicts = []
    for name in sorted({r["set"] for r in rows}):
        by_seed = {(r["seed"], r["input_features"]): r for r in rows if r["set"] == name}
        seeds = sorted(s for s, f in by_seed if f == candidate and (s, BASELINE) in by_seed)
        if not seeds:
            continue
        base = np.array([[by_seed[s, BASELINE][f] for f in FIGURES] for s in seeds])
        cand = np.array([[by_seed[s, candidate][f] for f in FIGURES] for s in seeds])
        diff = (cand - base).mean(axis=0)
        lines.append(f"{name} ({len(seeds)} seeds: {', '.join(map(str, seeds))}; "
                     f"{by_seed[seeds[0], BASELINE]['volume_objects']} volume objects a seed)")
        for i, figure in enumerate(FIGURES):
            per_seed = " / ".join(f"{d:+.3f}" for d in cand[:, i] - base[:, i])
            lines.append(f"  {figure:17s} {base[:, i].mean():7.3f} → {cand[:, i].mean():7.3f}"
                         f"  ({diff[i]:+.3f}; seeds {per_seed})")
        passed = all(diff[FIGURES.index(f)] >= bar for f, bar in LEAD_BARS.items())
        verdicts.append(passed)
        lines.append(f"  clears the rule's bars (majority ≥ +0.02, view accuracy ≥ +0.02, "
                     f"log p ≥ 0): {'yes' if passed else 'no'}")
    lead = bool(verdicts) and all(verdicts)
    lines.append(f"\nverdict ({candidate}, {len(verdicts)} sets): "
                 f"{'a lead (every set clears the bars)' if lead else 'not a lead'}")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+",
                        help="workspaces with the dataset, render and xrho stages")
    parser.add_argument("--candidate", nargs="+", default=["depth_normals"],
                        help="train.input_features values compared with depth")
    parser.add_argument("--out", type=Path, help="JSON lines file the rows are appended to")
    parser.add_argument("--summary", type=Path, nargs="+",
                        help="print the paired summary of these JSON lines files")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    if args.summary:
        rows = [json.loads(line) for path in args.summary
                for line in path.read_text().splitlines() if line.strip()]
        for candidate in args.candidate:
            print("\n".join(summarise(rows, candidate)))
        return
    if not args.workspace or args.out is None:
        parser.error("give --workspace and --out to measure, or --summary to summarise")
    print(f"{'workspace':40s} {'input':14s} {'view acc':>8s} {'log p':>7s} {'majority':>8s} "
          f"{'obj<10%':>7s} {'s':>6s}")
    for root in args.workspace:
        for row in measure(root, [BASELINE, *args.candidate], args.threads):
            with args.out.open("a") as handle:
                handle.write(json.dumps(row) + "\n")
            print(f"{row['workspace']:40s} {row['input_features']:14s} "
                  f"{row['view_accuracy']:8.3f} {row['log_p_true']:7.3f} {row['majority']:8.3f} "
                  f"{row['objects_under_10']:7.3f} {row['seconds']:6.0f}", flush=True)


if __name__ == "__main__":
    main()
