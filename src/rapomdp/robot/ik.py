"""Inverse kinematics for every viewpoint: camera at the viewpoint, optical axis on the centroid.

The roll about the optical axis does not change the view's geometry (only the image's
rotation), so it is free: each viewpoint is solved at ``roll_samples`` rolls, each from
``restarts`` seeded starting configurations, and the feasible solution with the highest
manipulability is kept. A solution is feasible when ``ik_LM`` converged inside the joint
limits, forward kinematics puts the camera within the position and angle tolerances of the
target, and (optionally) the arm's skeleton clears the floor and the object. A viewpoint with no
feasible solution is unreachable; it is reported as such, never with a bad solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rapomdp.geometry.camera import look_at_many
from rapomdp.progress import track
from rapomdp.robot.arm import CameraArm

# ik_LM's residual is 0.5 e^T e of the 6-vector pose error; 1e-10 is ~1e-5 m / rad.
SOLVER_TOLERANCE = 1e-10


@dataclass(frozen=True)
class IKSettings:
    """How hard to search; see :class:`~rapomdp.config.RobotConfig`.

    Attributes:
        roll_samples: Rolls about the optical axis tried per viewpoint (the roll is free).
        restarts: IK starts per roll (the ready pose, then seeded draws).
        iterations: Levenberg-Marquardt iterations per start.
        position_tolerance_m: The largest camera position error accepted, metres.
        angle_tolerance_rad: The largest camera rotation error accepted, radians.
        floor_clearance_m: How far above the floor every link must stay (None: unchecked).
        object_clearance_m: How far from the object's centroid the links must stay (None:
            unchecked).
        seed: Seed of the random starts.
    """

    roll_samples: int = 8
    restarts: int = 4
    iterations: int = 40
    position_tolerance_m: float = 1e-3
    angle_tolerance_rad: float = float(np.radians(0.5))
    floor_clearance_m: float | None = 0.05
    object_clearance_m: float | None = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        if self.roll_samples < 1 or self.restarts < 1 or self.iterations < 1:
            raise ValueError(
                f"roll_samples, restarts and iterations must be at least 1, got "
                f"{self.roll_samples}, {self.restarts}, {self.iterations}"
            )


@dataclass(frozen=True)
class ViewpointSolutions:
    """IK for n viewpoints; rows of unreachable viewpoints hold NaN.

    What :func:`solve_viewpoints` returns: per viewpoint, whether it is reachable, the joint
    angles (radians), the manipulability there, the chosen roll, the camera pose reached and
    its errors (metres, radians), and how many IK tries converged.
    """

    reachable: np.ndarray  # (n,) bool
    q_rad: np.ndarray  # (n, joints) joint angles, NaN where unreachable
    manipulability: np.ndarray  # (n,) sqrt(det(J J^T)) at q, NaN where unreachable
    roll_rad: np.ndarray  # (n,) chosen roll about the optical axis, NaN where unreachable
    camera_pose_world: np.ndarray  # (n, 4, 4) the pose FK reaches, NaN where unreachable
    position_error_m: np.ndarray  # (n,) |FK - target|, NaN where unreachable
    angle_error_rad: np.ndarray  # (n,) rotation angle between FK and target, NaN likewise
    converged_count: np.ndarray  # (n,) int, IK tries that converged (before the checks)

    @property
    def count(self) -> int:
        return int(self.reachable.size)


def pose_errors(achieved: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and rotation-angle (rad) differences between poses (..., 4, 4)."""
    achieved = np.asarray(achieved, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    position = np.linalg.norm(achieved[..., :3, 3] - target[..., :3, 3], axis=-1)
    relative = np.swapaxes(target[..., :3, :3], -1, -2) @ achieved[..., :3, :3]
    cosine = (np.trace(relative, axis1=-2, axis2=-1) - 1.0) / 2.0
    return position, np.arccos(np.clip(cosine, -1.0, 1.0))


def roll_angles(samples: int) -> np.ndarray:
    """``samples`` rolls evenly spread over a full turn, radians."""
    return 2.0 * np.pi * np.arange(samples) / samples


def camera_targets(eyes_world: np.ndarray, centroid_world: np.ndarray, rolls_rad: np.ndarray
                   ) -> np.ndarray:
    """Target camera poses (n, rolls, 4, 4): centre at each eye, optical axis on the centroid.

    Built from :func:`~rapomdp.geometry.camera.look_at_many` turned about its own z axis.

    Args:
        eyes_world: (n, 3) camera centres in metres.
        centroid_world: (3,) the point every camera looks at.
        rolls_rad: (rolls,) turns about the optical axis, radians.

    Returns:
        (n, rolls, 4, 4) camera-to-world poses.

    Example:
        >>> import numpy as np
        >>> poses = camera_targets(np.array([[0.5, 0.0, 0.3]]), np.array([0.5, 0.0, 0.0]),
        ...                        np.array([0.0, np.pi / 2]))
        >>> poses.shape, bool(np.allclose(poses[0, 1, :3, 2], [0.0, 0.0, -1.0]))
        ((1, 2, 4, 4), True)
    """
    base = look_at_many(eyes_world, centroid_world)
    cos, sin = np.cos(rolls_rad), np.sin(rolls_rad)
    turn = np.zeros((len(rolls_rad), 4, 4))
    turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = cos, -sin, sin, cos
    turn[:, 2, 2] = turn[:, 3, 3] = 1.0
    return base[:, None] @ turn[None]


def starting_configurations(arm: CameraArm, restarts: int, seed: int) -> np.ndarray:
    """IK starts (restarts, joints): the ready pose, then seeded draws inside the limits."""
    low, high = arm.joint_limits_rad
    margin = 0.1 * (high - low)
    rng = np.random.default_rng(seed)
    draws = rng.uniform(low + margin, high - margin, size=(restarts - 1, arm.joint_count))
    return np.concatenate([arm.ready_rad[None], draws])


def solve_viewpoints(
    arm: CameraArm, eyes_world: np.ndarray, settings: IKSettings | None = None,
    progress: bool = True,
) -> ViewpointSolutions:
    """Solve every viewpoint of ``eyes_world`` (n, 3); the camera looks at the scene centroid.

    Each viewpoint tries ``settings.roll_samples`` rolls from ``settings.restarts`` starts
    and keeps the most manipulable solution that passes the tolerance and clearance checks.

    Args:
        arm: The arm (:class:`~rapomdp.robot.arm.CameraArm`).
        eyes_world: (n, 3) camera centres in metres.
        settings: The search (default :class:`IKSettings`).
        progress: Show a progress bar.

    Returns:
        One row per viewpoint, NaN where it is unreachable.

    Example:
        See :class:`~rapomdp.robot.arm.CameraArm` (roboticstoolbox takes seconds to load).
    """
    settings = settings or IKSettings()
    eyes_world = np.atleast_2d(np.asarray(eyes_world, dtype=np.float64))
    n, joints = len(eyes_world), arm.joint_count
    rolls = roll_angles(settings.roll_samples)
    targets_world = camera_targets(eyes_world, arm.scene.centroid_world, rolls)
    targets_base = arm.to_base(targets_world)
    may_reach = arm.may_reach(targets_base)  # (n, rolls): skips hopeless targets
    starts = starting_configurations(arm, settings.restarts, settings.seed)

    q_out = np.full((n, joints), np.nan)
    roll_out = np.full(n, np.nan)
    target_out = np.full((n, 4, 4), np.nan)
    converged_count = np.zeros(n, dtype=np.int64)
    # the solver is per target (C++); keep the Python work per try minimal
    for i in track(range(n), "robot: IK", progress, unit="viewpoints"):
        found_q, found_roll = [], []
        for r in np.flatnonzero(may_reach[i]):
            for q0 in starts:
                q, ok = arm.solve(targets_base[i, r], q0, settings.iterations, SOLVER_TOLERANCE)
                if ok:
                    found_q.append(q)
                    found_roll.append(r)
        if not found_q:
            continue
        candidates = np.array(found_q)
        converged_count[i] = len(candidates)
        # Most manipulable first; the first that passes every check is the viewpoint's solution.
        order = np.argsort(-arm.manipulability(candidates), kind="stable")
        for best in order:
            target = targets_world[i, found_roll[best]]
            position, angle = pose_errors(arm.camera_poses_world(candidates[best]), target)
            if (
                arm.within_limits(candidates[best])
                and position[0] <= settings.position_tolerance_m
                and angle[0] <= settings.angle_tolerance_rad
                and collision_free(arm, candidates[best], settings)
            ):
                q_out[i] = candidates[best]
                roll_out[i] = rolls[found_roll[best]]
                target_out[i] = target
                break

    reachable = ~np.isnan(q_out[:, 0])
    manipulability = np.full(n, np.nan)
    poses = np.full((n, 4, 4), np.nan)
    position_error = np.full(n, np.nan)
    angle_error = np.full(n, np.nan)
    if reachable.any():
        manipulability[reachable] = arm.manipulability(q_out[reachable])
        poses[reachable] = arm.camera_poses_world(q_out[reachable])
        position_error[reachable], angle_error[reachable] = pose_errors(
            poses[reachable], target_out[reachable]
        )
    return ViewpointSolutions(
        reachable=reachable,
        q_rad=q_out,
        manipulability=manipulability,
        roll_rad=roll_out,
        camera_pose_world=poses,
        position_error_m=position_error,
        angle_error_rad=angle_error,
        converged_count=converged_count,
    )


def arm_skeleton_world(arm: CameraArm, q: np.ndarray, samples_per_link: int = 4) -> np.ndarray:
    """Points (m, 3) along the segments joining the link frames and the camera, world frame.

    A cheap stand-in for the arm's body: the chain of link-frame origins from panda_link1 on,
    each segment sampled ``samples_per_link`` times (the fixed base column is left out).
    """
    origins = arm.joint_origins_world(q)[1:]
    t = np.linspace(0.0, 1.0, samples_per_link, endpoint=False)[:, None, None]
    along = origins[:-1][None] + t * (origins[1:] - origins[:-1])[None]
    return np.concatenate([along.reshape(-1, 3), origins[-1:]])


def collision_free(arm: CameraArm, q: np.ndarray, settings: IKSettings) -> bool:
    """Whether the arm's skeleton stays above the floor and outside the object's sphere.

    Approximate by design (link radii of ~6 cm are folded into the clearances); either check
    is off when its clearance is None.
    """
    if settings.floor_clearance_m is None and settings.object_clearance_m is None:
        return True
    points = arm_skeleton_world(arm, q)
    if settings.floor_clearance_m is not None and np.any(
        points[:, 2] < settings.floor_clearance_m
    ):
        return False
    if settings.object_clearance_m is not None:
        distance = np.linalg.norm(points - arm.scene.centroid_world, axis=1)
        if np.any(distance < settings.object_clearance_m):
            return False
    return True
