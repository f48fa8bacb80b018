"""Depth rendering by ray casting through Embree (embreex).

The Embree scene is built once per mesh; a call renders a batch of poses with all their rays in
one Embree call. Ray directions have unit z in the camera frame, so the ray parameter Embree
returns at a hit *is* the z-depth: no per-pixel work is left after the call.
"""

from __future__ import annotations

import numpy as np
import trimesh
from embreex import mesh_construction, rtcore_scene

from rapomdp.geometry.camera import Intrinsics, pixel_directions

# Embree reports a miss as a huge distance; anything beyond this is background.
_MISS_M = 1e30
# Rays per Embree call: bounds the temporary arrays (about 30 bytes a ray).
_RAYS_PER_CALL = 1 << 18


class DepthRenderer:
    """Renders z-depth images (metres, 0 = no hit) of one mesh for batches of camera poses.

    The Embree scene is built once, in the constructor; every ``render`` call casts one ray per
    pixel of every pose in one batch.

    Args:
        mesh: the object, in metres (``rapomdp.data.meshes.normalise_mesh`` stands it on the
            floor at the dataset's radius).
        intrinsics: the camera (``rapomdp.geometry.xtion_intrinsics(width, height)``).

    Raises:
        ValueError: the mesh has no faces.

    Examples:
        >>> import numpy as np
        >>> from rapomdp.data.meshes import normalise_mesh
        >>> from rapomdp.data.procedural import generate_model
        >>> from rapomdp.geometry import look_at_many, viewpoints, xtion_intrinsics
        >>> mesh = normalise_mesh(generate_model("mug", seed=0, index=0), radius_m=0.2)
        >>> centre = np.array([0.0, 0.0, mesh.bounds[1, 2] / 2])
        >>> poses = look_at_many(viewpoints(8, 0.6, hemisphere=True, centre=centre), centre)
        >>> depth = DepthRenderer(mesh, xtion_intrinsics(160, 120)).render(poses)
        >>> depth.shape, depth.dtype                      # (poses, height, width), metres
        ((8, 120, 160), dtype('float32'))
        >>> bool(0.3 < depth[depth > 0].min() < depth.max() < 0.9)   # the camera is 0.6 m away
        True
    """

    def __init__(self, mesh: trimesh.Trimesh, intrinsics: Intrinsics) -> None:
        if len(mesh.faces) == 0:
            raise ValueError("cannot render a mesh without faces")
        self.mesh = mesh
        self.intrinsics = intrinsics
        self._scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(
            scene=self._scene,
            vertices=np.ascontiguousarray(mesh.vertices, dtype=np.float32),
            indices=np.ascontiguousarray(mesh.faces, dtype=np.int32),
        )
        # (H*W, 3) camera-frame directions with z = 1, float32 as Embree takes them.
        self._directions = pixel_directions(intrinsics).astype(np.float32)

    @property
    def image_shape(self) -> tuple[int, int]:
        return self.intrinsics.height, self.intrinsics.width

    def rays(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins and directions (n*H*W, 3) float32 for poses (n, 4, 4)."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        rotations_t = np.ascontiguousarray(poses[:, :3, :3].transpose(0, 2, 1), dtype=np.float32)
        directions = np.matmul(self._directions[None], rotations_t).reshape(-1, 3)
        centres = poses[:, :3, 3].astype(np.float32)
        origins = np.repeat(centres, self._directions.shape[0], axis=0)
        return origins, directions

    def render(self, poses: np.ndarray) -> np.ndarray:
        """Depth images (n, H, W) float32 for poses (n, 4, 4), or (H, W) for one pose (4, 4)."""
        single = np.ndim(poses) == 2
        depth = self._cast(poses, "DISTANCE")
        depth[depth > _MISS_M] = 0.0
        return depth[0] if single else depth

    def render_faces(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Depth images and the index of the face hit at each pixel (-1 = none)."""
        single = np.ndim(poses) == 2
        depth, faces = self._cast(poses, "FACES")
        return (depth[0], faces[0]) if single else (depth, faces)

    def _cast(self, poses: np.ndarray, what: str):  # noqa: ANN202 - one or two arrays
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        h, w = self.image_shape
        per_call = max(1, _RAYS_PER_CALL // (h * w))
        depth = np.empty((poses.shape[0], h, w), dtype=np.float32)
        faces = np.empty((poses.shape[0], h, w), dtype=np.int32) if what == "FACES" else None
        for start in range(0, poses.shape[0], per_call):
            chunk = slice(start, start + per_call)
            origins, directions = self.rays(poses[chunk])
            if faces is None:
                depth[chunk] = self._scene.run(origins, directions, query="DISTANCE").reshape(
                    -1, h, w
                )
            else:
                hit = self._scene.run(origins, directions, output=1)
                prim = hit["primID"].reshape(-1, h, w)
                d = hit["tfar"].reshape(-1, h, w)
                depth[chunk] = np.where(prim >= 0, d, 0.0)
                faces[chunk] = prim
        return depth if faces is None else (depth, faces)


def incidence_angles(
    renderer: DepthRenderer, poses: np.ndarray, faces: np.ndarray
) -> np.ndarray:
    """Angle (rad) between each hit surface's normal and the ray back to the camera.

    ``faces`` is the (n, H, W) output of :meth:`DepthRenderer.render_faces`; pixels without a hit
    get angle pi/2.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    n, h, w = faces.shape
    _, rays = renderer.rays(poses)
    rays = rays.reshape(n, h, w, 3).astype(np.float64)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    normals = np.asarray(renderer.mesh.face_normals)[np.maximum(faces, 0)]
    cosine = np.abs(np.einsum("nhwc,nhwc->nhw", rays, normals))
    angles = np.arccos(np.clip(cosine, 0.0, 1.0))
    return np.where(faces >= 0, angles, np.pi / 2)
