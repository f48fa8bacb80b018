"""How far the perturbation mask moves after 50-150 iterations, against 300 (the default).

On a trained workspace, attributes one class's volume-model views (one batch) with the mask at
several iteration counts (same seed, so the same jitter sequence) and compares each saliency map
with the 300-iteration one. Prints lines and writes benchmarks/results/mask_convergence.json.

    python benchmarks/mask_convergence.py -w runs/default --class bicycle
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.awareness.saliency import MaskParams, PerturbationMask
from rapomdp.io import write_text_atomic
from rapomdp.recognition.stage import load_workspace_classifier

RESULTS = Path(__file__).parent / "results" / "mask_convergence.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-w", "--workspace", type=Path, required=True)
    parser.add_argument("--class", dest="class_name", default="bicycle")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config, views, classifier = load_workspace_classifier(args.workspace)
    dataset = views.dataset
    model = next(m for m in dataset.with_role("volume") if m.class_name == args.class_name)
    depth, _ = views.load(model)
    prep = classifier.preprocess(depth)
    x = torch.from_numpy(prep.images)
    label = dataset.label(model)
    target = torch.full((x.shape[0],), label, dtype=torch.long)
    clean = classifier.predict_inputs(prep.images)[:, label]
    size = classifier.preprocessing.input_size_px
    maps, stats = {}, {}
    for iterations in (50, 100, 150, 300):
        mask = PerturbationMask(classifier.network, MaskParams.scaled(size, iterations=iterations),
                                seed=1)
        start = time.perf_counter()
        maps[iterations] = mask.attribute(x, target).numpy().reshape(x.shape[0], -1)
        stats[iterations] = {"seconds": time.perf_counter() - start,
                             "perturbed_p": float(mask.last_probability.mean())}
    reference = maps[300]
    for iterations, flat in maps.items():
        ok = (flat.std(axis=1) > 0) & (reference.std(axis=1) > 0)
        corr = [np.corrcoef(flat[i], reference[i])[0, 1] for i in np.flatnonzero(ok)]
        stats[iterations].update({
            "mean_correlation_with_300": float(np.mean(corr)) if corr else float("nan"),
            "mean_abs_difference": float(np.abs(flat - reference).mean()),
            "deleted_fraction": float((flat > 0.5).mean()),
        })
        s = stats[iterations]
        print(f"{iterations:>3} iterations: {s['seconds']:.1f} s, mean correlation with 300 "
              f"{s['mean_correlation_with_300']:.3f}, mean |diff| {s['mean_abs_difference']:.4f},"
              f" deleted {s['deleted_fraction']:.3f}, p_class clean {clean.mean():.3f} -> "
              f"perturbed {s['perturbed_p']:.3f}")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    record = {"class": args.class_name, "views": int(x.shape[0]),
              "clean_p": float(clean.mean()), "iterations": stats}
    write_text_atomic(RESULTS, json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
