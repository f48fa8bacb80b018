"""Measure the robot stage: reachable viewpoints of X_rho and the IK wall time.

    PYTHONPATH=src OMP_NUM_THREADS=1 python benchmarks/robot_ik.py [--repeats 3] [--placements]

Prints the default scene's reachable count out of the test viewpoints, the IK wall time for all
of them (best and median of ``--repeats`` runs; the machine may be shared), the manipulability
spread, the FK errors of the solutions, a comparison with a thorough roll/restart search and,
with ``--placements``, the reachable count for other base placements.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from rapomdp.config import Config
from rapomdp.robot.arm import CameraArm
from rapomdp.robot.ik import solve_viewpoints
from rapomdp.robot.scene import Scene
from rapomdp.robot.stage import ik_settings


def _solve(config: Config, repeats: int = 1):
    arm = CameraArm(Scene.from_config(config.robot))
    eyes = arm.scene.viewpoints_world(config.viewpoints.count, config.viewpoints.radius_m)
    settings = ik_settings(config.robot, config.seed)
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = solve_viewpoints(arm, eyes, settings, progress=False)
        times.append(time.perf_counter() - start)
    return result, np.array(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--placements", action="store_true")
    args = parser.parse_args()

    start = time.perf_counter()
    import roboticstoolbox  # noqa: F401  (timed: the first import is slow)

    import_s = time.perf_counter() - start
    config = Config()
    r = config.robot
    print(f"machine: {platform.processor() or platform.machine()}, OMP_NUM_THREADS=1")
    print(f"roboticstoolbox import: {import_s:.2f} s (once per process, not counted below)")
    print(
        f"scene: base {list(r.base_xyz_m)} m yaw {r.base_yaw_deg} deg, centroid "
        f"{list(r.centroid_m)} m, camera mount {list(r.camera_mount_xyz_m)} m, "
        f"{config.viewpoints.count} viewpoints at {config.viewpoints.radius_m} m"
    )
    print(f"search: {r.roll_samples} rolls x {r.restarts} restarts, {r.iterations} iterations")
    result, times = _solve(config, args.repeats)
    m = result.manipulability[result.reachable]
    print(f"reachable: {int(result.reachable.sum())} / {result.count}")
    print(
        f"IK wall time, all {result.count} viewpoints: best {times.min():.2f} s, "
        f"median {np.median(times):.2f} s over {args.repeats} runs"
    )
    print(f"manipulability: min {m.min():.4f}, median {np.median(m):.4f}, max {m.max():.4f}")
    print(
        f"FK check: max position error {np.nanmax(result.position_error_m) * 1e3:.4f} mm, "
        f"max angle error {np.degrees(np.nanmax(result.angle_error_rad)):.5f} deg"
    )

    thorough = config.model_copy(deep=True)
    thorough.robot.roll_samples, thorough.robot.restarts = 24, 8
    deep, deep_times = _solve(thorough)
    both = deep.reachable & result.reachable
    ratio = result.manipulability[both] / deep.manipulability[both]
    print(
        f"thorough search (24 rolls x 8 restarts): reachable {int(deep.reachable.sum())}, "
        f"{deep_times[0]:.2f} s; default reaches {ratio.mean():.3f} of its manipulability "
        f"on average (worst viewpoint {ratio.min():.3f})"
    )

    if args.placements:
        print("placements (base x, y, z in m; same search):")
        for base in [(-0.35, 0.0, 0.0), (-0.4, 0.0, 0.0), (-0.45, 0.0, 0.0), (-0.5, 0.0, 0.0),
                     (-0.35, 0.0, 0.2), (-0.4, 0.0, 0.2), (-0.45, 0.0, 0.2), (-0.4, 0.0, 0.3)]:
            moved = config.model_copy(deep=True)
            moved.robot.base_xyz_m = base
            placed, placed_times = _solve(moved)
            pm = placed.manipulability[placed.reachable]
            print(
                f"  base {base}: reachable {int(placed.reachable.sum()):3d} / {placed.count}, "
                f"median manipulability {np.median(pm):.4f}, {placed_times[0]:.2f} s"
            )


if __name__ == "__main__":
    main()
