"""Test-view rendering: one model seen from X_rho, its noise drawn from a named stream."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import (
    TEST_STREAM,
    VOLUME_STREAM,
    TestViews,
    xrho_noise_rng,
    xrho_renders,
)
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT, tiny_config


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory):
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    run_pipeline(tiny_config(), ws, until="dataset", context=TEST_CONTEXT)
    return load_dataset(ws.require("dataset"))


def test_without_noise_every_view_is_the_clean_render(dataset) -> None:
    config = tiny_config()
    model = dataset.with_role("test")[0]
    views = TestViews.of_model(config, dataset, model)
    assert views.poses.shape == (config.viewpoints.count, 4, 4)
    clean, sensed, poses = xrho_renders(dataset, model, config, TEST_STREAM)
    assert sensed is clean and np.array_equal(poses, views.poses)
    assert clean.shape == (config.viewpoints.count, config.camera.height, config.camera.width)
    assert (clean > 0).any(axis=(1, 2)).all()  # the model is in every view
    assert np.array_equal(views.look(3, np.random.default_rng(0)), clean[3])


def test_noise_streams_are_keyed_by_purpose_and_model(dataset) -> None:
    config = tiny_config(render={"views": 6, "noise": {"enabled": True}})
    model = dataset.with_role("test")[0]
    clean, sensed, _ = xrho_renders(dataset, model, config, TEST_STREAM)
    again = xrho_renders(dataset, model, config, TEST_STREAM)[1]
    other = xrho_renders(dataset, model, config, VOLUME_STREAM)[1]
    assert np.array_equal(sensed, again)  # the same stream, the same images
    assert not np.array_equal(sensed, clean) and not np.array_equal(sensed, other)
    views = TestViews.of_model(config, dataset, model)
    assert np.array_equal(views.sensed(xrho_noise_rng(config.seed, TEST_STREAM, model)), sensed)
    seen = sensed > 0
    assert np.abs(sensed[seen] - clean[seen]).max() < 0.05  # axial noise, centimetres


def test_the_stream_depends_on_the_model(dataset) -> None:
    a, b = dataset.with_role("test")[:2]
    first = xrho_noise_rng(3, TEST_STREAM, a).random(4)
    assert np.array_equal(first, xrho_noise_rng(3, TEST_STREAM, a).random(4))
    assert not np.array_equal(first, xrho_noise_rng(3, TEST_STREAM, b).random(4))
    assert not np.array_equal(first, xrho_noise_rng(4, TEST_STREAM, a).random(4))
