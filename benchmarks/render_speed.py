"""Depth rendering speed: images per second, and the renderer against a raw embreex call.

Prints, for a ~50k-face mesh at 160x120 and 640x480: images/s of ``DepthRenderer.render`` on a
batch of poses, images/s of one pose per call (as in a closed-loop episode), and the ratio of
rays/s to a raw ``EmbreeScene.run`` on the same precomputed rays, all measured in one run.

    OMP_NUM_THREADS=1 python benchmarks/render_speed.py
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import trimesh

from rapomdp.data.procedural import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints


def dense_mesh(name: str, target_faces: int) -> trimesh.Trimesh:
    mesh = generate_model(name, seed=0, index=0)
    while len(mesh.faces) < target_faces * 0.6:
        mesh = mesh.subdivide()
    scale = 0.2 / np.linalg.norm(mesh.extents / 2)
    mesh.apply_translation(-(mesh.bounds[0] + mesh.bounds[1]) / 2)
    mesh.apply_scale(scale)
    return mesh


def interleaved_medians(
    fns: dict, repeats: int = 9, clock=time.perf_counter  # noqa: ANN001
) -> dict[str, float]:
    """Median seconds of each function, timed in turn so machine load hits all alike."""
    times: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            start = clock()
            fn()
            times[name].append(clock() - start)
    return {name: float(np.median(t)) for name, t in times.items()}


def main() -> None:
    meshes = {
        "torus (dense, fills the view)": trimesh.creation.torus(
            0.15, 0.05, major_sections=250, minor_sections=100),
        "teapot (procedural, subdivided)": dense_mesh("teapot", 50_000),
        "bicycle (procedural, subdivided)": dense_mesh("bicycle", 50_000),
    }
    print("wall: images per wall-clock second; cpu: per second of this process's CPU time (one")
    print("core's throughput even when the machine is shared); ratio = raw / renderer time.")
    print(f"{'mesh':34s} {'faces':>6s} {'res':>8s} {'hit%':>5s} {'batch img/s':>12s} "
          f"{'1-pose img/s':>13s} {'raw img/s':>10s} {'ratio':>6s} {'cpu img/s':>10s} "
          f"{'cpu ratio':>9s}")
    for label, mesh in meshes.items():
        for width, height, views in ((160, 120, 200), (640, 480, 20)):
            renderer = DepthRenderer(mesh, xtion_intrinsics(width, height))
            poses = look_at_many(viewpoints(views, 0.6), np.zeros(3))
            depth = renderer.render(poses)
            origins, directions = renderer.rays(poses)
            medians = interleaved_medians({
                # bind loop variables now (ruff B023)
                "raw": lambda o=origins, d=directions, r=renderer: r._scene.run(
                    o, d, query="DISTANCE"),
                "batch": lambda r=renderer, p=poses: r.render(p),
                "single": lambda r=renderer, p=poses: [r.render(q) for q in p[:20]],
            })
            raw, batch, single = medians["raw"], medians["batch"], medians["single"]
            cpu = interleaved_medians({
                "raw": lambda o=origins, d=directions, r=renderer: r._scene.run(
                    o, d, query="DISTANCE"),
                "batch": lambda r=renderer, p=poses: r.render(p),
            }, clock=time.process_time)
            print(f"{label:34s} {len(mesh.faces):6d} {width:>4d}x{height:<3d} "
                  f"{100 * (depth > 0).mean():5.1f} {views / batch:12.0f} {20 / single:13.0f} "
                  f"{views / raw:10.0f} {raw / batch:6.2f} {views / cpu['batch']:10.0f} "
                  f"{cpu['raw'] / cpu['batch']:9.2f}")


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
