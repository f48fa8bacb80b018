"""The arm: a Franka Emika Panda carrying the depth camera over the test viewpoints X_rho.

``scene`` places the arm, the object's centroid and the camera mount; ``arm`` wraps
roboticstoolbox's Panda (forward kinematics, Jacobian, manipulability, ``ik_LM``); ``ik`` solves
every viewpoint with a free roll about the optical axis; ``energy`` builds the movement energy
E_M (Eq. 3); ``stage`` is the pipeline stage (``run_robot_stage``, ``solve_robot``,
``load_robot``). The ``robot`` configuration section (``RobotConfig``, ``EnergyConfig``) lives in
``rapomdp.config`` with every other section.
"""

from rapomdp.robot.arm import CameraArm, manipulability_from_jacobians
from rapomdp.robot.energy import joint_distance_matrix, movement_energy, singularity_penalty
from rapomdp.robot.ik import IKSettings, ViewpointSolutions, camera_targets, solve_viewpoints
from rapomdp.robot.scene import Scene

__all__ = [
    "CameraArm",
    "IKSettings",
    "Scene",
    "ViewpointSolutions",
    "camera_targets",
    "joint_distance_matrix",
    "manipulability_from_jacobians",
    "movement_energy",
    "singularity_penalty",
    "solve_viewpoints",
]
