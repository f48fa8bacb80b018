"""The robot stage's artefacts: their names, and the readers every later stage goes through.

``W/robot/robot.npz`` (:data:`ROBOT_ARRAYS`: per viewpoint of X_rho ``reachable``, ``q_rad``,
``manipulability``, ``directions``, ..., and the (V, V) ``distance_m`` and ``energy`` E_M),
``robot.json`` (:data:`ROBOT_SUMMARY`) and ``robot.png`` (:data:`ROBOT_FIGURE`). Only NumPy is
needed to read them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.io import ArtefactError, load_npz, read_json

ROBOT_ARRAYS = "robot.npz"
ROBOT_SUMMARY = "robot.json"
ROBOT_FIGURE = "robot.png"


def load_robot_summary(folder: str | Path) -> dict[str, Any]:
    """The summary of a finished robot stage (``robot.json`` in ``folder``)."""
    return read_json(Path(folder) / ROBOT_SUMMARY)


def describe(summary: dict[str, Any]) -> str:
    """One line for the command line from a ``robot.json`` summary."""
    m = summary["manipulability"]
    return (
        f"{summary['reachable']}/{summary['viewpoints']} viewpoints reachable "
        f"({100 * summary['reachable_fraction']:.0f} %), IK {summary['ik_seconds']:.2f} s, "
        f"manipulability {m['min']:.3f}-{m['max']:.3f} (median {m['median']:.3f})"
    )


def load_robot(folder: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a finished robot stage (``robot.npz`` in ``folder``), checked for shape."""
    arrays = load_npz(Path(folder) / ROBOT_ARRAYS)
    missing = {"reachable", "energy", "distance_m", "manipulability", "q_rad"} - set(arrays)
    if missing:
        raise ArtefactError(f"{Path(folder) / ROBOT_ARRAYS}: missing arrays {sorted(missing)}")
    n = arrays["reachable"].shape[0]
    if arrays["energy"].shape != (n, n) or arrays["distance_m"].shape != (n, n):
        raise ArtefactError(
            f"{Path(folder) / ROBOT_ARRAYS}: energy/distance are not {n}x{n} "
            f"(got {arrays['energy'].shape}, {arrays['distance_m'].shape})"
        )
    return arrays
