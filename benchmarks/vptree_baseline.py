"""The VP-tree baseline on a workspace's renders: fit time, predict latency, single-view accuracy.

Reads ``W/dataset`` and ``W/render`` (and ``W/config.yaml`` when present) and writes nothing
into the workspace. Fits the vocabulary-tree classifier on the train models' training-viewsphere
renders exactly as the ``vptree`` stage does, then classifies the test models (and the volume
models, which the observation model is counted on) at the test viewpoints X_rho.

Usage: python benchmarks/vptree_baseline.py --workspace W [--patch-size-m 0.08] [--stride-px 4]
       [--branching 10] [--levels 3] [--top-k 1]
Writes benchmarks/results/vptree_baseline.txt.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
import yaml

from rapomdp.config import Config, config_from_dict
from rapomdp.data.test_views import load_xrho_views
from rapomdp.data.training_views import load_training_views
from rapomdp.io import write_text_atomic
from rapomdp.recognition.vptree_stage import fit_vptree, xrho_predictions

RESULTS = Path(__file__).parent / "results" / "vptree_baseline.txt"
CNN_ACCURACY = 0.676  # the default CNN on the test models at X_rho (classifier_eval)


def workspace_config(ws: Path) -> Config:
    """The workspace's configuration, sections this version does not know dropped (a workspace
    made by a newer version may have more; the VP-tree reads only seed, camera, render,
    viewpoints and vptree)."""
    path = ws / "config.yaml"
    if not path.exists():
        return Config()
    data = yaml.safe_load(path.read_text()) or {}
    unknown = sorted(set(data) - set(Config.model_fields))
    if unknown:
        print(f"note: {path}: ignoring sections {', '.join(unknown)}")
    return config_from_dict({k: v for k, v in data.items() if k in Config.model_fields},
                            str(path))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, required=True)
    parser.add_argument("--patch-size-m", type=float)
    parser.add_argument("--stride-px", type=int)
    parser.add_argument("--branching", type=int)
    parser.add_argument("--levels", type=int)
    parser.add_argument("--top-k", type=int)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    ws = args.workspace
    config = workspace_config(ws)
    for name in ("patch_size_m", "stride_px", "branching", "levels", "top_k"):
        if getattr(args, name) is not None:
            setattr(config.vptree, name, getattr(args, name))

    start = time.perf_counter()
    views = load_training_views(ws / "render", ws / "dataset")
    classifier = fit_vptree(views, config.vptree, config.seed, progress=False)
    fit_s = time.perf_counter() - start
    dataset = views.dataset

    start = time.perf_counter()
    images = load_xrho_views(ws / "xrho", dataset)
    vol_labels, vol_pred = xrho_predictions(classifier, images, dataset.with_role("volume"),
                                            "volume", False)
    volume_s = time.perf_counter() - start
    start = time.perf_counter()
    test_labels, test_pred = xrho_predictions(classifier, images, dataset.with_role("test"),
                                              "test", False)
    test_s = time.perf_counter() - start
    correct = test_pred == test_labels[:, None]

    # single-image latency, as inside a closed-loop step (one image per call)
    sensed = images.load(dataset.with_role("test")[0]).sensed
    classifier.predict(sensed[0])
    latency = []
    for image in sensed:
        t = time.perf_counter()
        classifier.predict(image)
        latency.append(time.perf_counter() - t)
    latency_ms = 1e3 * np.array(latency)

    cfg = config.vptree
    lines = [
        "VP-tree baseline (vocabulary tree over metric depth patches, TF-IDF, best match)",
        f"workspace: {ws}   machine: {platform.processor() or platform.machine()}, "
        f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}",
        f"vptree: branching {cfg.branching}, levels {cfg.levels} ({classifier.tree.leaves} "
        f"leaves), patch {cfg.patch_size_m} m x {cfg.patch_samples}^2 samples, stride "
        f"{cfg.stride_px} px, top_k {cfg.top_k}, k-means on {classifier.fit_descriptors} "
        "descriptors",
        f"training images: {classifier.labels.size} (train models x training viewsphere), "
        f"{len(dataset.classes)} classes",
        f"fit (load + descriptors + tree + index): {fit_s:.1f} s",
        f"volume models at X_rho ({vol_pred.size} renders + predictions, the confusion "
        f"counts): {volume_s:.1f} s",
        f"test models at X_rho ({test_pred.size} renders + predictions): {test_s:.1f} s",
        f"fit + observation model: {fit_s + volume_s:.1f} s (budget 40 s)",
        f"predict one image: median {np.median(latency_ms):.2f} ms, p95 "
        f"{np.percentile(latency_ms, 95):.2f} ms ({latency_ms.size} calls)",
        "",
        f"single-view accuracy, test models at X_rho: {correct.mean():.1%}  "
        f"(volume models: {(vol_pred == vol_labels[:, None]).mean():.1%}; CNN "
        f"{CNN_ACCURACY:.1%}; chance {1 / len(dataset.classes):.1%})",
        "per class (test models at X_rho):",
    ]
    for c, name in enumerate(dataset.classes):
        rows = test_labels == c
        lines.append(f"  {name:<12} {correct[rows].mean():.1%}")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out, text)


if __name__ == "__main__":
    main()
