"""A bounded soak of the robot API's server: 50 episodes through the client, each on a new
connection, answer as the in-process object does, and the process's open file descriptors and
traced memory do not grow."""

from __future__ import annotations

import gc
import os
import sys
import threading
import tracemalloc
from dataclasses import fields

import numpy as np
import pytest

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.robot_api.recognizer import ActiveRecognizer
from rapomdp.robot_api.server import RecognizerClient, RecognizerServer

#: Episodes of the soak, after the warm-up's.
EPISODES = 50
WARM_UP = 5
#: How much the traced memory may grow over the soak (bytes): far less than one episode's
#: images kept per episode would take (50 x 7 x 6 KiB).
MEMORY_BOUND = 512 * 2**10


def open_fds() -> int | None:
    """This process's open file descriptors (None where /proc is not there)."""
    return len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else None


def equal(a: object, b: object) -> bool:
    """Two answers field by field (arrays exactly, NaN equal to NaN)."""
    for item in fields(a):  # type: ignore[arg-type]
        x, y = getattr(a, item.name), getattr(b, item.name)
        if isinstance(x, np.ndarray):
            if not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
                return False
        elif isinstance(x, float) and np.isnan(x):
            if not np.isnan(y):
                return False
        elif x != y:
            return False
    return True


@pytest.mark.skipif(sys.platform != "linux", reason="counts /proc/self/fd")
def test_fifty_episodes_through_the_server_leak_nothing(pipeline_workspace, recognizer
                                                        ) -> None:
    ws, config = pipeline_workspace
    dataset = load_dataset(ws.require("dataset"))
    rng = np.random.default_rng(0)
    scenes = [(TestViews.of_model(dataset, m, config.viewpoints, config.camera,
                                  config.render.noise).render_all(rng)[1] * 1000.0
               ).astype(np.uint16) for m in dataset.with_role("test")]
    starts = np.flatnonzero(recognizer.motion.reachable)
    poses = recognizer.camera_poses_world
    base_fds = open_fds()
    server = RecognizerServer(ActiveRecognizer.load(ws.root, "ra"), "127.0.0.1", 0,
                              idle_timeout_s=30.0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()

    def episode(n: int) -> tuple[int, bool]:
        """Episode n on a new connection; (steps, every answer equal to the object's)."""
        images = scenes[n % len(scenes)]
        viewpoint = int(starts[n % starts.size])
        same, steps = True, 0
        with RecognizerClient(*server.address) as client:
            client.reset(seed=n)
            recognizer.reset(seed=n)
            while True:
                pose = poses[viewpoint]
                same &= equal(client.observe(images[viewpoint], pose),
                              recognizer.observe(images[viewpoint], pose))
                remote, local = client.next_view(), recognizer.next_view()
                same &= equal(remote, local)
                steps += 1
                if local.is_declare:
                    return steps, same
                viewpoint = local.viewpoint

    try:
        for n in range(WARM_UP):
            episode(n)
        gc.collect()
        fds_before = open_fds()
        tracemalloc.start()
        memory_before = tracemalloc.get_traced_memory()[0]
        steps = 0
        for n in range(WARM_UP, WARM_UP + EPISODES):
            taken, same = episode(n)
            assert same, f"episode {n}: the server's answers differ from the object's"
            steps += taken
        gc.collect()
        memory_after = tracemalloc.get_traced_memory()[0]
        tracemalloc.stop()
        fds_after = open_fds()
    finally:
        server.shutdown()
        thread.join(timeout=5)
    assert not thread.is_alive()
    assert steps > EPISODES  # most episodes move at least once
    assert fds_after is not None and fds_before is not None
    assert fds_after <= fds_before + 1, (fds_before, fds_after)
    assert memory_after - memory_before < MEMORY_BOUND, (memory_before, memory_after)
    assert open_fds() <= base_fds + 1  # the listening socket is closed at shutdown
