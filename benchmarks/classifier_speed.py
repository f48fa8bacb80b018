"""Classifier speed on this machine: training images per second and single-image latency.

Renders a few procedural models (no workspace needed), then times, for each thread count:
* a training step of the default configuration (augmentation + preprocessing + forward +
  backward + Adam) in images per second, and the share of it spent preprocessing;
* ``Classifier.predict`` on one depth image (preprocessing included), median latency.

Usage: python benchmarks/classifier_speed.py [--threads 1 2] [--steps 8]
Writes benchmarks/results/classifier_speed.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.config import TrainConfig
from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.procedural import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.data.training_views import model_poses
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.io import write_text_atomic
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.preprocess import preprocess
from rapomdp.recognition.training import augment_batch, preprocess_params

RESULTS = Path(__file__).parent / "results" / "classifier_speed.json"


class _Model:
    centroid = np.array([0.0, 0.0, 0.15])


def training_depth(intrinsics, count: int) -> np.ndarray:
    """Depth renders of four procedural classes over the training viewsphere."""
    images = []
    for name in ("bicycle", "mug", "chair", "teapot"):
        mesh = normalise_mesh(generate_model(name, 0, 0), 0.2, "z")
        model = _Model()
        model.centroid = np.array([0.0, 0.0, float(np.ptp(mesh.vertices[:, 2])) / 2])
        poses = model_poses(model, count // 4, 0.6, hemisphere=False)
        images.append(DepthRenderer(mesh, intrinsics).render(poses))
    return np.concatenate(images)


def time_training(depth, cfg: TrainConfig, intrinsics, steps: int) -> dict[str, float]:
    params = preprocess_params(cfg.preprocess)
    torch.manual_seed(0)
    network = DepthAlexNet(NetworkSpec(14, params.input_size_px, cfg.width, cfg.dropout))
    optimiser = torch.optim.Adam(network.parameters(), lr=cfg.learning_rate,
                                 weight_decay=cfg.weight_decay)
    rng = np.random.default_rng(0)
    labels = torch.from_numpy(rng.integers(0, 14, cfg.batch_size))
    prep_s = total_s = 0.0
    for step in range(steps + 1):  # the first step warms up and is not counted
        idx = rng.choice(depth.shape[0], cfg.batch_size, replace=False)
        t0 = time.perf_counter()
        d, shift, scale = augment_batch(depth[idx], cfg.augment, None, rng)
        x = torch.from_numpy(preprocess(d, intrinsics.fx, intrinsics.fy, params, shift,
                                        scale).images)
        t1 = time.perf_counter()
        loss = torch.nn.functional.cross_entropy(network(x), labels)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        t2 = time.perf_counter()
        if step:
            prep_s += t1 - t0
            total_s += t2 - t0
    return {"train_images_per_s": steps * cfg.batch_size / total_s,
            "preprocess_share": prep_s / total_s}


def time_inference(depth, cfg: TrainConfig, intrinsics, repeats: int) -> dict[str, float]:
    params = preprocess_params(cfg.preprocess)
    network = DepthAlexNet(NetworkSpec(14, params.input_size_px, cfg.width, cfg.dropout))
    classifier = Classifier(network, [str(i) for i in range(14)], params, intrinsics.fx,
                            intrinsics.fy)
    single, batch = depth[0], depth[:128]
    classifier.predict(single)
    latencies = []
    for i in range(repeats):
        t0 = time.perf_counter()
        classifier.predict(depth[i % depth.shape[0]])
        latencies.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    classifier.predict(batch)
    batch_s = time.perf_counter() - t0
    return {"latency_ms_median": 1000 * float(np.median(latencies)),
            "latency_ms_p90": 1000 * float(np.percentile(latencies, 90)),
            "batch128_images_per_s": batch.shape[0] / batch_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--steps", type=int, default=8, help="timed training steps")
    parser.add_argument("--repeats", type=int, default=100, help="timed single predictions")
    args = parser.parse_args()
    cfg = TrainConfig()
    intrinsics = xtion_intrinsics(160, 120)
    depth = training_depth(intrinsics, 400)
    rows = []
    for threads in args.threads:
        torch.set_num_threads(threads)
        row = {"threads": threads}
        row.update(time_training(depth, cfg, intrinsics, args.steps))
        row.update(time_inference(depth, cfg, intrinsics, args.repeats))
        rows.append(row)
        print(f"threads {threads}: train {row['train_images_per_s']:.0f} images/s "
              f"({row['preprocess_share']:.0%} preprocessing), single-image latency "
              f"{row['latency_ms_median']:.2f} ms (p90 {row['latency_ms_p90']:.2f}), "
              f"batched inference {row['batch128_images_per_s']:.0f} images/s")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    result = {
        "config": {"width": cfg.width, "input_size_px": cfg.preprocess.input_size_px,
                   "batch_size": cfg.batch_size, "camera": "160x120"},
        "machine": {"cpus": os.cpu_count(), "load_average_1min": load,
                    "python": platform.python_version(), "torch": torch.__version__},
        "rows": rows,
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS, json.dumps(result, indent=2) + "\n")
    print(f"load average at the end: {load:.2f} on {os.cpu_count()} CPUs; wrote {RESULTS}")


if __name__ == "__main__":
    main()
