"""The ``robot`` stage: IK for every test viewpoint, manipulability, and the E_M matrix.

Writes ``robot.npz`` (arrays, index = viewpoint index of X_rho), ``robot.json`` (a summary with
the measured figures) and ``robot.png`` (the figure); :mod:`rapomdp.robot.artefacts` names them
and reads them back.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.config import Config, RobotConfig, ViewpointsConfig
from rapomdp.context import RunContext
from rapomdp.geometry.viewsphere import fibonacci_directions, geodesic_distance_matrix
from rapomdp.io import save_npz, write_json_atomic
from rapomdp.robot.arm import CameraArm
from rapomdp.robot.artefacts import ROBOT_ARRAYS, ROBOT_FIGURE, ROBOT_SUMMARY
from rapomdp.robot.energy import joint_distance_matrix, movement_energy, singularity_penalty
from rapomdp.robot.figures import pick_poses, plot_robot
from rapomdp.robot.ik import IKSettings, ViewpointSolutions, arm_skeleton_world, solve_viewpoints
from rapomdp.robot.scene import Scene
from rapomdp.workspace import StageError, StageInputs


class UnreachableError(StageError):
    """No test viewpoint can be reached from the configured placement."""


@dataclass(frozen=True)
class RobotResult:
    """Everything the robot stage computes; arrays are indexed by viewpoint (n = |X_rho|)."""

    viewpoints_m: np.ndarray  # (n, 3) camera centres, world frame
    directions: np.ndarray  # (n, 3) unit directions from the centroid (same for every stage)
    solutions: ViewpointSolutions
    distance_m: np.ndarray  # (n, n) geodesic distances on the viewsphere
    joint_distance_rad: np.ndarray  # (n, n) |q' - q|, inf where either end is unreachable
    penalty: np.ndarray  # (n,) kappa * singularity penalty of moving *to* each viewpoint
    energy: np.ndarray  # (n, n) E_M, metres; 0 on the diagonal, inf to/from unreachable ones
    ik_seconds: float
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def reachable(self) -> np.ndarray:
        return self.solutions.reachable

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays written to ``robot.npz``."""
        s = self.solutions
        return {
            "viewpoints_m": self.viewpoints_m,
            "directions": self.directions,
            "reachable": s.reachable,
            "q_rad": s.q_rad,
            "manipulability": s.manipulability,
            "roll_rad": s.roll_rad,
            "camera_pose_world": s.camera_pose_world,
            "position_error_m": s.position_error_m,
            "angle_error_rad": s.angle_error_rad,
            "distance_m": self.distance_m,
            "joint_distance_rad": self.joint_distance_rad,
            "penalty": self.penalty,
            "energy": self.energy,
        }


def ik_settings(robot: RobotConfig, seed: int = 0) -> IKSettings:
    """The IK search settings of a ``robot`` section (degrees become radians here).

    Args:
        robot: The ``robot`` section (its roll samples, restarts, iterations, tolerances and
            clearances).
        seed: The seed of the IK's random restarts (the configuration's ``seed``).

    Returns:
        The :class:`~rapomdp.robot.ik.IKSettings`, the angle tolerance in radians.

    Example:
        >>> from rapomdp.config import RobotConfig
        >>> settings = ik_settings(RobotConfig(angle_tolerance_deg=1.0), seed=3)
        >>> round(settings.angle_tolerance_rad, 6), settings.restarts, settings.seed
        (0.017453, 4, 3)
    """
    return IKSettings(
        roll_samples=robot.roll_samples,
        restarts=robot.restarts,
        iterations=robot.iterations,
        position_tolerance_m=robot.position_tolerance_m,
        angle_tolerance_rad=float(np.radians(robot.angle_tolerance_deg)),
        floor_clearance_m=robot.floor_clearance_m,
        object_clearance_m=robot.object_clearance_m,
        seed=seed,
    )


