"""The robot API's object: the closed loop's actions and declarations from real depth images."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.evaluation import episode_rng
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.robot_api.recognizer import (
    ActiveRecognizer,
    OutOfOrderError,
    depth_in_metres,
    intrinsics_for,
)
from tests.experiment.conftest import METHODS


def scenes(ws, config):
    dataset = load_dataset(ws.require("dataset"))
    return {m.file: TestViews.of_model(dataset, m, config.viewpoints, config.camera,
                                       config.render.noise)
            for m in dataset.with_role("test")}, {m.file: m for m in dataset.with_role("test")}


@pytest.mark.parametrize("method", METHODS)
def test_the_object_takes_the_closed_loops_actions_episode_for_episode(
        pipeline_workspace, method: str) -> None:
    """Fed each rendered image with the camera pose the IK reaches, the object moves, believes
    and declares as the evaluate stage's episodes did (every test model x start)."""
    ws, config = pipeline_workspace
    table = EpisodeTable.load(ws.require("evaluate") / EPISODES_FILE)
    recognizer = ActiveRecognizer.load(ws.root, method)
    views, models = scenes(ws, config)
    mine = np.flatnonzero(table.method == method)
    assert mine.size == 9  # 3 test models x 3 starts
    for e in mine:
        model, start = models[str(table.model[e])], int(table.start[e])
        recognizer.reset(rng=episode_rng(config.seed, model, start, method))
        viewpoint, seen, beliefs = start, [start], []
        while True:
            depth = views[model.file].look(viewpoint, np.random.default_rng())
            observed = recognizer.observe(depth, recognizer.camera_poses_world[viewpoint])
            # the IK reaches the viewpoint to within its tolerance
            assert observed.viewpoint == viewpoint and observed.off_viewpoint_m < 1e-4
            beliefs.append(observed.belief)
            step = recognizer.next_view()
            if step.is_declare:
                break
            assert step.energy_m == recognizer.motion.energy[viewpoint, step.viewpoint]
            np.testing.assert_array_equal(step.q_rad, recognizer.q_rad[step.viewpoint])
            viewpoint = step.viewpoint
            seen.append(viewpoint)
        assert seen == table.viewpoints_of(e).tolist()
        assert step.declared_class == int(table.declared[e])
        assert observed.done and observed.declared_class == step.declared_class
        rows = slice(table.offsets[e], table.offsets[e + 1])
        np.testing.assert_allclose(np.stack(beliefs), table.step_beliefs[rows], atol=1e-5)
        assert step.declared_confidence == pytest.approx(
            float(table.final_confidence()[e]), abs=1e-5)
        assert recognizer.visited == seen


def test_millimetres_and_metres_give_the_same_answer(pipeline_workspace, recognizer) -> None:
    """A uint16 image in millimetres, and the same depths as float metres with NaN holes,
    give the same probabilities, belief and declaration."""
    ws, config = pipeline_workspace
    views, _ = scenes(ws, config)
    scene = next(iter(views.values()))
    viewpoint = int(np.flatnonzero(recognizer.motion.reachable)[0])
    millimetres = np.round(scene.look(viewpoint, np.random.default_rng()) * 1000.0
                           ).astype(np.uint16)
    assert (millimetres == 0).any() and (millimetres > 0).any()
    metres = millimetres / 1000.0
    metres[millimetres == 0] = np.nan
    camera = xtion_intrinsics(config.camera.width, config.camera.height)
    intrinsics = {"fx": camera.fx, "fy": camera.fy, "cx": camera.cx, "cy": camera.cy}
    answers = []
    for depth in (millimetres, metres.astype(np.float32), metres):
        recognizer.reset(seed=0)
        answers.append(recognizer.observe(depth, viewpoint=viewpoint, intrinsics=intrinsics))
    for other in answers[1:]:
        np.testing.assert_allclose(other.output, answers[0].output, atol=1e-6)
        np.testing.assert_allclose(other.belief, answers[0].belief, atol=1e-6)
        assert other.declared_class == answers[0].declared_class
    np.testing.assert_array_equal(depth_in_metres(metres)[millimetres == 0], 0.0)
    assert depth_in_metres(millimetres).dtype == np.float32


