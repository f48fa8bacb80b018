"""The ``robot`` configuration section: the arm's placement, the camera mount, IK and energy.

Lengths in metres and angles in degrees, as everywhere at the configuration surface.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from rapomdp.section import Section

Vector3 = tuple[float, float, float]


class EnergyConfig(Section):
    """Movement energy E_M(x, x') = geodesic length + kappa * penalty(man(q')) [+ joint term].

    The penalty is 0 at the most manipulable reachable viewpoint and grows as man(q') falls
    toward a singularity (man = 0); see docs/robot.md for why this departs from Eq. 3.
    """

    kappa_m: float = Field(0.1, ge=0, description="weight of the singularity penalty, metres")
    penalty: Literal["inverse", "log", "linear"] = Field(
        "inverse",
        description="inverse: m_ref/m - 1; log: -ln(m/m_ref); linear: 1 - m/m_ref "
        "(m_ref = best manipulability over the reachable viewpoints)",
    )
    joint_weight_m_per_rad: float = Field(
        0.0, ge=0, description="weight of the joint-space distance |q' - q| (0 = off)"
    )


class RobotConfig(Section):
    """A Franka Emika Panda (roboticstoolbox's URDF model) with a depth camera on its flange.

    The world frame is the object's: Z up, floor z = 0, the object centred at x = y = 0. The
    test viewpoints lie on the hemisphere of radius ``viewpoints.radius_m`` around ``centroid_m``.
    """

    base_xyz_m: Vector3 = Field(
        (-0.4, 0.0, 0.2),
        description="the arm's base (panda_link0) in the world frame: 0.4 m behind the object, "
        "on a 0.2 m riser",
    )
    base_yaw_deg: float = Field(0.0, description="the base's rotation about world Z")
    centroid_m: Vector3 = Field(
        (0.0, 0.0, 0.2), description="the object's centroid in the world frame (sphere centre)"
    )
    camera_mount_xyz_m: Vector3 = Field(
        (0.0, 0.065, 0.045),
        description="camera centre in the flange (panda_link8) frame",
    )
    camera_mount_rpy_deg: Vector3 = Field(
        (0.0, 0.0, 0.0),
        description="camera frame (optical axis = z) relative to the flange, roll-pitch-yaw",
    )
    roll_samples: int = Field(
        8, ge=1, le=360, description="rolls about the optical axis searched per viewpoint"
    )
    restarts: int = Field(4, ge=1, le=100, description="IK starting configurations per roll")
    iterations: int = Field(40, ge=1, le=1000, description="Levenberg-Marquardt steps per try")
    position_tolerance_m: float = Field(0.001, gt=0, description="FK check: camera position")
    angle_tolerance_deg: float = Field(0.5, gt=0, description="FK check: camera orientation")
    floor_clearance_m: float | None = Field(
        0.05,
        description="the arm's skeleton (segments between link frames, from panda_link1 on) "
        "must stay this high above the floor; null disables the check",
    )
    object_clearance_m: float | None = Field(
        0.25,
        gt=0,
        description="the arm must stay this far from the centroid (object bounding sphere plus "
        "a link radius); null disables the check",
    )
    energy: EnergyConfig = EnergyConfig()
