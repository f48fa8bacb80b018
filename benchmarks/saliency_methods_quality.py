"""Self-awareness quality of the RA models built from each saliency method.

On a workspace whose ``saliency`` stage has run (the mask, by default), computes the volume
models' 2D maps with every other method in memory, builds their volumes at the configured
resolution and the observation models, and reports the RA quality on the test models. Renders
and classifier outputs at X_rho are shared. Prints lines and writes
benchmarks/results/saliency_methods_quality.json.

    python benchmarks/saliency_methods_quality.py -w runs/default [--methods gradient gradcam]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.awareness.observe_stage import XrhoOutcomes, observe
from rapomdp.awareness.stage import class_volume, saliency_maps
from rapomdp.awareness.volume import object_grid, saliency_volume
from rapomdp.io import write_text_atomic
from rapomdp.recognition.stage import load_workspace_classifier
from rapomdp.workspace import Workspace

RESULTS = Path(__file__).parent / "results" / "saliency_methods_quality.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-w", "--workspace", type=Path, required=True)
    parser.add_argument("--methods", nargs="+",
                        default=["gradient", "smoothgrad", "gradcam", "integrated_gradients"])
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config, views, classifier = load_workspace_classifier(args.workspace)
    saliency_dir = Workspace(args.workspace).require("saliency")
    dataset = views.dataset
    resolution = config.volume.resolution
    cache: dict[str, XrhoOutcomes] = {}
    results = {}
    volumes = {n: class_volume(dataset, views, saliency_dir, n, resolution)
               for n in dataset.classes}
    runs = [(config.saliency.method + " (workspace)", volumes, 0.0)]
    for method in args.methods:
        start = time.perf_counter()
        built = {}
        for model in dataset.with_role("volume"):
            depth, poses = views.load(model)
            maps = saliency_maps(classifier, depth, dataset.label(model), method,
                                 config.saliency, config.seed)["saliency"]
            mesh = dataset.mesh(model)
            grid = object_grid(mesh.bounds[0], mesh.bounds[1], resolution)
            built[model.class_name] = saliency_volume(depth, poses, maps, views.intrinsics, grid)
        runs.append((method, built, time.perf_counter() - start))
    for name, vols, seconds in runs:
        result = observe(dataset, classifier, vols, config.observe, config.viewpoints,
                         config.camera, config.render.noise, config.seed, cache, progress=False)
        rows = {row["model"]: row for row in result.quality}
        results[name] = {"saliency_and_volumes_s": seconds, "slope": result.calibration.slope,
                         "quality": rows,
                         "mean_voxel_score": float(np.mean([np.nanmean(v.scores)
                                                            for v in vols.values()]))}
        ra, rc = rows["ra"], rows["ra_class"]
        print(f"{name:<26} maps+volumes {seconds:6.1f} s | ra: log-lik {ra['log_likelihood']:.3f}"
              f" Brier {ra['brier']:.3f} AUC {ra['auc']:.3f} | ra_class: log-lik "
              f"{rc['log_likelihood']:.3f} Brier {rc['brier']:.3f} AUC {rc['auc']:.3f}",
              flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS, json.dumps(results, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
