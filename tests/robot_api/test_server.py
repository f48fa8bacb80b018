"""The robot API's server on 127.0.0.1 (an ephemeral port, in a thread): its answers are the
object's, every malformed message gets its named error, and it keeps serving."""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Iterator
from dataclasses import fields

import msgpack
import numpy as np
import pytest

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.robot_api.recognizer import ActiveRecognizer
from rapomdp.robot_api.server import RecognizerClient, RecognizerServer, RemoteError
from rapomdp.robot_api.wire import decode_array, encode_array, pack


@pytest.fixture(scope="module")
def server(pipeline_workspace) -> Iterator[RecognizerServer]:
    """The tiny workspace's RA-POMDP served on 127.0.0.1, a port the system picks, with a
    64 KiB message limit (the tiny images are 6 KiB)."""
    ws, _ = pipeline_workspace
    running = RecognizerServer(ActiveRecognizer.load(ws.root, "ra"), "127.0.0.1", 0,
                               max_message_bytes=64 * 2**10, idle_timeout_s=30.0)
    thread = threading.Thread(target=running.serve_forever, daemon=True)
    thread.start()
    yield running
    running.shutdown()
    thread.join(timeout=5)
    assert not thread.is_alive()


def same(a: object, b: object) -> None:
    """Two answers field by field (arrays exactly, NaN equal to NaN)."""
    assert type(a) is type(b)
    for item in fields(a):  # type: ignore[arg-type]
        x, y = getattr(a, item.name), getattr(b, item.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
        elif isinstance(x, float) and np.isnan(x):
            assert np.isnan(y)
        else:
            assert x == y, item.name


def test_the_servers_answers_equal_the_objects(pipeline_workspace, recognizer, server) -> None:
    """Every test model's episode from a reachable start, through the client and in process:
    the same observations and next views, field by field."""
    ws, config = pipeline_workspace
    dataset = load_dataset(ws.require("dataset"))
    starts = np.flatnonzero(recognizer.motion.reachable)
    assert server.address[0] == "127.0.0.1"
    with RecognizerClient(*server.address) as client:
        info = client.info()
        assert info["classes"] == recognizer.classes and info["method"] == "ra"
        np.testing.assert_array_equal(info["viewpoints_m"], recognizer.viewpoints_m)
        steps = 0
        for i, model in enumerate(dataset.with_role("test")):
            scene = TestViews.of_model(dataset, model, config.viewpoints, config.camera,
                                       config.render.noise)
            client.reset(seed=i)
            recognizer.reset(seed=i)
            viewpoint = int(starts[i % starts.size])
            while True:
                depth = (scene.look(viewpoint, np.random.default_rng()) * 1000).astype(np.uint16)
                pose = recognizer.camera_poses_world[viewpoint]
                same(client.observe(depth, pose), recognizer.observe(depth, pose))
                remote, local = client.next_view(), recognizer.next_view()
                same(remote, local)
                steps += 1
                if local.is_declare:
                    break
                viewpoint = local.viewpoint
        assert steps > 3


def raw_request(connection: socket.socket, frame: bytes) -> dict:
    connection.sendall(frame)
    (length,) = struct.unpack(">I", connection.recv(4, socket.MSG_WAITALL))
    return msgpack.unpackb(connection.recv(length, socket.MSG_WAITALL), raw=False)


def frame(body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + body


def observe_with(depth: dict, **extra: object) -> bytes:
    return pack({"request": "observe", "depth": depth, "viewpoint": 0, **extra})


GOOD_DEPTH = encode_array(np.zeros((48, 64), dtype=np.float32))
#: Each malformed message and the error it must get.
MALFORMED = {
    "not msgpack": (frame(b"\xc1\xc1\xc1"), "malformed"),
    "a list, not a map": (frame(msgpack.packb([1, 2])), "malformed"),
    "no request field": (pack({"seed": 1}), "malformed"),
    "an extension type": (frame(msgpack.packb({"request": msgpack.ExtType(1, b"x")})),
                          "malformed"),
    "an unknown request": (pack({"request": "fly"}), "unknown_request"),
    "an object dtype": (observe_with({"dtype": "|O", "shape": [1],
                                      "bytes": b"\0" * 8}), "bad_array"),
    "a pickle-like dtype string": (observe_with({"dtype": "V8", "shape": [1],
                                                 "bytes": b"\0" * 8}), "bad_array"),
    "bytes short of the shape": (observe_with({"dtype": "<f4", "shape": [48, 64],
                                               "bytes": b"\0" * 10}), "bad_array"),
    "oversized": (frame(b"\0" * (64 * 2**10 + 1)), "too_large"),
    "observe before reset": (observe_with(GOOD_DEPTH), "out_of_order"),
    "a bad seed": (pack({"request": "reset", "seed": "x"}), "bad_value"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_a_malformed_message_gets_its_named_error_and_the_next_is_served(server,
                                                                        case: str) -> None:
    message, error = MALFORMED[case]
    with socket.create_connection(server.address, timeout=30) as connection:
        reply = raw_request(connection, message)
        assert reply["ok"] is False and reply["error"] == error, reply
        assert reply["message"]
        good = raw_request(connection, pack({"request": "info"}))
        assert good["ok"] is True and good["method"] == "ra"


def test_requests_out_of_order_and_bad_values_are_named(server, recognizer) -> None:
    with RecognizerClient(*server.address) as client:
        client.reset(seed=0)
        with pytest.raises(RemoteError) as caught:
            client.next_view()
        assert caught.value.code == "out_of_order"
        with pytest.raises(RemoteError) as caught:
            client.observe(np.zeros((48, 64), dtype=np.float32), np.eye(3))
        assert caught.value.code == "bad_value" and "(4, 4)" in str(caught.value)
        with pytest.raises(RemoteError) as caught:
            client.observe(np.zeros((48, 64), dtype=np.int32), viewpoint=0)
        assert caught.value.code == "bad_value" and "uint16" in str(caught.value)
        assert client.info()["method"] == "ra"


def test_a_client_that_leaves_mid_episode_leaves_the_server_serving(server, recognizer
                                                                    ) -> None:
    start = int(np.flatnonzero(recognizer.motion.reachable)[0])
    depth = np.zeros((48, 64), dtype=np.float32)
    depth[20:28, 28:36] = 0.55
    first = RecognizerClient(*server.address)
    first.reset(seed=0)
    first.observe(depth, viewpoint=start)
    first.close()  # mid-episode
    with RecognizerClient(*server.address) as second:
        with pytest.raises(RemoteError) as caught:  # the next client starts with no episode
            second.observe(depth, viewpoint=start)
        assert caught.value.code == "out_of_order"
        second.reset(seed=0)
        assert second.observe(depth, viewpoint=start).moves == 0


def test_arrays_round_trip_and_refuse_what_is_not_numbers() -> None:
    for array in (np.arange(6, dtype="<u2").reshape(2, 3), np.eye(4), np.array([True])):
        back = decode_array(encode_array(array), "a")
        assert back.dtype == array.dtype and np.array_equal(back, array)
    with pytest.raises(ValueError, match="not sent"):
        encode_array(np.array([object()]))


def test_rapomdp_serve_serves_the_workspace_on_localhost(pipeline_workspace) -> None:
    """``rapomdp serve -w W --port 0`` in a subprocess: it says where it listens (127.0.0.1)
    and answers a client; it is stopped by its process id."""
    import os
    import re
    import subprocess
    import sys
    from pathlib import Path

    ws, _ = pipeline_workspace
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root / "src"), "OMP_NUM_THREADS": "1",
           "COLUMNS": "200"}
    process = subprocess.Popen([sys.executable, "-m", "rapomdp.cli", "serve", "-w", str(ws.root),
                                "--method", "static", "--port", "0"],
                               stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                               env=env)
    try:
        assert process.stderr is not None
        line = process.stderr.readline()
        found = re.search(r"on 127\.0\.0\.1:(\d+)", line)
        assert found, line
        with RecognizerClient("127.0.0.1", int(found.group(1))) as client:
            assert client.info()["method"] == "static"
            client.reset(seed=0)
            seen = client.observe(np.zeros((48, 64), dtype=np.uint16), viewpoint=0)
            assert seen.done and client.next_view().is_declare
    finally:
        process.terminate()
        process.wait(timeout=30)
