"""Scratch against pretrained convolutions, paired by seed and object, on one or more datasets.

For each configuration and seed it runs the pipeline up to ``classifier_eval`` twice in
workspaces under ``--root`` (``train.backbone: scratch``, then ``pretrained`` on a hard-linked
copy, so the dataset, renders and test views are the same files), then reads the classifier's
probabilities at the 128 test viewpoints and prints, per dataset and pooled:

* held-out objects (the *volume* models, which no choice reads the test models for): the
  single-view accuracy, and the evidence ceiling of the classifier alone: the belief after
  every view (the product of its probabilities), the majority label, any view right;
* test models: the single-view accuracy (reported, never used to choose).

Differences are pretrained − scratch with 95 % bootstrap intervals that resample seeds and,
within each, objects (paired: the same objects in both arms). Decision 0032's rule reads the
held-out single-view row.

    python benchmarks/backbone_transfer.py --config default configs/real-cad-dev.yaml \
        --seeds 0 1 2 [--root runs/backbone] [--out benchmarks/results/backbone_transfer]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from rapomdp.io import load_npz

ARMS = ("scratch", "pretrained")
BOOTSTRAP = 2000


def run_arm(workspace: Path, config: str, seed: int, arm: str, threads: int, workers: int,
            base: Path | None) -> None:
    """Run up to classifier_eval (after hard-linking ``base``'s stages when it is given)."""
    if base is not None and not workspace.exists():
        # hard links: every artefact is replaced by a rename, never written in place
        shutil.copytree(base, workspace, copy_function=os.link)
    command = [sys.executable, "-m", "rapomdp.cli", "classifier_eval", "-w", str(workspace),
               f"seed={seed}", f"train.backbone={arm}", "--threads", str(threads),
               "--workers", str(workers), "--reconfigure"]
    if config != "default":
        command += ["-c", config]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)


def object_figures(folder: Path) -> dict[str, np.ndarray]:
    """Per object: held-out single-view accuracy, all-views belief, majority, any view right;
    test single-view accuracy."""
    data = load_npz(folder / "classifier_eval" / "probabilities.npz")
    out: dict[str, np.ndarray] = {}
    p, labels = data["volume_xrho"].astype(np.float64), data["volume_labels"]
    predicted = p.argmax(axis=2)  # (M, V)
    right = predicted == labels[:, None]
    out["heldout_view"] = right.mean(axis=1)
    out["heldout_all_views"] = (np.log(np.maximum(p, 1e-12)).sum(axis=1).argmax(axis=1)
                                == labels).astype(float)
    counts = (predicted[..., None] == np.arange(p.shape[2])).sum(axis=1)
    out["heldout_majority"] = (counts.argmax(axis=1) == labels).astype(float)
    out["heldout_any_view"] = right.any(axis=1).astype(float)
    test = data["xrho"]
    out["test_view"] = (test.argmax(axis=2) == data["labels"][:, None]).mean(axis=1)
    return out


def paired_interval(diffs: list[np.ndarray], rng: np.random.Generator) -> tuple[float, float,
                                                                                   float]:
    """Mean of per-object differences over seeds, and a bootstrap interval resampling seeds
    and objects within each."""
    mean = float(np.mean(np.concatenate(diffs)))
    draws = np.empty(BOOTSTRAP)
    for b in range(BOOTSTRAP):
        seeds = rng.integers(0, len(diffs), len(diffs))
        draws[b] = np.mean(np.concatenate(
            [diffs[s][rng.integers(0, len(diffs[s]), len(diffs[s]))] for s in seeds]))
    low, high = np.percentile(draws, [2.5, 97.5])
    return mean, float(low), float(high)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", nargs="+", default=["default"],
                        help="configuration files (default: the embedded default)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--root", type=Path, default=Path("runs/backbone"))
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--arms", nargs="+", choices=ARMS, default=list(ARMS),
                        help="run only these arms now (the other's finished workspaces are "
                        "read; the pretrained arm starts from the scratch arm's copy)")
    parser.add_argument("--no-run", action="store_true",
                        help="run nothing: summarise the finished workspaces under --root")
    parser.add_argument("--out", type=Path, default=None,
                        help="also write OUT.json with every figure")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    figures: dict[str, dict[str, dict[int, dict[str, np.ndarray]]]] = {}
    for config in args.config:
        name = Path(config).stem
        figures[name] = {arm: {} for arm in ARMS}
        for seed in args.seeds:
            base: Path | None = None
            for arm in ARMS:
                workspace = args.root / name / f"{arm}-s{seed}"
                if arm in args.arms and not args.no_run:
                    run_arm(workspace, config, seed, arm, args.threads, args.workers, base)
                base = workspace
    if set(args.arms) != set(ARMS):
        return
    for name in figures:
        for seed in args.seeds:
            for arm in ARMS:
                figures[name][arm][seed] = object_figures(args.root / name / f"{arm}-s{seed}")
    keys = ("heldout_view", "heldout_all_views", "heldout_majority", "heldout_any_view",
            "test_view")
    lines = [f"seeds {args.seeds}; pretrained - scratch, 95 % interval resampling seeds and "
             "objects (paired)", "",
             f"{'dataset':18s} {'figure':18s} {'scratch':>8s} {'pretrained':>10s} "
             f"{'difference':>26s}"]
    record: dict[str, dict[str, list[float]]] = {}
    for name in [*figures, "pooled"]:
        for key in keys:
            sets = list(figures) if name == "pooled" else [name]
            scratch = [figures[n]["scratch"][s][key] for n in sets for s in args.seeds]
            pretrained = [figures[n]["pretrained"][s][key] for n in sets for s in args.seeds]
            diffs = [b - a for a, b in zip(scratch, pretrained, strict=True)]
            mean, low, high = paired_interval(diffs, rng)
            a, b = float(np.mean(np.concatenate(scratch))), float(np.mean(
                np.concatenate(pretrained)))
            record.setdefault(name, {})[key] = [a, b, mean, low, high]
            lines.append(f"{name:18s} {key:18s} {a:8.3f} {b:10.3f} "
                         f"{mean:+8.3f} [{low:+.3f}, {high:+.3f}]")
    lines += ["", "train stage seconds (mean over seeds, 1 thread, from W/train/metrics.json; "
              "the machine was shared, so compare within a row):"]
    for name in figures:
        walls = {arm: np.mean([json.loads((args.root / name / f"{arm}-s{seed}" / "train"
                                           / "metrics.json").read_text())["wall_s"]
                               for seed in args.seeds]) for arm in ARMS}
        lines.append(f"{name:18s} " + "  ".join(f"{arm} {w:.0f}" for arm, w in walls.items()))
    print("\n".join(lines))
    if args.out is not None:
        args.out.with_suffix(".txt").write_text("\n".join(lines) + "\n")
        args.out.with_suffix(".json").write_text(json.dumps(
            {"seeds": args.seeds, "configs": args.config, "figures": record}, indent=1))


if __name__ == "__main__":
    main()
