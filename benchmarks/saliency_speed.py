"""Perturbation masks per second: one batch of all views of a model vs one image at a time.

Renders a procedural model over the training viewsphere at the default camera and input size,
and times PerturbationMask on the default DepthAlexNet (random weights: the cost does not depend
on them) in one batch and in a one-image loop over a subset, in the same run, on the CPU. Also
times every captum method on the same batch. Prints lines and writes
benchmarks/results/saliency_speed.json.

    python benchmarks/saliency_speed.py [--views 100] [--iterations 300] [--loop 5] [--threads 1]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.awareness.saliency import METHODS, MaskParams, PerturbationMask, make_attribution
from rapomdp.config import Config
from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.procedural import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints
from rapomdp.io import write_text_atomic
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.preprocess import PreprocessParams, preprocess

RESULTS = Path(__file__).parent / "results" / "saliency_speed.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=100)
    parser.add_argument("--iterations", type=int, default=300)
    parser.add_argument("--loop", type=int, default=5, help="views timed one at a time")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    config = Config()
    intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
    mesh = normalise_mesh(generate_model("bicycle", 0, 0), config.dataset.radius_m, "z")
    centroid = np.array([0.0, 0.0, float(np.ptp(mesh.vertices[:, 2])) / 2])
    poses = look_at_many(viewpoints(args.views, config.render.radius_m, centre=centroid),
                         centroid)
    depth = DepthRenderer(mesh, intrinsics).render(poses)
    params = PreprocessParams(**config.train.preprocess.model_dump())
    inputs = torch.from_numpy(preprocess(depth, intrinsics.fx, intrinsics.fy, params).images)
    net = DepthAlexNet(NetworkSpec(classes=14, input_size_px=params.input_size_px,
                                   width=config.train.width)).eval()
    target = torch.zeros(args.views, dtype=torch.long)
    mask = PerturbationMask(net, MaskParams.scaled(params.input_size_px,
                                                   iterations=args.iterations))

    start = time.perf_counter()
    mask.attribute(inputs, target)
    batch_s = time.perf_counter() - start
    start = time.perf_counter()
    for i in range(args.loop):
        mask.attribute(inputs[i:i + 1], target[i:i + 1])
    loop_s = time.perf_counter() - start
    batch_rate, loop_rate = args.views / batch_s, args.loop / loop_s
    result = {
        "views": args.views, "iterations": args.iterations, "threads": args.threads,
        "input_px": params.input_size_px, "mask_px": mask.params.mask_size_px,
        "batch_s": batch_s, "batch_masks_per_s": batch_rate,
        "loop_views": args.loop, "loop_s": loop_s, "loop_masks_per_s": loop_rate,
        "speedup": batch_rate / loop_rate, "methods": {},
        "cpu": platform.processor() or platform.machine(), "torch": torch.__version__,
    }
    print(f"mask, {args.iterations} iterations, {args.views} views of a model in one batch: "
          f"{batch_s:.1f} s = {batch_rate:.2f} masks/s ({args.threads} thread)")
    print(f"mask, one image at a time ({args.loop} views): {loop_s:.1f} s = "
          f"{loop_rate:.3f} masks/s -> batch is {batch_rate / loop_rate:.1f}x faster")
    for method in METHODS:
        if method == "mask":
            continue
        attribution = make_attribution(method, net, params.input_size_px)
        start = time.perf_counter()
        attribution.attribute(inputs, target)
        seconds = time.perf_counter() - start
        result["methods"][method] = {"seconds": seconds, "maps_per_s": args.views / seconds}
        print(f"{method}: {args.views} views in {seconds:.2f} s = "
              f"{args.views / seconds:.1f} maps/s")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS, json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
