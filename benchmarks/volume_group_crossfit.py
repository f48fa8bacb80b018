"""Volume models labelled by classifiers that trained on the other volume groups: the held-out
analogue of a classifier deployed on the train *and* volume models, its evidence cross-fitted
(rule: ``benchmarks/results/volume_group_crossfit_rule.md``). The test models are not read.

For each workspace and each volume group g (the observe stage's ``evidence_groups``: the k-th
volume model of every class), the workspace's recipe (seed, validation split, epochs) is trained
on the train models plus the volume models of the other groups, and labels group g at X_rho.
Writes ``OUT/<config>-<seed>-crossfit.npz`` and, from the workspace's own classifier (train
models only), ``OUT/<config>-<seed>-baseline.npz`` (``files``, ``predicted`` (M, V)), both for
``held_out_closed_loop.py --volume-labels``, and prints each one's single-view accuracy.

    OMP_NUM_THREADS=1 python benchmarks/volume_group_crossfit.py -w W [W ...] --out DIR
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from instance_count_curve import train_recipe  # noqa: E402

from rapomdp.data.test_views import load_xrho_views  # noqa: E402
from rapomdp.data.training_views import load_training_views  # noqa: E402
from rapomdp.io import load_npz, save_npz  # noqa: E402
from rapomdp.recognition.artefacts import load_volume_probabilities  # noqa: E402
from rapomdp.recognition.classifier import configure_torch  # noqa: E402
from rapomdp.recognition.training import LabelledViews, collect_views  # noqa: E402
from rapomdp.workspace import Workspace  # noqa: E402


def joined(first: LabelledViews, second: LabelledViews) -> LabelledViews:
    """Both sets of views in one (model indices of ``second`` moved past ``first``'s)."""
    offset = int(first.models.max()) + 1 if len(first) else 0
    return LabelledViews(np.concatenate([first.depth, second.depth]),
                         np.concatenate([first.labels, second.labels]),
                         np.concatenate([first.models, second.models + offset]),
                         np.concatenate([first.views, second.views]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for root in args.workspace:
        config = Workspace(root).config()
        views = load_training_views(root / "render", root / "dataset")
        xrho = load_xrho_views(root / "xrho", root / "dataset")
        dataset = views.dataset
        volume = dataset.with_role("volume")
        observe = load_npz(root / "observe" / "observation_models.npz")
        groups = observe["evidence_groups"][observe["evidence_from_volume"]]
        if groups.shape[0] != len(volume):
            raise SystemExit(f"{root}: the observe stage's volume rows are not the volume models")
        truth = np.array([dataset.label(m) for m in volume])
        train = collect_views(views, "train")
        held_views = collect_views(views, "volume")  # model index i = the i-th volume model
        device = configure_torch("cpu", args.threads)
        labelled: dict[int, np.ndarray] = {}  # volume model index -> its labels (V,)
        for group in np.unique(groups):
            data = joined(train, held_views.subset(groups[held_views.models] != group))
            start = time.perf_counter()
            classifier, trained_views = train_recipe(config, views, data,
                                                     np.ones(len(data), dtype=bool), device)
            members = np.flatnonzero(groups == group)
            labelled.update({int(i): classifier.predict(xrho.load(volume[i]).sensed).argmax(1)
                             for i in members})
            right = np.mean([labelled[int(i)] == truth[i] for i in members])
            print(f"{root}: group {group} labelled by a classifier of {trained_views} "
                  f"views: accuracy {right:.3f} ({time.perf_counter() - start:.0f} s)",
                  flush=True)
        predicted = np.stack([labelled[i] for i in range(len(volume))])
        outputs = load_volume_probabilities(root / "classifier_eval")
        baseline = np.stack([outputs.of(m).argmax(axis=1) for m in volume])
        files = np.array([m.file for m in volume])
        name = f"{root.parent.name}-{root.name}"
        save_npz(args.out / f"{name}-crossfit.npz", files=files, predicted=predicted)
        save_npz(args.out / f"{name}-baseline.npz", files=files, predicted=baseline)
        print(f"{root}: single-view accuracy on the volume models, own classifier "
              f"{(baseline == truth[:, None]).mean():.3f}, cross-fitted "
              f"{(predicted == truth[:, None]).mean():.3f}", flush=True)


if __name__ == "__main__":
    main()
