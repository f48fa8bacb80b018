"""Test-view rendering: one model seen from X_rho, its noise drawn from a named stream."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.config import CameraConfig, NoiseConfig, ViewpointsConfig, config_from_dict
from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import (
    TEST_STREAM,
    VOLUME_STREAM,
    XRHO_FILE,
    TestViews,
    load_xrho_views,
    xrho_noise_rng,
    xrho_renders,
)
from rapomdp.io import read_json
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import StageError, Workspace
from tests.conftest import TEST_CONTEXT, TINY_PIPELINE, tiny_config


def _renders(dataset, model, config, stream):
    """:func:`xrho_renders` with a whole configuration's sections, as the xrho stage calls it."""
    return xrho_renders(dataset, model, stream, config.seed, config.viewpoints, config.camera,
                        config.render.noise)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory):
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    run_pipeline(tiny_config(), ws, until="dataset", context=TEST_CONTEXT)
    return load_dataset(ws.require("dataset"))


def test_without_noise_every_view_is_the_clean_render(dataset) -> None:
    config = tiny_config()
    model = dataset.with_role("test")[0]
    views = TestViews.of_model(dataset, model, config.viewpoints, config.camera,
                                  config.render.noise)
    assert views.poses.shape == (config.viewpoints.count, 4, 4)
    clean, sensed, poses = _renders(dataset, model, config, TEST_STREAM)
    assert sensed is clean and np.array_equal(poses, views.poses)
    assert clean.shape == (config.viewpoints.count, config.camera.height, config.camera.width)
    assert (clean > 0).any(axis=(1, 2)).all()  # the model is in every view
    assert np.array_equal(views.look(3, np.random.default_rng(0)), clean[3])


def test_test_views_and_xrho_renders_without_a_pipeline_configuration(dataset) -> None:
    model = dataset.with_role("test")[0]
    views = TestViews.of_model(dataset, model)  # the default sections: X_rho of 128, no noise
    assert views.poses.shape == (128, 4, 4) and views.noise == NoiseConfig()
    np.testing.assert_allclose(np.linalg.norm(views.poses[:, :3, 3] - model.centroid, axis=1), 0.6)
    viewpoints, camera = ViewpointsConfig(count=5, radius_m=0.5), CameraConfig(width=24, height=16)
    noise = NoiseConfig(enabled=True)
    clean, sensed, poses = xrho_renders(dataset, model, TEST_STREAM, 3, viewpoints, camera, noise)
    assert clean.shape == sensed.shape == (5, 16, 24) and poses.shape == (5, 4, 4)
    np.testing.assert_allclose(np.linalg.norm(poses[:, :3, 3] - model.centroid, axis=1), 0.5)
    assert 0.3 < clean[clean > 0].min() and clean.max() < 0.7  # the model, 0.5 m away
    # the same sections give what the xrho stage renders from a whole configuration
    config = tiny_config(viewpoints={"count": 5, "radius_m": 0.5},
                         camera={"width": 24, "height": 16}, render={"noise": {"enabled": True}})
    again = _renders(dataset, model, config, TEST_STREAM)
    assert all(np.array_equal(a, b) for a, b in zip((clean, sensed, poses), again, strict=True))
    assert not np.array_equal(sensed, clean)


def test_noise_streams_are_keyed_by_purpose_and_model(dataset) -> None:
    config = tiny_config(render={"views": 6, "noise": {"enabled": True}})
    model = dataset.with_role("test")[0]
    clean, sensed, _ = _renders(dataset, model, config, TEST_STREAM)
    again = _renders(dataset, model, config, TEST_STREAM)[1]
    other = _renders(dataset, model, config, VOLUME_STREAM)[1]
    assert np.array_equal(sensed, again)  # the same stream, the same images
    assert not np.array_equal(sensed, clean) and not np.array_equal(sensed, other)
    views = TestViews.of_model(dataset, model, config.viewpoints, config.camera,
                                  config.render.noise)
    assert np.array_equal(views.sensed(xrho_noise_rng(config.seed, TEST_STREAM, model)), sensed)
    seen = sensed > 0
    assert np.abs(sensed[seen] - clean[seen]).max() < 0.05  # axial noise, centimetres


def test_the_stream_depends_on_the_model(dataset) -> None:
    a, b = dataset.with_role("test")[:2]
    first = xrho_noise_rng(3, TEST_STREAM, a).random(4)
    assert np.array_equal(first, xrho_noise_rng(3, TEST_STREAM, a).random(4))
    assert not np.array_equal(first, xrho_noise_rng(3, TEST_STREAM, b).random(4))
    assert not np.array_equal(first, xrho_noise_rng(4, TEST_STREAM, a).random(4))


def test_the_xrho_stage_stores_each_models_images_of_its_own_stream(tmp_path) -> None:
    config = tiny_config(render={"views": 6, "noise": {"enabled": True}})
    ws = Workspace(tmp_path / "ws")
    run_pipeline(config, ws, until="xrho", context=TEST_CONTEXT)
    dataset = load_dataset(ws.require("dataset"))
    images = load_xrho_views(ws.require("xrho"), dataset)
    record = read_json(ws.require("xrho") / XRHO_FILE)
    rendered = [m for m in dataset.models if m.role in ("volume", "test")]
    assert [(m["class"], m["id"], m["role"]) for m in record["models"]] == [
        (m.class_name, m.id, m.role) for m in rendered]
    for model in rendered:
        stream = VOLUME_STREAM if model.role == "volume" else TEST_STREAM
        clean, sensed, poses = _renders(dataset, model, config, stream)
        stored = images.load(model)
        assert np.array_equal(stored.sensed, sensed) and np.array_equal(stored.clean, clean)
        assert np.array_equal(stored.poses, poses)
    with pytest.raises(StageError, match=r"\(a train model\); the xrho stage renders the volume"):
        images.load(dataset.with_role("train")[0])


def test_every_consumer_reads_the_one_render_of_each_model(tmp_path, monkeypatch) -> None:
    calls: list[int] = []
    render_all = TestViews.render_all

    def counted(self: TestViews, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        calls.append(1)
        return render_all(self, rng)

    monkeypatch.setattr(TestViews, "render_all", counted)
    config = config_from_dict({**tiny_config().model_dump(), **TINY_PIPELINE})
    ws = Workspace(tmp_path / "ws")
    results = run_pipeline(config, ws, until="observe", context=TEST_CONTEXT)
    results += run_pipeline(config, ws, until="vptree", context=TEST_CONTEXT)
    dataset = load_dataset(ws.require("dataset"))
    # one render per volume and test model, by the xrho stage alone, for classifier_eval,
    # observe and vptree
    assert len(calls) == len(dataset.with_role("volume")) + len(dataset.with_role("test"))
    assert [r.name for r in results if not r.cached].count("xrho") == 1
    stages = ws.manifest()["stages"]
    for name in ("classifier_eval", "observe", "vptree"):
        assert stages[name]["input_keys"]["xrho"] == stages["xrho"]["key"]