def test_a_pose_off_the_viewsphere_maps_to_the_nearest_viewpoint(recognizer) -> None:
    """A camera 5 cm behind a viewpoint (off the sphere, along its optical axis) counts as
    that viewpoint, and the answer says it was 0.05 m off."""
    for viewpoint in np.flatnonzero(recognizer.motion.reachable)[:3]:
        pose = recognizer.camera_poses_world[viewpoint].copy()
        # the viewpoint's centre, moved back along the optical axis
        pose[:3, 3] = recognizer.viewpoints_m[viewpoint] - 0.05 * pose[:3, 2]
        recognizer.reset(seed=0)
        observed = recognizer.observe_output(np.full(len(recognizer.classes), 0.5), pose)
        assert observed.viewpoint == viewpoint
        assert observed.off_viewpoint_m == pytest.approx(0.05, abs=1e-12)
    index, gap_m = recognizer.nearest_viewpoint(recognizer.camera_poses_world[viewpoint])
    assert (index, gap_m) == (viewpoint, pytest.approx(0.0, abs=1e-4))  # the IK's error


def test_calls_out_of_order_are_refused_by_name(recognizer) -> None:
    recognizer.forget()
    probabilities = np.array([0.1, 0.8, 0.1])
    with pytest.raises(OutOfOrderError) as caught:
        recognizer.observe_output(probabilities, viewpoint=0)
    assert caught.value.code == "not_reset"
    recognizer.reset(seed=0)
    with pytest.raises(OutOfOrderError) as caught:
        recognizer.next_view()
    assert caught.value.code == "no_observation"
    start = int(np.flatnonzero(recognizer.motion.reachable)[0])
    for _ in range(recognizer.max_moves + 1):
        observed = recognizer.observe_output(probabilities, viewpoint=start)
        if observed.done:
            break
        start = recognizer.next_view().viewpoint
    assert observed.done and recognizer.next_view().is_declare
    with pytest.raises(OutOfOrderError) as caught:
        recognizer.observe_output(probabilities, viewpoint=start)
    assert caught.value.code == "episode_over"


def test_bad_images_and_poses_are_refused_naming_the_problem(recognizer) -> None:
    recognizer.reset(seed=0)
    with pytest.raises(ValueError, match="uint16 millimetres or float metres"):
        recognizer.observe(np.ones((48, 64), dtype=np.int32), viewpoint=0)
    with pytest.raises(ValueError, match="millimetres\\?"):
        recognizer.observe(np.full((48, 64), 650.0, dtype=np.float32), viewpoint=0)
    with pytest.raises(ValueError, match=r"must be \(H, W\)"):
        recognizer.observe(np.ones((2, 48, 64), dtype=np.float32), viewpoint=0)
    with pytest.raises(ValueError, match="exactly one of camera_pose and viewpoint"):
        recognizer.observe(np.ones((48, 64), dtype=np.float32))
    with pytest.raises(ValueError, match="last row"):
        recognizer.observe_output(np.full(3, 1 / 3), np.zeros((4, 4)))
    with pytest.raises(ValueError, match="intrinsics lack"):
        intrinsics_for(np.ones((48, 64)), {"fx": 50.0})
    with pytest.raises(ValueError, match="method 'nope'"):
        ActiveRecognizer.load(".", "nope")


def test_an_image_at_another_resolution_with_its_intrinsics_reads_the_same(
        pipeline_workspace, recognizer) -> None:
    """The same views rendered at 160 x 120 instead of the workspace's 64 x 48, classified with
    that camera's fx, fy: the CNN's probabilities agree to 0.005 (its crop is sized in metres)."""
    ws, config = pipeline_workspace
    dataset = load_dataset(ws.require("dataset"))
    model = dataset.with_role("test")[0]
    native = TestViews.of_model(dataset, model, config.viewpoints, config.camera,
                                config.render.noise)
    large = TestViews.of_model(dataset, model, config.viewpoints,
                               config.camera.model_copy(update={"width": 160, "height": 120}),
                               config.render.noise)
    camera = xtion_intrinsics(160, 120)
    intrinsics = {"fx": camera.fx, "fy": camera.fy, "cx": camera.cx, "cy": camera.cy}
    for viewpoint in (0, 5, 10):
        small = recognizer.classify(native.look(viewpoint, np.random.default_rng()))
        big = recognizer.classify(large.look(viewpoint, np.random.default_rng()), intrinsics)
        np.testing.assert_allclose(big, small, atol=0.005)
        assert big.argmax() == small.argmax()
