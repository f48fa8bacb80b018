import numpy as np
import pytest
import trimesh

from rapomdp.data.renderer import DepthRenderer, incidence_angles
from rapomdp.geometry.camera import back_project, look_at, look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints


def _tilted_plane() -> trimesh.Trimesh:
    # z = 0.25 x + 0.125 y + 0.0625, corners exactly representable in float32
    xy = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    z = 0.25 * xy[:, 0] + 0.125 * xy[:, 1] + 0.0625
    vertices = np.column_stack([xy, z])
    return trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False)


def test_plane_depth_matches_the_analytic_depth() -> None:
    k = xtion_intrinsics(160, 120)
    normal = np.array([-0.25, -0.125, 1.0])
    point = np.array([0.0, 0.0, 0.0625])
    poses = look_at_many(np.array([[0.3, -0.2, 0.7], [0.0, 0.0, 0.6], [-0.5, 0.1, 0.4]]), point)
    depth = DepthRenderer(_tilted_plane(), k).render(poses)
    x, y = np.meshgrid((np.arange(160) - k.cx) / k.fx, (np.arange(120) - k.cy) / k.fy)
    rays = np.stack([x, y, np.ones_like(x)], axis=-1)
    for i, pose in enumerate(poses):
        world = rays @ pose[:3, :3].T
        expected = normal @ (point - pose[:3, 3]) / (world @ normal)
        assert np.all(depth[i] > 0)
        np.testing.assert_allclose(depth[i], expected, atol=1e-6, rtol=0)


def test_sphere_depth_matches_the_sphere_and_its_triangles() -> None:
    radius = 0.2
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    k = xtion_intrinsics(80, 60)
    pose = look_at(np.array([0.35, -0.3, 0.35]), np.zeros(3))
    renderer = DepthRenderer(sphere, k)
    depth, faces = renderer.render_faces(pose)
    centre_cam = pose[:3, 3]
    _, directions = renderer.rays(pose)
    rays = directions.astype(np.float64)
    # the analytic sphere: ray-sphere intersection of every pixel
    b = rays @ centre_cam
    a = np.einsum("ij,ij->i", rays, rays)
    disc = b**2 - a * (centre_cam @ centre_cam - radius**2)
    t_sphere = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / a, np.inf)
    flat_depth = depth.ravel()
    hit = flat_depth > 0
    # an inscribed polyhedron: nothing outside the sphere, everything inside its insphere
    inradius = np.min(np.abs(np.einsum("ij,ij->i", sphere.face_normals, sphere.triangles[:, 0])))
    disc_in = b**2 - a * (centre_cam @ centre_cam - inradius**2)
    assert not np.any(hit & (disc < 0))
    assert np.all(hit[disc_in > 0])
    assert np.all(flat_depth[hit] >= t_sphere[hit] - 1e-6)
    # each hit equals the exact (float64) intersection with the triangle it reports
    f = faces.ravel()[hit]
    n = sphere.face_normals[f]
    v0 = sphere.triangles[f, 0]
    t_exact = np.einsum("ij,ij->i", n, v0 - centre_cam) / np.einsum("ij,ij->i", n, rays[hit])
    np.testing.assert_allclose(flat_depth[hit], t_exact, atol=1e-6, rtol=0)
    # and the image holds z-depth: the nearest point of the sphere is 0.2 m closer than the centre
    assert depth.max() <= np.linalg.norm(centre_cam) + 1e-6
    assert depth[depth > 0].min() == pytest.approx(np.linalg.norm(centre_cam) - radius, abs=2e-3)


def test_back_projected_pixels_lie_on_the_triangles_they_hit() -> None:
    mesh = trimesh.creation.torus(0.15, 0.05, major_sections=24, minor_sections=12)
    k = xtion_intrinsics(64, 48)
    poses = look_at_many(viewpoints(4, 0.6), np.zeros(3))
    renderer = DepthRenderer(mesh, k)
    depth, faces = renderer.render_faces(poses)
    points = back_project(depth, poses, k)
    hit = depth > 0
    p = points[hit]
    tri = mesh.triangles[faces[hit]]
    distance = np.einsum("ij,ij->i", p - tri[:, 0], mesh.face_normals[faces[hit]])
    assert np.max(np.abs(distance)) < 1e-6
    bary = trimesh.triangles.points_to_barycentric(tri, p)
    assert bary.min() > -1e-4


def test_batch_equals_one_at_a_time_and_single_pose_shape() -> None:
    mesh = trimesh.creation.box(extents=(0.2, 0.3, 0.1))
    renderer = DepthRenderer(mesh, xtion_intrinsics(32, 24))
    poses = look_at_many(viewpoints(5, 0.6), np.zeros(3))
    batch = renderer.render(poses)
    assert batch.shape == (5, 24, 32) and batch.dtype == np.float32
    for i in range(5):
        np.testing.assert_array_equal(renderer.render(poses[i]), batch[i])
    assert not np.any(batch < 0)


def test_incidence_angle_is_zero_facing_and_right_angle_for_misses() -> None:
    plane = trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
                            [[0, 1, 2], [0, 2, 3]], process=False)
    renderer = DepthRenderer(plane, xtion_intrinsics(16, 12))
    pose = look_at(np.array([0.0, 0.0, 0.5]), np.zeros(3))
    depth, faces = renderer.render_faces(pose[None])
    angles = incidence_angles(renderer, pose[None], faces)
    k = renderer.intrinsics
    centre = (int(round(k.cy)), int(round(k.cx)))
    assert angles[0][centre] < np.radians(3)
    expected = np.arctan(np.hypot((np.arange(16) - k.cx) / k.fx, 0.0))
    np.testing.assert_allclose(angles[0, int(k.cy)], expected, atol=0.05)
    edge_on = look_at(np.array([2.0, 0.0, 0.0]), np.zeros(3))
    d2, f2 = renderer.render_faces(edge_on[None])
    assert np.all(incidence_angles(renderer, edge_on[None], f2)[f2 < 0] == np.pi / 2)
