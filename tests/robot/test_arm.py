"""The Panda model: forward kinematics, manipulability, the reach prefilter."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.robot.arm import CameraArm, manipulability_from_jacobians
from rapomdp.robot.scene import Scene
from tests.robot.conftest import PANDA_Q_MAX, PANDA_Q_MIN, dh_flange_pose


def _fd_jacobian(scene: Scene, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """Geometric Jacobian (6, 7) of the camera frame by central differences of the DH FK."""
    jacobian = np.zeros((6, 7))
    for k in range(7):
        dq = np.zeros(7)
        dq[k] = step
        plus = dh_flange_pose(q + dq) @ scene.mount
        minus = dh_flange_pose(q - dq) @ scene.mount
        jacobian[:3, k] = (plus[:3, 3] - minus[:3, 3]) / (2 * step)
        rotation = (dh_flange_pose(q) @ scene.mount)[:3, :3]
        skew = (plus[:3, :3] - minus[:3, :3]) / (2 * step) @ rotation.T
        jacobian[3:, k] = [skew[2, 1], skew[0, 2], skew[1, 0]]
    return jacobian


def test_library_model_matches_franka_dh(arm: CameraArm) -> None:
    rng = np.random.default_rng(3)
    for q in rng.uniform(PANDA_Q_MIN, PANDA_Q_MAX, size=(20, 7)):
        expected = dh_flange_pose(q) @ arm.scene.mount
        np.testing.assert_allclose(arm.camera_pose_base(q), expected, atol=1e-9)
    np.testing.assert_allclose(arm.joint_limits_rad, [PANDA_Q_MIN, PANDA_Q_MAX])


@pytest.mark.parametrize(
    "q",
    [
        np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, np.pi / 4]),  # the Panda's 'ready' pose
        np.array([0.4, 0.2, -0.5, -1.4, 0.9, 1.1, -0.6]),
    ],
)
def test_manipulability_matches_finite_differences(arm: CameraArm, q: np.ndarray) -> None:
    jacobian = _fd_jacobian(arm.scene, q)
    expected = float(np.sqrt(np.linalg.det(jacobian @ jacobian.T)))
    assert expected > 1e-3
    assert arm.manipulability(q[None])[0] == pytest.approx(expected, rel=1e-5)


def test_manipulability_is_zero_at_a_singularity(arm: CameraArm) -> None:
    stretched = np.zeros(7)  # elbow straight (joint 4 = 0) is a singular configuration
    assert arm.manipulability(stretched[None])[0] == pytest.approx(0.0, abs=1e-8)
    assert manipulability_from_jacobians(np.zeros((2, 6, 7))).tolist() == [0.0, 0.0]


def test_reach_prefilter_never_rejects_a_reachable_pose(arm: CameraArm) -> None:
    rng = np.random.default_rng(7)
    qs = rng.uniform(PANDA_Q_MIN, PANDA_Q_MAX, size=(300, 7))
    poses = np.stack([arm.camera_pose_base(q) for q in qs])
    assert arm.may_reach(poses, margin_m=0.0).all()
