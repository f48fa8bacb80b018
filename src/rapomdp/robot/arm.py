"""The Franka Emika Panda with a camera on its flange: kinematics, Jacobian, manipulability.

The model is roboticstoolbox-python's URDF ``Panda`` (the C++ ``ik_LM`` solver, ``fkine``
and ``jacob0``). Its kinematic chain is taken to the flange ``panda_link8`` and extended by
the camera mount as the tool, so every pose and Jacobian here is the *camera's*. The gripper
model's own tool point (0.1034 m, -45 deg) is not used. roboticstoolbox is imported lazily: it
takes seconds to import.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from rapomdp.robot.scene import Scene, invert

FLANGE_LINK = "panda_link8"

# Panda geometry (Franka's modified DH, docs/robot.md): the shoulder (joints 1-2) sits 0.333 m
# above the base; the wrist point (joints 5-6 axes' common origin) is at most
# sqrt(0.316^2 + 0.0825^2) + sqrt(0.384^2 + 0.0825^2) = 0.7194 m from it; joint 7's frame is
# 0.107 m behind the flange, and the wrist point lies on a circle of radius 0.088 m around it in
# the plane normal to the flange axis.
SHOULDER_HEIGHT_M = 0.333
SHOULDER_TO_WRIST_MAX_M = float(np.hypot(0.316, 0.0825) + np.hypot(0.384, 0.0825))
FLANGE_OFFSET_M = 0.107
WRIST_CIRCLE_RADIUS_M = 0.088


@lru_cache(maxsize=1)
def _panda() -> Any:
    try:
        import roboticstoolbox as rtb
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError(
            "the robot stage needs roboticstoolbox-python (pip install roboticstoolbox-python)"
        ) from exc
    return rtb.models.Panda()


def manipulability_from_jacobians(jacobians: np.ndarray) -> np.ndarray:
    """Yoshikawa's measure sqrt(det(J J^T)) of Jacobians (..., 6, n); 0 at a singularity.

    Args:
        jacobians: (..., 6, n) geometric Jacobians (metres and radians per radian).

    Returns:
        (...) manipulabilities ≥ 0.

    Example:
        >>> import numpy as np
        >>> jacobian = np.hstack([np.eye(6), np.zeros((6, 1))])  # seven joints, one idle
        >>> float(manipulability_from_jacobians(jacobian))
        1.0
        >>> float(manipulability_from_jacobians(np.zeros((6, 7))))  # singular
        0.0
    """
    jacobians = np.asarray(jacobians, dtype=np.float64)
    gram = jacobians @ np.swapaxes(jacobians, -1, -2)
    return np.sqrt(np.clip(np.linalg.det(gram), 0.0, None))


class CameraArm:
    """The Panda placed in the world, with the camera of ``scene`` as its end effector.

    Loading the model imports roboticstoolbox (seconds, once per process).

    Args:
        scene: Where the arm's base, the object and the camera mount are.

    Example:
        The test viewpoints' reachability, as the robot stage finds it (seconds)::

            from rapomdp.config import Config
            from rapomdp.robot import CameraArm, Scene, solve_viewpoints

            scene = Scene.from_config(Config().robot)
            arm = CameraArm(scene)
            solutions = solve_viewpoints(arm, scene.viewpoints_world(16, 0.5))
            solutions.reachable.sum(), solutions.manipulability  # (16,) NaN where unreachable
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.robot = _panda()
        self._world_to_base = invert(scene.base_world)

    @property
    def joint_count(self) -> int:
        return int(self.robot.n)

    @property
    def joint_limits_rad(self) -> np.ndarray:
        """Lower and upper joint limits, shape (2, n)."""
        return np.asarray(self.robot.qlim, dtype=np.float64)

    @property
    def ready_rad(self) -> np.ndarray:
        """The Panda's 'ready' configuration (elbow up, flange down), a natural IK start."""
        return np.asarray(self.robot.qr, dtype=np.float64)

    def within_limits(self, q: np.ndarray) -> np.ndarray:
        """Whether configurations (..., n) respect the joint limits."""
        low, high = self.joint_limits_rad
        q = np.asarray(q, dtype=np.float64)
        return np.all((q >= low) & (q <= high), axis=-1)

    def camera_pose_base(self, q: np.ndarray) -> np.ndarray:
        """Camera-to-base transform (4, 4) at configuration q."""
        return np.asarray(
            self.robot.fkine(np.asarray(q, dtype=np.float64), end=FLANGE_LINK,
                             tool=self.scene.mount).A
        )

    def camera_poses_world(self, qs: np.ndarray) -> np.ndarray:
        """Camera-to-world transforms (m, 4, 4) of configurations (m, n)."""
        qs = np.atleast_2d(np.asarray(qs, dtype=np.float64))
        base = np.stack([self.camera_pose_base(q) for q in qs]) if len(qs) else np.zeros((0, 4, 4))
        return self.scene.base_world @ base

    def jacobians(self, qs: np.ndarray) -> np.ndarray:
        """Geometric Jacobians (m, 6, n) of the camera frame, in the base frame (v; omega)."""
        qs = np.atleast_2d(np.asarray(qs, dtype=np.float64))
        if not len(qs):
            return np.zeros((0, 6, self.joint_count))
        return np.stack(
            [self.robot.jacob0(q, end=FLANGE_LINK, tool=self.scene.mount) for q in qs]
        )

    def manipulability(self, qs: np.ndarray) -> np.ndarray:
        """Yoshikawa manipulability (m,) of the camera frame at configurations (m, n).

        The measure mixes metres and radians (the full 6 x n Jacobian), as the paper's Eq. 3
        does; it does not depend on where the base stands, only on q and the mount.
        """
        return manipulability_from_jacobians(self.jacobians(qs))

    def joint_origins_world(self, q: np.ndarray) -> np.ndarray:
        """World positions (10, 3) of the link frames panda_link0..8 and the camera centre."""
        frames = np.asarray(self.robot.fkine_all(np.asarray(q, dtype=np.float64)).A)
        # fkine_all: the base, then panda_link0..panda_link8, then the gripper's links.
        links = frames[1 : 2 + self.joint_count + 1, :3, 3]
        points = np.concatenate([links, self.camera_pose_base(q)[None, :3, 3]])
        homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
        return (homogeneous @ self.scene.base_world.T)[:, :3]

    def solve(
        self, target_base: np.ndarray, q0: np.ndarray, iterations: int, tolerance: float
    ) -> tuple[np.ndarray, bool]:
        """One Levenberg-Marquardt search (C++ ``ik_LM``) from ``q0``; no internal restarts.

        Restarts are the caller's, from seeded starting points, so results are reproducible
        (``ik_LM``'s own restarts draw from an unseeded generator).
        """
        solution = self.robot.ik_LM(
            target_base,
            end=FLANGE_LINK,
            tool=self.scene.mount,
            q0=q0,
            ilimit=iterations,
            slimit=1,
            tol=tolerance,
            joint_limits=True,
        )
        return np.asarray(solution.q, dtype=np.float64), bool(solution.success)

    def may_reach(self, camera_targets_base: np.ndarray, margin_m: float = 0.005) -> np.ndarray:
        """A necessary condition for a camera pose (..., 4, 4) in the base frame to be reached.

        The flange pose follows from the camera pose; the wrist point must then lie on a known
        circle, whose nearest point must be within the shoulder-to-wrist reach. A target that
        fails cannot be reached in any configuration, so IK need not be tried; one that passes
        may still be out of reach (joint limits, orientation).
        """
        flange = np.asarray(camera_targets_base, dtype=np.float64) @ invert(self.scene.mount)
        axis = flange[..., :3, 2]
        centre = flange[..., :3, 3] - FLANGE_OFFSET_M * axis
        to_shoulder = np.array([0.0, 0.0, SHOULDER_HEIGHT_M]) - centre
        along = np.einsum("...i,...i->...", to_shoulder, axis)
        across = np.linalg.norm(to_shoulder - along[..., None] * axis, axis=-1)
        nearest = np.hypot(across - WRIST_CIRCLE_RADIUS_M, along)
        return nearest <= SHOULDER_TO_WRIST_MAX_M + margin_m

    def to_base(self, poses_world: np.ndarray) -> np.ndarray:
        """World poses (..., 4, 4) expressed in the robot's base frame."""
        return self._world_to_base @ np.asarray(poses_world, dtype=np.float64)