def solve_robot(robot: RobotConfig, viewpoints: ViewpointsConfig, seed: int = 0,
                progress: bool = True) -> RobotResult:
    """IK, manipulability, distances and movement energy for the test viewpoints X_rho.

    Raises :class:`UnreachableError`, naming the placement, when no viewpoint is reachable.

    Args:
        robot: The ``robot`` section (the arm's placement, the IK search, the energy's terms).
        viewpoints: The ``viewpoints`` section: X_rho's count V and radius in metres.
        seed: The seed of the IK's random restarts (the configuration's ``seed``).
        progress: Show the IK's progress bar.

    Returns:
        Per viewpoint of X_rho: reachability (V,), joint angles (V, 7) in radians,
        manipulability (V,), and the (V, V) geodesic distances and movement energy E_M in
        metres, with a summary.

    Example:
        The default arm placement over 16 viewpoints (seconds: roboticstoolbox loads)::

            from rapomdp.config import RobotConfig, ViewpointsConfig
            result = solve_robot(RobotConfig(), ViewpointsConfig(count=16), progress=False)
            result.summary["reachable"]  # how many viewpoints the arm reaches
    """
    scene = Scene.from_config(robot)
    arm = CameraArm(scene)
    count, radius_m = viewpoints.count, viewpoints.radius_m
    eyes = scene.viewpoints_world(count, radius_m)
    start = time.perf_counter()
    solutions = solve_viewpoints(arm, eyes, ik_settings(robot, seed), progress)
    ik_seconds = time.perf_counter() - start
    reachable = solutions.reachable
    if not reachable.any():
        raise UnreachableError(
            f"robot: none of the {count} viewpoints (radius {radius_m} m around the centroid "
            f"{list(robot.centroid_m)}) is reachable from the base at "
            f"{list(robot.base_xyz_m)} with camera mount "
            f"{list(robot.camera_mount_xyz_m)}; move robot.base_xyz_m or "
            f"robot.centroid_m closer together, or lower viewpoints.radius_m"
        )
    directions = fibonacci_directions(count, hemisphere=True)
    distance = geodesic_distance_matrix(directions, radius_m)
    energy_cfg = robot.energy
    energy = movement_energy(
        distance,
        solutions.manipulability,
        reachable,
        kappa_m=energy_cfg.kappa_m,
        penalty=energy_cfg.penalty,
        q_rad=solutions.q_rad,
        joint_weight_m_per_rad=energy_cfg.joint_weight_m_per_rad,
    )
    joints = joint_distance_matrix(solutions.q_rad)
    joints = np.where(np.isnan(joints), np.inf, joints)
    np.fill_diagonal(joints, 0.0)
    m = solutions.manipulability
    reference = float(np.max(m[reachable]))
    penalty = np.full(count, np.inf)
    penalty[reachable] = energy_cfg.kappa_m * singularity_penalty(
        m[reachable], reference, energy_cfg.penalty
    )
    summary = {
        "viewpoints": count,
        "radius_m": radius_m,
        "reachable": int(reachable.sum()),
        "reachable_fraction": round(float(reachable.mean()), 4),
        "ik_seconds": round(ik_seconds, 3),
        "manipulability": {
            "min": float(np.min(m[reachable])),
            "median": float(np.median(m[reachable])),
            "max": reference,
        },
        "max_position_error_m": float(np.nanmax(solutions.position_error_m)),
        "max_angle_error_deg": float(np.degrees(np.nanmax(solutions.angle_error_rad))),
        "centroid_in_base_m": [round(float(v), 4) for v in scene.centroid_base],
        "energy_finite_max_m": float(np.max(energy[np.isfinite(energy)])),
        "unreachable_indices": np.flatnonzero(~reachable).tolist(),
    }
    return RobotResult(
        viewpoints_m=eyes,
        directions=directions,
        solutions=solutions,
        distance_m=distance,
        joint_distance_rad=joints,
        penalty=penalty,
        energy=energy,
        ik_seconds=ik_seconds,
        summary=summary,
    )


def plot_result(result: RobotResult, robot: RobotConfig, path: str | Path,
                arms: int = 3) -> None:
    """The stage's figure for ``result``: the arm drawn at ``arms`` of its solutions.

    Args:
        result: What :func:`solve_robot` computed.
        robot: The ``robot`` section ``result`` was solved with (the arm's placement).
        path: The figure's file (PNG).
        arms: How many of the solutions to draw the arm at.
    """
    scene = Scene.from_config(robot)
    arm = CameraArm(scene)
    s = result.solutions
    picks = pick_poses(s.manipulability, s.reachable, arms)
    plot_robot(
        path,
        viewpoints_m=result.viewpoints_m,
        reachable=s.reachable,
        manipulability=s.manipulability,
        centroid_m=scene.centroid_world,
        base_m=scene.base_world[:3, 3],
        skeletons_m=[arm_skeleton_world(arm, s.q_rad[i], samples_per_link=1) for i in picks],
        camera_poses=s.camera_pose_world[picks],
        title=(
            f"Panda: {int(s.reachable.sum())}/{s.count} viewpoints reachable "
            f"(radius {result.summary['radius_m']} m), coloured by manipulability"
        ),
        arm_labels=[f"arm at viewpoint {i} (man. {s.manipulability[i]:.3f})" for i in picks],
    )


def run_robot_stage(config: Config, inputs: StageInputs, out: Path,
                    context: RunContext) -> None:
    """The pipeline stage: writes robot.npz, robot.json and robot.png into ``out``.

    Args:
        config: The configuration (its ``robot`` and ``viewpoints`` sections).
        inputs: Unused: the robot stage reads only the configuration.
        out: The stage's folder.
        context: Its progress setting.

    Raises:
        UnreachableError: The arm reaches no viewpoint of X_rho (the placement is named).
    """
    del inputs  # the robot stage reads only the configuration
    result = solve_robot(config.robot, config.viewpoints, config.seed, context.progress)
    out = Path(out)
    save_npz(out / ROBOT_ARRAYS, **result.arrays())
    write_json_atomic(out / ROBOT_SUMMARY, result.summary)
    plot_result(result, config.robot, out / ROBOT_FIGURE)
