"""The depth CNN's batched inference with the network's own pooling against PyTorch's
``nn.MaxPool2d`` (the network before it), in one process, interleaved, one core: the forward
on a batch of preprocessed inputs and ``Classifier.predict`` on raw depth images (preprocessing
included), the ratio of their times and whether the outputs are the same bits.

    OMP_NUM_THREADS=1 python benchmarks/inference_speed.py [--batch 512] [--repeats 10]
"""

from __future__ import annotations

import argparse
import copy
import os
import time

import numpy as np
import torch
from torch import nn

from rapomdp.config import TrainConfig
from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.procedural import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry import look_at_many, viewpoints, xtion_intrinsics
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.network import DepthAlexNet, MaxPool2d, NetworkSpec
from rapomdp.recognition.preprocess import preprocess
from rapomdp.recognition.training import preprocess_params


def with_pytorch_pooling(network: DepthAlexNet) -> DepthAlexNet:
    """A copy of ``network`` whose pooling layers are PyTorch's ``nn.MaxPool2d``."""
    reference = copy.deepcopy(network)
    for i, layer in enumerate(reference.features):
        if isinstance(layer, MaxPool2d):
            reference.features[i] = nn.MaxPool2d(layer.kernel_size, layer.stride)
    return reference


def seconds(fn, repeats: int) -> float:  # noqa: ANN001
    """Median seconds of ``fn()`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--classes", type=int, default=35)
    args = parser.parse_args()
    torch.set_num_threads(1)
    cfg = TrainConfig()
    params = preprocess_params(cfg.preprocess)
    intrinsics = xtion_intrinsics(160, 120)
    mesh = normalise_mesh(generate_model("bicycle", seed=0, index=0), radius_m=0.2)
    centre = np.array([0.0, 0.0, mesh.bounds[1, 2] / 2])
    poses = look_at_many(viewpoints(args.batch, 0.6, hemisphere=True, centre=centre), centre)
    depth = DepthRenderer(mesh, intrinsics).render(poses)
    torch.manual_seed(0)
    network = DepthAlexNet(NetworkSpec(args.classes, params.input_size_px, cfg.width,
                                       cfg.dropout)).eval()
    reference = with_pytorch_pooling(network).eval()
    names = [f"c{i}" for i in range(args.classes)]
    ours = Classifier(network, names, params, intrinsics.fx, intrinsics.fy)
    theirs = Classifier(reference, names, params, intrinsics.fx, intrinsics.fy)
    x = torch.from_numpy(preprocess(depth, intrinsics.fx, intrinsics.fy, params).images)
    with torch.inference_mode():
        same_logits = torch.equal(network(x), reference(x))
    same_predict = np.array_equal(ours.predict(depth), theirs.predict(depth))
    rows = []
    for label, run_ours, run_theirs in (
        (f"forward, batch {args.batch}",
         lambda: network(x), lambda: reference(x)),
        (f"predict, {args.batch} depth images",
         lambda: ours.predict(depth), lambda: theirs.predict(depth)),
        ("predict, one depth image",
         lambda: ours.predict(depth[:1]), lambda: theirs.predict(depth[:1])),
    ):
        with torch.inference_mode():
            before = seconds(run_theirs, args.repeats)
            after = seconds(run_ours, args.repeats)
        rows.append((label, before, after))
    print(f"1 thread, {args.classes} classes, input {params.input_size_px} px; "
          f"before: nn.MaxPool2d, after: the network's MaxPool2d")
    print(f"{'':<32}{'before ms':>10}{'after ms':>10}{'speed-up':>10}")
    for label, before, after in rows:
        print(f"{label:<32}{1e3 * before:>10.2f}{1e3 * after:>10.2f}{before / after:>9.2f}x")
    print(f"same logits: {same_logits}; same probabilities from predict: {same_predict}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
