"""Checkpoints: identical outputs after a round trip; any mismatch is refused by name."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from rapomdp.recognition.classifier import (
    META_FILE,
    WEIGHTS_FILE,
    CheckpointError,
    CheckpointMismatchError,
    Classifier,
    default_threads,
)
from rapomdp.recognition.network import DepthAlexNet, DepthEnsemble, NetworkSpec, build_network
from rapomdp.recognition.preprocess import PreprocessParams

CLASSES = ["cup", "mug", "vase"]
PARAMS = PreprocessParams(input_size_px=32)


@pytest.fixture()
def saved(tmp_path, intrinsics):
    torch.manual_seed(0)
    network = DepthAlexNet(NetworkSpec(len(CLASSES), 32, width=0.125))
    classifier = Classifier(network, CLASSES, PARAMS, intrinsics.fx, intrinsics.fy)
    classifier.save(tmp_path, config_hash="abc123")
    return classifier, tmp_path


def test_round_trip_gives_identical_outputs(saved, render_model):
    classifier, folder = saved
    depth = render_model("mug", np.array([[0.6, 0.0, 0.1], [0.0, -0.6, 0.2], [0.3, 0.3, 0.4]]))
    loaded = Classifier.load(folder / WEIGHTS_FILE, classes=CLASSES, preprocessing=PARAMS,
                             config_hash="abc123", device="cpu", threads=1)
    expected = classifier.predict(depth)
    np.testing.assert_array_equal(loaded.predict(depth), expected)
    assert expected.shape == (3, 3)
    np.testing.assert_allclose(expected.sum(axis=1), 1.0, atol=1e-5)
    # one image gives one row; the folder and the metadata file load the same checkpoint
    np.testing.assert_array_equal(Classifier.load(folder).predict(depth[0]), expected[:1])
    assert Classifier.load(folder / META_FILE).classes == CLASSES
    assert loaded.fx_px == classifier.fx_px and loaded.preprocessing == PARAMS


def test_an_ensemble_checkpoint_loads_as_the_same_ensemble(tmp_path, intrinsics, render_model):
    torch.manual_seed(0)
    network = build_network(NetworkSpec(len(CLASSES), 32, width=0.125, members=3))
    classifier = Classifier(network, CLASSES, PARAMS, intrinsics.fx, intrinsics.fy)
    classifier.save(tmp_path, config_hash="abc123")
    loaded = Classifier.load(tmp_path, classes=CLASSES, device="cpu")
    assert isinstance(loaded.network, DepthEnsemble) and len(loaded.network.members) == 3
    assert json.loads((tmp_path / META_FILE).read_text())["network"]["members"] == 3
    depth = render_model("vase", np.array([[0.6, 0.0, 0.1], [0.0, -0.6, 0.2]]))
    np.testing.assert_array_equal(loaded.predict(depth), classifier.predict(depth))


def test_a_checkpoint_of_a_retired_network_is_refused_naming_its_decision(saved):
    """A depth-only network (a checkpoint before the normals) or a batch-normed one is no
    longer built: the load says so and names the decision page."""
    _, folder = saved
    meta = json.loads((folder / META_FILE).read_text())
    assert meta["network"]["input_features"] == "depth_normals"
    for change in ({"input_features": "depth"}, {"norm": "batch"}):
        (folder / META_FILE).write_text(json.dumps(
            {**meta, "network": {**meta["network"], **change}}))
        with pytest.raises(CheckpointError, match="no longer built .*0019-surface-normals"):
            Classifier.load(folder)


def test_a_checkpoint_written_before_ensembles_loads_as_one_network(saved):
    _, folder = saved
    meta = json.loads((folder / META_FILE).read_text())
    del meta["network"]["members"]  # the metadata of a checkpoint from before the option
    (folder / META_FILE).write_text(json.dumps(meta))
    assert isinstance(Classifier.load(folder).network, DepthAlexNet)


def test_mismatched_class_list_is_refused(saved):
    _, folder = saved
    with pytest.raises(CheckpointMismatchError, match="class list") as info:
        Classifier.load(folder, classes=["cup", "mug", "bottle"])
    message = str(info.value)
    assert str(folder / META_FILE) in message
    assert "missing ['bottle']" in message and "unexpected ['vase']" in message
    with pytest.raises(CheckpointMismatchError, match="another order"):
        Classifier.load(folder, classes=["mug", "cup", "vase"])


def test_mismatched_preprocessing_and_config_hash_are_refused(saved):
    _, folder = saved
    with pytest.raises(CheckpointMismatchError, match="preprocessing parameters"):
        Classifier.load(folder, preprocessing=PreprocessParams(input_size_px=64))
    with pytest.raises(CheckpointMismatchError, match="configuration hash"):
        Classifier.load(folder, config_hash="def456")


def test_corrupt_or_foreign_weights_are_refused(saved):
    _, folder = saved
    weights = folder / WEIGHTS_FILE
    data = bytearray(weights.read_bytes())
    data[-10] ^= 0xFF
    weights.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="SHA-256"):
        Classifier.load(folder)


def test_weights_load_without_unpickling_objects(saved):
    _, folder = saved
    # a checkpoint whose "weights" pickle an arbitrary object: weights_only=True refuses it
    import hashlib
    import io

    buffer = io.BytesIO()
    torch.save({"payload": object()}, buffer)
    (folder / WEIGHTS_FILE).write_bytes(buffer.getvalue())
    meta = json.loads((folder / META_FILE).read_text())
    meta["weights_sha256"] = hashlib.sha256(buffer.getvalue()).hexdigest()
    (folder / META_FILE).write_text(json.dumps(meta))
    with pytest.raises(CheckpointError, match="cannot load weights"):
        Classifier.load(folder)


def test_missing_metadata_names_the_file(tmp_path):
    with pytest.raises(CheckpointError, match=str(tmp_path / META_FILE)):
        Classifier.load(tmp_path)


def test_thread_count_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv("RAPOMDP_THREADS", "3")
    assert default_threads() == 3
    monkeypatch.setenv("RAPOMDP_THREADS", "zero")
    with pytest.raises(ValueError, match="RAPOMDP_THREADS"):
        default_threads()
    monkeypatch.delenv("RAPOMDP_THREADS")
    assert default_threads() >= 1
