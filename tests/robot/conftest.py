"""Shared fixtures: the default scene solved once per session (about 2 s of IK)."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.config import Config
from rapomdp.robot.arm import CameraArm
from rapomdp.robot.scene import Scene

# Franka's modified (Craig) DH parameters (a, d, alpha) and joint limits, from REFERENCES.md;
# independent of roboticstoolbox's URDF model.
PANDA_DH = np.array(
    [
        [0.0, 0.333, 0.0],
        [0.0, 0.0, -np.pi / 2],
        [0.0, 0.316, np.pi / 2],
        [0.0825, 0.0, np.pi / 2],
        [-0.0825, 0.384, -np.pi / 2],
        [0.0, 0.0, np.pi / 2],
        [0.088, 0.0, np.pi / 2],
    ]
)
PANDA_FLANGE_D = 0.107
PANDA_Q_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
PANDA_Q_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])


def dh_flange_pose(q: np.ndarray) -> np.ndarray:
    """Flange-to-base transform from the modified DH table: Rx(alpha) Tx(a) Rz(q) Tz(d)."""
    pose = np.eye(4)
    for (a, d, alpha), angle in zip(PANDA_DH, q, strict=True):
        ca, sa, cq, sq = np.cos(alpha), np.sin(alpha), np.cos(angle), np.sin(angle)
        link = np.array(
            [
                [cq, -sq, 0.0, a],
                [sq * ca, cq * ca, -sa, -d * sa],
                [sq * sa, cq * sa, ca, d * ca],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
        pose = pose @ link
    flange = np.eye(4)
    flange[2, 3] = PANDA_FLANGE_D
    return pose @ flange


def dh_camera_pose_world(scene: Scene, q: np.ndarray) -> np.ndarray:
    return scene.base_world @ dh_flange_pose(q) @ scene.mount


@pytest.fixture(scope="session")
def config() -> Config:
    return Config()


@pytest.fixture(scope="session")
def arm(config: Config) -> CameraArm:
    return CameraArm(Scene.from_config(config.robot))


@pytest.fixture(scope="session")
def solved(config: Config):
    from rapomdp.robot.stage import solve_robot

    return solve_robot(config.robot, config.viewpoints, config.seed, progress=False)
