"""Time to build every saliency volume and observation model, and the voxel-resolution sweep.

Needs a workspace whose ``saliency`` stage has run (``rapomdp saliency -w W``). For each voxel
resolution it builds every class's volume, the viewpoint scores, the observation models and the
self-awareness quality on the test models; renders and classifier outputs at X_rho are computed
once and shared (their time is reported separately). Prints lines and writes
benchmarks/results/volume_observe.json.

    python benchmarks/volume_observe_timing.py -w runs/default [--resolutions 16 25 40 60 80]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from rapomdp.awareness.observe_stage import XrhoOutcomes, observe, xrho_outcomes
from rapomdp.awareness.stage import class_volume
from rapomdp.io import write_text_atomic
from rapomdp.recognition.stage import load_workspace_classifier
from rapomdp.workspace import Workspace

RESULTS = Path(__file__).parent / "results" / "volume_observe.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-w", "--workspace", type=Path, required=True)
    parser.add_argument("--resolutions", type=int, nargs="+", default=[16, 25, 40, 60, 80])
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config, views, classifier = load_workspace_classifier(args.workspace)
    saliency_dir = Workspace(args.workspace).require("saliency")
    dataset = views.dataset
    cache: dict[str, XrhoOutcomes] = {}
    start = time.perf_counter()
    for model in dataset.with_role("volume") + dataset.with_role("test"):
        purpose = "observe/volume" if model.role == "volume" else "classifier_eval"
        cache[f"{model.class_name}/{model.id}"] = xrho_outcomes(
            dataset, model, classifier, purpose, config.seed, config.viewpoints, config.camera,
            config.render.noise)
    render_s = time.perf_counter() - start
    print(f"{len(dataset.classes)} classes, {config.viewpoints.count} viewpoints: rendering and "
          f"classifying the volume and test models at X_rho took {render_s:.1f} s")
    results = {"classes": len(dataset.classes), "viewpoints": config.viewpoints.count,
               "saliency_method": config.saliency.method, "xrho_render_classify_s": render_s,
               "threads": args.threads, "resolutions": {}}
    for resolution in args.resolutions:
        start = time.perf_counter()
        volumes = {name: class_volume(dataset, views, saliency_dir, name, resolution)
                   for name in dataset.classes}
        volume_s = time.perf_counter() - start
        result = observe(dataset, classifier, volumes, config.observe, config.viewpoints,
                         config.camera, config.render.noise, config.seed, cache, progress=False)
        rows = {row["model"]: row for row in result.quality}
        ra = rows["ra"]
        results["resolutions"][resolution] = {
            "volumes_s": volume_s, "observe_s": result.seconds["total_s"],
            "occupied_voxels": int(sum(int(v.occupied.sum()) for v in volumes.values())),
            "calibration_slope": result.calibration.slope, "quality": rows,
        }
        print(f"resolution {resolution:>3}: volumes {volume_s:.2f} s, scores + models + quality "
              f"{result.seconds['total_s']:.2f} s; RA on test models: log-lik "
              f"{ra['log_likelihood']:.3f}, Brier {ra['brier']:.3f}, AUC {ra['auc']:.3f}")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS, json.dumps(results, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
