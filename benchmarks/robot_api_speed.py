"""Milliseconds per step of the robot API: observe + next_view in process, and over localhost.

Needs a workspace where ``rapomdp run`` has reached the ``solve`` stage. On one thread, runs
episodes of the method on every test model's rendered images (each observe fed a uint16
millimetre image and the camera pose the IK reaches, as a robot program would), then the same
episodes through ``rapomdp serve``'s server on 127.0.0.1 (a thread, an ephemeral port), and
prints the milliseconds per step of each and the server's added round trip.

With ``--soak N`` it then runs N more episodes through the server, each on a new connection
(the test models and starts in turn), and prints the process's open file descriptors and
resident memory before and after (Linux: /proc/self).

Usage: OMP_NUM_THREADS=1 python benchmarks/robot_api_speed.py -w runs/demo [--method ra]
       [--soak N]
"""

from __future__ import annotations

import argparse
import os
import threading
import time
from pathlib import Path

import numpy as np
import torch

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.robot_api.recognizer import ActiveRecognizer
from rapomdp.robot_api.server import RecognizerClient, RecognizerServer
from rapomdp.workspace import Workspace


def episodes(step_fn, reset_fn, scenes: list[np.ndarray], poses: np.ndarray,
             starts: np.ndarray) -> tuple[int, float]:
    """Run one episode per (scene, start); return (steps, seconds in observe + next_view)."""
    steps, seconds = 0, 0.0
    for images in scenes:
        for i, start in enumerate(starts):
            reset_fn(i)
            viewpoint = int(start)
            while True:
                began = time.perf_counter()
                nxt = step_fn(images[viewpoint], poses[viewpoint])
                seconds += time.perf_counter() - began
                steps += 1
                if nxt.is_declare:
                    break
                viewpoint = nxt.viewpoint
    return steps, seconds


def open_fds() -> int:
    """This process's open file descriptors (-1 where /proc/self/fd is not there)."""
    return len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else -1


def rss_mib() -> float:
    """This process's resident memory in MiB (NaN where /proc/self/statm is not there)."""
    try:
        with open("/proc/self/statm") as handle:
            pages = int(handle.read().split()[1])
    except OSError:
        return float("nan")
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def soak(server: RecognizerServer, count: int, scenes: list[np.ndarray], poses: np.ndarray,
         starts: np.ndarray) -> tuple[int, float]:
    """``count`` episodes through ``server``, each on a new connection; (steps, seconds)."""
    steps, began = 0, time.perf_counter()
    for n in range(count):
        images, viewpoint = scenes[n % len(scenes)], int(starts[n % starts.size])
        with RecognizerClient(*server.address) as client:
            client.reset(seed=n)
            while True:
                client.observe(images[viewpoint], poses[viewpoint])
                nxt = client.next_view()
                steps += 1
                if nxt.is_declare:
                    break
                viewpoint = nxt.viewpoint
    return steps, time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-w", "--workspace", type=Path, required=True)
    parser.add_argument("--method", default="ra")
    parser.add_argument("--starts", type=int, default=3, help="start viewpoints per model")
    parser.add_argument("--models", type=int, default=10, help="test models at most")
    parser.add_argument("--soak", type=int, default=0, metavar="N",
                        help="then N episodes through the server, each on a new connection: "
                             "open file descriptors and resident memory before and after")
    args = parser.parse_args()
    torch.set_num_threads(1)
    recognizer = ActiveRecognizer.load(args.workspace, args.method, threads=1)
    ws = Workspace(args.workspace)
    config = ws.config()
    dataset = load_dataset(ws.require("dataset"))
    models = dataset.with_role("test")[: args.models]
    rng = np.random.default_rng(0)
    scenes = [(TestViews.of_model(dataset, m, config.viewpoints, config.camera,
                                  config.render.noise).render_all(rng)[1] * 1000.0
               ).astype(np.uint16) for m in models]
    reachable = np.flatnonzero(recognizer.motion.reachable)
    starts = reachable[np.linspace(0, reachable.size - 1, args.starts).astype(int)]
    poses = recognizer.camera_poses_world

    def local(depth: np.ndarray, pose: np.ndarray):
        recognizer.observe(depth, pose)
        return recognizer.next_view()

    steps, seconds = episodes(local, lambda i: recognizer.reset(seed=i), scenes, poses, starts)
    server = RecognizerServer(recognizer, "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    with RecognizerClient(*server.address) as client:
        def remote(depth: np.ndarray, pose: np.ndarray):
            client.observe(depth, pose)
            return client.next_view()

        remote_steps, remote_seconds = episodes(remote, lambda i: client.reset(seed=i),
                                                scenes, poses, starts)
        began = time.perf_counter()
        for _ in range(100):
            client.request({"request": "next_view"})
        ping_ms = (time.perf_counter() - began) * 10.0
    if args.soak > 0:
        fds_before, rss_before = open_fds(), rss_mib()
        soak_steps, soak_seconds = soak(server, args.soak, scenes, poses, starts)
        fds_after, rss_after = open_fds(), rss_mib()
    server.shutdown()
    thread.join(timeout=5)
    height, width = scenes[0].shape[1:]
    print(f"workspace {args.workspace}, method {args.method}, {len(models)} test models x "
          f"{len(starts)} starts, {width}x{height} uint16 images, 1 thread")
    print(f"in process: {steps} steps, {1000 * seconds / steps:.2f} ms per observe + next_view")
    print(f"server on 127.0.0.1: {remote_steps} steps, "
          f"{1000 * remote_seconds / remote_steps:.2f} ms per step, "
          f"{1000 * (remote_seconds / remote_steps - seconds / steps):+.2f} ms added "
          f"(two round trips); one next_view round trip {ping_ms:.3f} ms")
    if args.soak > 0:
        print(f"soak: {args.soak} episodes ({soak_steps} steps, {soak_seconds:.1f} s), each on "
              f"a new connection: open fds {fds_before} -> {fds_after}, resident memory "
              f"{rss_before:.1f} -> {rss_after:.1f} MiB")


if __name__ == "__main__":
    main()
