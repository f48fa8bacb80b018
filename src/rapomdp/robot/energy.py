"""Movement energy between viewpoints (the paper's Eq. 3, with a singularity penalty).

The paper writes E_M(x, x') = len(x, x') + man(q'), with man(q) = sqrt(det(J J^T)) >= 0 and
man = 0 at a singularity. Added as it stands, that term makes *dexterous* poses expensive and
singular ones free, the opposite of what the text asks for (an energy bounded by manipulability
constraints). We implement the intent: a penalty that is 0 at the most manipulable reachable
viewpoint and grows as man(q') falls toward 0, weighted by kappa (metres):

    E_M(x, x') = len(x, x') + kappa * penalty(man(q') / m_ref) [+ w * |q' - q|]

with m_ref the largest manipulability over the reachable viewpoints. Staying costs nothing
(zero diagonal); a move to or from an unreachable viewpoint costs +inf (it is not an action).
Because the penalty depends only on the target and is >= 0, E_M keeps the triangle inequality
of the geodesic distance.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

PenaltyForm = Literal["inverse", "log", "linear"]


def singularity_penalty(
    manipulability: np.ndarray, reference: float, form: PenaltyForm = "inverse"
) -> np.ndarray:
    """Penalty >= 0 for each manipulability: 0 at ``reference`` (or above), larger toward 0.

    ``inverse``: reference/m - 1 (-> inf at a singularity); ``log``: -ln(m/reference) (-> inf,
    gentler); ``linear``: 1 - m/reference (bounded by 1, the scale of the paper's raw term).

    Args:
        manipulability: (n,) Yoshikawa manipulabilities (≥ 0).
        reference: The manipulability that costs nothing (> 0), the most manipulable
            reachable viewpoint's.
        form: ``inverse``, ``log`` or ``linear``.

    Returns:
        (n,) penalties, dimensionless (the energy weighs them by κ in metres).

    Raises:
        ValueError: ``reference`` ≤ 0 or an unknown ``form``.

    Example:
        >>> import numpy as np
        >>> singularity_penalty(np.array([0.1, 0.05, 0.0]), reference=0.1).tolist()
        [0.0, 1.0, inf]
        >>> singularity_penalty(np.array([0.1, 0.05]), reference=0.1, form="linear").tolist()
        [0.0, 0.5]
    """
    if not reference > 0:
        raise ValueError(f"reference manipulability must be positive, got {reference}")
    ratio = np.clip(np.asarray(manipulability, dtype=np.float64) / reference, 0.0, 1.0)
    with np.errstate(divide="ignore"):
        if form == "inverse":
            return 1.0 / ratio - 1.0
        if form == "log":
            return -np.log(ratio)
        if form == "linear":
            return 1.0 - ratio
    raise ValueError(f"unknown penalty form {form!r}; choose inverse, log or linear")


def joint_distance_matrix(q_rad: np.ndarray) -> np.ndarray:
    """Euclidean joint-space distances (n, n), radians, between configurations (n, joints).

    Args:
        q_rad: (n, joints) joint angles in radians.

    Returns:
        (n, n) distances in radians (NaN where a configuration holds NaN).

    Example:
        >>> import numpy as np
        >>> joint_distance_matrix(np.array([[0.0, 0.0], [3.0, 4.0]])).tolist()
        [[0.0, 5.0], [5.0, 0.0]]
    """
    q_rad = np.asarray(q_rad, dtype=np.float64)
    return np.linalg.norm(q_rad[:, None, :] - q_rad[None, :, :], axis=-1)


def movement_energy(
    distance_m: np.ndarray,
    manipulability: np.ndarray,
    reachable: np.ndarray,
    kappa_m: float = 0.1,
    penalty: PenaltyForm = "inverse",
    q_rad: np.ndarray | None = None,
    joint_weight_m_per_rad: float = 0.0,
) -> np.ndarray:
    """E_M (n, n) in metres: row = from x, column = to x'; see the module docstring.

    ``distance_m`` is the geodesic matrix of all n viewpoints, ``manipulability`` (n,) and
    ``reachable`` (n,) come from IK; ``q_rad`` (n, joints) is needed only for the joint term.

    Args:
        distance_m: (n, n) geodesic distances between the viewpoints, metres.
        manipulability: (n,) manipulability at each viewpoint's IK solution.
        reachable: (n,) bool: the viewpoints IK reached.
        kappa_m: The singularity penalty's weight κ in metres.
        penalty: The penalty's form (:func:`singularity_penalty`).
        q_rad: (n, joints) the IK solutions, for the joint term only.
        joint_weight_m_per_rad: The joint term's weight, metres per radian (0: none).

    Returns:
        (n, n) E_M in metres: 0 on the diagonal, +inf to or from an unreachable viewpoint.

    Raises:
        ValueError: Shapes disagree, nothing is reachable, a negative weight, or the joint
            term without ``q_rad``.

    Example:
        >>> import numpy as np
        >>> distance = np.array([[0.0, 0.3, 0.5], [0.3, 0.0, 0.4], [0.5, 0.4, 0.0]])
        >>> energy = movement_energy(distance, np.array([0.1, 0.05, 0.08]),
        ...                          np.array([True, True, False]), kappa_m=0.1)
        >>> energy.round(3).tolist()  # moving to the less dexterous viewpoint 1 costs 0.1 more
        [[0.0, 0.4, inf], [0.3, 0.0, inf], [inf, inf, 0.0]]
    """
    distance_m = np.asarray(distance_m, dtype=np.float64)
    reachable = np.asarray(reachable, dtype=bool)
    n = reachable.size
    if distance_m.shape != (n, n) or np.shape(manipulability) != (n,):
        raise ValueError(
            f"shapes disagree: distance {distance_m.shape}, manipulability "
            f"{np.shape(manipulability)}, reachable ({n},)"
        )
    if not reachable.any():
        raise ValueError("no viewpoint is reachable; movement energy is undefined")
    if kappa_m < 0 or joint_weight_m_per_rad < 0:
        raise ValueError("kappa_m and joint_weight_m_per_rad must be non-negative")
    manipulability = np.asarray(manipulability, dtype=np.float64)
    reference = float(np.max(manipulability[reachable]))
    cost_to = np.full(n, np.inf)
    penalties = singularity_penalty(manipulability[reachable], reference, penalty)
    cost_to[reachable] = kappa_m * penalties
    energy = distance_m + cost_to[None, :]
    if joint_weight_m_per_rad > 0:
        if q_rad is None:
            raise ValueError("the joint-distance term needs the joint solutions q_rad")
        joints = joint_distance_matrix(q_rad)
        energy = energy + joint_weight_m_per_rad * np.where(np.isnan(joints), np.inf, joints)
    energy[~reachable, :] = np.inf
    energy[:, ~reachable] = np.inf
    np.fill_diagonal(energy, 0.0)
    return energy
