import numpy as np
import pytest

from rapomdp.geometry.camera import (
    Intrinsics,
    back_project,
    look_at,
    look_at_many,
    pixel_directions,
    project,
    xtion_intrinsics,
)
from rapomdp.geometry.viewsphere import viewpoints


def test_xtion_field_of_view_at_any_resolution() -> None:
    for width, height in [(640, 480), (160, 120), (80, 60)]:
        k = xtion_intrinsics(width, height)
        h, v = k.fov_deg
        assert h == pytest.approx(58.0, abs=1e-9)
        assert v == pytest.approx(45.0, abs=0.2)
    assert xtion_intrinsics().fx == pytest.approx(320 / np.tan(np.radians(29)))
    assert xtion_intrinsics(160, 120).cx == pytest.approx(79.5)


def test_poses_are_rigid_and_look_at_the_target() -> None:
    target = np.array([0.0, 0.0, 0.2])
    eyes = viewpoints(50, 0.6, hemisphere=True, centre=target)
    poses = look_at_many(eyes, target)
    rotations = poses[:, :3, :3]
    np.testing.assert_allclose(rotations @ rotations.transpose(0, 2, 1),
                               np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rotations), 1.0, atol=1e-12)
    # the optical axis (camera z) points at the target
    axis = (target - eyes) / 0.6
    np.testing.assert_allclose(rotations[:, :, 2], axis, atol=1e-12)
    # the target projects to the principal point
    k = xtion_intrinsics(160, 120)
    uv, z = project(target[None], poses, k)
    np.testing.assert_allclose(uv[:, 0], np.tile([k.cx, k.cy], (50, 1)), atol=1e-9)
    np.testing.assert_allclose(z[:, 0], np.full(50, 0.6))


def test_look_at_is_well_defined_at_the_pole() -> None:
    pose = look_at(np.array([0.0, 0.0, 0.8]), np.array([0.0, 0.0, 0.2]))
    assert np.all(np.isfinite(pose))
    np.testing.assert_allclose(pose[:3, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)
    # at the pole image right is world +Y and image up (-y) world -X, the documented limit
    np.testing.assert_allclose(pose[:3, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(-pose[:3, 1], [-1, 0, 0], atol=1e-12)
    # a camera just off the pole on the +X meridian has the same orientation (no flip)
    near = look_at(np.array([1e-4, 0.0, 0.8]), np.array([0.0, 0.0, 0.2]))
    np.testing.assert_allclose(near[:3, :3], pose[:3, :3], atol=1e-3)


def test_look_at_refuses_a_camera_on_its_target() -> None:
    with pytest.raises(ValueError, match="sits at its target"):
        look_at(np.zeros(3), np.zeros(3))


def test_project_back_project_round_trip() -> None:
    rng = np.random.default_rng(0)
    k = xtion_intrinsics(64, 48)
    poses = look_at_many(viewpoints(5, 0.6), np.zeros(3))
    depth = rng.uniform(0.3, 0.9, size=(5, 48, 64))
    points = back_project(depth, poses, k)
    assert points.shape == (5, 48, 64, 3)
    for i in range(5):
        uv, z = project(points[i].reshape(-1, 3), poses[i], k)
        np.testing.assert_allclose(z, depth[i].ravel(), atol=1e-12)
        v, u = np.mgrid[0:48, 0:64]
        np.testing.assert_allclose(uv, np.stack([u.ravel(), v.ravel()], 1), atol=1e-9)


def test_back_project_broadcasts_images_and_poses_like_one_image_at_a_time() -> None:
    rng = np.random.default_rng(1)
    k = xtion_intrinsics(16, 12)
    poses = look_at_many(viewpoints(3, 0.6), np.zeros(3))
    depth = rng.uniform(0.3, 0.9, size=(3, 12, 16))
    each = np.stack([back_project(depth[i], poses[i], k) for i in range(3)])
    np.testing.assert_allclose(back_project(depth, poses, k), each, rtol=0, atol=1e-15)
    # one pose for a batch of images, and one image seen from a batch of poses
    shared = back_project(depth, poses[0], k)
    assert shared.shape == (3, 12, 16, 3)
    np.testing.assert_allclose(shared[2], back_project(depth[2], poses[0], k), atol=1e-15)
    fanned = back_project(depth[0], poses, k)
    assert fanned.shape == (3, 12, 16, 3)
    np.testing.assert_allclose(fanned[1], back_project(depth[0], poses[1], k), atol=1e-15)
    # the camera centre is where a zero depth lands
    np.testing.assert_allclose(back_project(np.zeros((12, 16)), poses[1], k),
                               np.broadcast_to(poses[1, :3, 3], (12, 16, 3)))


def test_pixel_directions_have_unit_z_and_hit_pixel_centres() -> None:
    k = Intrinsics(4, 3, fx=2.0, fy=2.0, cx=1.5, cy=1.0)
    d = pixel_directions(k)
    assert d.shape == (12, 3)
    np.testing.assert_allclose(d[:, 2], 1.0)
    np.testing.assert_allclose(d[0], [-0.75, -0.5, 1.0])


def test_back_project_checks_the_image_size() -> None:
    with pytest.raises(ValueError, match="intrinsics expect 160x120"):
        back_project(np.zeros((10, 10)), np.eye(4), xtion_intrinsics(160, 120))
