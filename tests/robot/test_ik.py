"""Inverse kinematics over the test viewpoints: solutions reach, misses are misses, reproducible."""

from __future__ import annotations

import numpy as np

from rapomdp.robot.arm import CameraArm
from rapomdp.robot.ik import IKSettings, camera_targets, roll_angles, solve_viewpoints
from rapomdp.robot.scene import Scene
from tests.robot.conftest import PANDA_Q_MAX, PANDA_Q_MIN, dh_camera_pose_world


def test_every_solution_reaches_its_viewpoint(solved, arm: CameraArm) -> None:
    s = solved.solutions
    reach = s.reachable
    assert reach.sum() >= 40  # the default placement reaches a good part of X_rho
    centroid = arm.scene.centroid_world
    for i in np.flatnonzero(reach):
        q = s.q_rad[i]
        assert np.all(q >= PANDA_Q_MIN) and np.all(q <= PANDA_Q_MAX)
        pose = dh_camera_pose_world(arm.scene, q)  # independent FK
        assert np.linalg.norm(pose[:3, 3] - solved.viewpoints_m[i]) <= 1e-3
        to_centroid = centroid - pose[:3, 3]
        cosine = pose[:3, 2] @ to_centroid / np.linalg.norm(to_centroid)
        assert np.degrees(np.arccos(min(cosine, 1.0))) <= 0.5
        np.testing.assert_allclose(pose, s.camera_pose_world[i], atol=1e-9)
    assert np.all(np.isnan(s.q_rad[~reach])) and np.all(np.isnan(s.manipulability[~reach]))
    assert np.nanmax(s.position_error_m) <= 1e-3
    assert np.degrees(np.nanmax(s.angle_error_rad)) <= 0.5








def test_target_two_metres_away_is_unreachable(arm: CameraArm) -> None:
    far = arm.scene.base_world[:3, 3] + np.array([2.0, 0.0, 0.4])
    result = solve_viewpoints(arm, far[None], IKSettings(roll_samples=4, restarts=2))
    assert result.reachable.tolist() == [False]
    assert np.isnan(result.q_rad).all() and np.isnan(result.manipulability).all()
    assert result.converged_count.tolist() == [0]


def test_out_of_reach_target_is_unreachable_without_the_prefilter(arm: CameraArm) -> None:
    """The solver itself fails on a far target: ik_LM never returns it as a success."""
    far = arm.scene.base_world[:3, 3] + np.array([2.0, 0.0, 0.4])
    target = arm.to_base(camera_targets(far[None], arm.scene.centroid_world, roll_angles(1)))
    assert not arm.may_reach(target).any()
    q, ok = arm.solve(target[0, 0], arm.ready_rad, iterations=100, tolerance=1e-10)
    assert not ok




def test_camera_targets_look_at_the_centroid_at_every_roll() -> None:
    eyes = np.array([[0.6, 0.0, 0.2], [0.0, 0.3, 0.7], [0.0, 0.0, 0.8]])
    centroid = np.array([0.0, 0.0, 0.2])
    targets = camera_targets(eyes, centroid, roll_angles(5))
    assert targets.shape == (3, 5, 4, 4)
    np.testing.assert_allclose(targets[..., :3, 3], np.repeat(eyes[:, None], 5, axis=1))
    forward = (centroid - eyes) / np.linalg.norm(centroid - eyes, axis=1, keepdims=True)
    np.testing.assert_allclose(targets[..., :3, 2], np.repeat(forward[:, None], 5, axis=1),
                               atol=1e-12)
    rotations = targets[..., :3, :3]
    identity = np.swapaxes(rotations, -1, -2) @ rotations
    np.testing.assert_allclose(identity, np.broadcast_to(np.eye(3), identity.shape), atol=1e-12)


def test_ik_is_reproducible(arm: CameraArm, solved) -> None:
    eyes = solved.viewpoints_m[np.flatnonzero(solved.reachable)[:2]]
    settings = IKSettings(roll_samples=4, restarts=3, seed=5)
    first = solve_viewpoints(arm, eyes, settings)
    second = solve_viewpoints(arm, eyes, settings)
    assert first.reachable.all()
    np.testing.assert_array_equal(first.q_rad, second.q_rad)




def test_a_turned_base_still_reaches_its_targets() -> None:
    """The base pose is applied everywhere: the arm turned 90 deg about Z, placed to match."""
    from rapomdp.config import RobotConfig

    scene = Scene.from_config(RobotConfig(base_xyz_m=(0.0, -0.4, 0.2), base_yaw_deg=90.0))
    turned = CameraArm(scene)
    eyes = scene.viewpoints_world(16, 0.6)
    result = solve_viewpoints(turned, eyes, IKSettings(roll_samples=4, restarts=2))
    assert result.reachable.sum() >= 5
    for i in np.flatnonzero(result.reachable):
        pose = dh_camera_pose_world(scene, result.q_rad[i])
        assert np.linalg.norm(pose[:3, 3] - eyes[i]) <= 1e-3
