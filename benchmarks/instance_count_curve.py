"""How the classifier's accuracy on unseen objects grows with the training models a class: the
workspace's recipe retrained on the first k of each class's training models (a seeded order,
nested: the k-model set holds the (k-1)-model set), scored on the volume models at X_rho
(never trained on; the test models are not read). Nothing is chosen from it: it says whether
the errors that gather on whole instances (``evidence_ceiling.py``) shrink with more instances.

Per k it prints the single-view accuracy, the mean log-probability of the true class, the share
of objects right by the majority of their views (what a belief fed every view approaches when
errors are per object), the share right from under 10 % of their views, and the seconds.

    OMP_NUM_THREADS=1 python benchmarks/instance_count_curve.py -w W [W ...] --counts 1 2 3 4
        (a count above a class's training models uses all of them)

Measured: ``benchmarks/results/instance_count_curve.txt``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.config import Config
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import load_xrho_views
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.recognition.classifier import Classifier, configure_torch
from rapomdp.recognition.training import (
    LabelledViews,
    collect_views,
    train_classifier,
    validation_mask,
)
from rapomdp.workspace import Workspace


def train_recipe(config: Config, views: TrainingViews, data: LabelledViews, keep: np.ndarray,
                 device: torch.device) -> tuple[Classifier, int]:
    """The workspace's recipe (seed, epochs, noise) trained on the views ``keep`` of ``data``,
    and how many it trained on. The validation split is the train stage's, drawn over all of
    ``data``, so the views kept are split as the full set splits them."""
    held = validation_mask(data, config.train.validation_fraction,
                           class_seed(config.train_seed, "train/validation"))
    classifier, _ = train_classifier(
        data.subset(keep & ~held), data.subset(keep & held), views.dataset.classes,
        config.train, views.intrinsics.fx, views.intrinsics.fy, config.train_seed, device,
        config.render.noise, progress=False)
    return classifier, int((keep & ~held).sum())


def first_models(labels: np.ndarray, models: np.ndarray, count: int, seed: int) -> np.ndarray:
    """True for the views of the first ``count`` models of each class, in a seeded order per
    class (nested in ``count``)."""
    keep = np.zeros(models.shape[0], dtype=bool)
    for label in np.unique(labels):
        ids = np.unique(models[labels == label])
        order = class_seed(seed, f"instance-count/{label}").permutation(ids.size)
        keep |= np.isin(models, ids[order[:count]])
    return keep


def volume_scores(probabilities: list[np.ndarray], labels: list[int]) -> dict[str, float]:
    """Single-view and per-object figures of volume models' probabilities (V, C) each."""
    view_right = [p.argmax(axis=1) == y for p, y in zip(probabilities, labels, strict=True)]
    log_p = [np.log(np.maximum(p[:, y], 1e-12)) for p, y in zip(probabilities, labels,
                                                                 strict=True)]
    majority = [np.bincount(p.argmax(axis=1), minlength=p.shape[1]).argmax() == y
                for p, y in zip(probabilities, labels, strict=True)]
    share = np.array([r.mean() for r in view_right])
    return {"view_accuracy": float(np.concatenate(view_right).mean()),
            "log_p_true": float(np.concatenate(log_p).mean()),
            "majority": float(np.mean(majority)),
            "objects_under_10": float((share < 0.1).mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--counts", type=int, nargs="+", required=True,
                        help="training models a class to train on")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    print(f"{'workspace':44s} {'k':>3s} {'views':>6s} {'view acc':>8s} {'log p':>7s} "
          f"{'majority':>8s} {'obj<10%':>7s} {'s':>6s}")
    for root in args.workspace:
        ws = Workspace(root)
        config = ws.config()
        views = load_training_views(root / "render", root / "dataset")
        xrho = load_xrho_views(root / "xrho", root / "dataset")
        dataset = views.dataset
        data = collect_views(views, "train")
        volume = dataset.with_role("volume")
        device = configure_torch("cpu", args.threads)
        for count in args.counts:
            keep = first_models(data.labels, data.models, count, config.train_seed)
            start = time.perf_counter()
            classifier, trained_views = train_recipe(config, views, data, keep, device)
            seconds = time.perf_counter() - start
            probabilities = [classifier.predict(xrho.load(m).sensed) for m in volume]
            scores = volume_scores(probabilities, [dataset.label(m) for m in volume])
            print(f"{str(root):44s} {count:3d} {trained_views:6d} "
                  f"{scores['view_accuracy']:8.3f} {scores['log_p_true']:7.3f} "
                  f"{scores['majority']:8.3f} {scores['objects_under_10']:7.3f} "
                  f"{seconds:6.0f}", flush=True)


if __name__ == "__main__":
    main()
