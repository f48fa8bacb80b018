"""What PyTorch offers for the depth CNN on this CPU, measured against the code as it is:
channels-last memory format and ``torch.compile`` (inductor), for a training step (forward +
backward + Adam on preprocessed inputs) and for inference (a batch of 128, and one image),
with the time ``torch.compile`` takes and whether each variant gives the same numbers.

A variant is worth adopting only if it is faster after its compile time on the demo's
training (1500 steps) and, since the pipeline's results must not move, gives the same
weights and outputs (``same`` columns: bitwise).

    OMP_NUM_THREADS=1 python benchmarks/torch_variants.py [--threads 1] [--steps 20]
"""

from __future__ import annotations

import argparse
import copy
import os
import time

import numpy as np
import torch

from rapomdp.config import TrainConfig
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.training import preprocess_params

DEMO_STEPS = 1500  # 25 epochs x 60 batches of the demo's training


def make_network(cfg: TrainConfig, size: int, classes: int) -> torch.nn.Module:
    torch.manual_seed(0)
    return DepthAlexNet(NetworkSpec(classes, size, cfg.width, cfg.dropout))


def train_steps(network: torch.nn.Module, step_fn, inputs: torch.Tensor, labels: torch.Tensor,
                steps: int, cfg: TrainConfig) -> tuple[float, float, torch.nn.Module]:
    """Seconds of the first step (compile included) and per later step; the trained network."""
    optimiser = torch.optim.Adam(network.parameters(), lr=cfg.learning_rate,
                                 weight_decay=cfg.weight_decay)
    torch.manual_seed(1)
    first = later = 0.0
    for step in range(steps + 1):
        x = inputs[step % len(inputs)]
        t0 = time.perf_counter()
        loss = torch.nn.functional.cross_entropy(step_fn(x), labels[step % len(labels)])
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        dt = time.perf_counter() - t0
        if step == 0:
            first = dt
        else:
            later += dt
    return first, later / steps, network


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--classes", type=int, default=35)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cfg = TrainConfig()
    size = preprocess_params(cfg.preprocess).input_size_px
    rng = np.random.default_rng(0)
    inputs = torch.from_numpy(rng.random((4, cfg.batch_size, 1, size, size), np.float32))
    labels = torch.from_numpy(rng.integers(0, args.classes, (4, cfg.batch_size)))
    batch = torch.from_numpy(rng.random((128, 1, size, size), np.float32))
    base_net = make_network(cfg, size, args.classes)

    variants = {}
    net = copy.deepcopy(base_net).train()
    variants["as is"] = (net, net)
    net = copy.deepcopy(base_net).train().to(memory_format=torch.channels_last)
    variants["channels-last"] = (net, lambda x, n=net: n(x.contiguous(
        memory_format=torch.channels_last)))
    net = copy.deepcopy(base_net).train()
    variants["torch.compile"] = (net, torch.compile(net))

    print(f"{args.threads} thread(s), input {size}x{size}, batch {cfg.batch_size}, "
          f"{args.classes} classes, {args.steps} timed steps")
    print(f"{'variant':<15}{'1st step s':>11}{'step ms':>9}{'ratio':>7}{'demo s':>8}"
          f"{'same weights':>14}{'infer128 ms':>13}{'ratio':>7}{'1 image ms':>12}{'same out':>10}")
    base = None
    for name, (network, step_fn) in variants.items():
        first, per_step, trained = train_steps(network, step_fn, inputs, labels, args.steps, cfg)
        trained.eval()
        fn = step_fn
        with torch.inference_mode():
            fn(batch)  # warm (compiles the inference graph)
            t0 = time.perf_counter()
            for _ in range(5):
                out = fn(batch)
            infer = (time.perf_counter() - t0) / 5
            fn(batch[:1])
            t0 = time.perf_counter()
            for i in range(50):
                fn(batch[i : i + 1])
            single = (time.perf_counter() - t0) / 50
        state = [p.detach().clone() for p in trained.parameters()]
        if base is None:
            base = (per_step, infer, state, out)
        same_w = all(torch.equal(a, b) for a, b in zip(state, base[2], strict=True))
        same_o = torch.equal(out, base[3])
        demo = first + per_step * (DEMO_STEPS - 1)
        print(f"{name:<15}{first:>11.2f}{1e3 * per_step:>9.1f}{base[0] / per_step:>7.2f}"
              f"{demo:>8.0f}{str(same_w):>14}{1e3 * infer:>13.1f}{base[1] / infer:>7.2f}"
              f"{1e3 * single:>12.2f}{str(same_o):>10}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
