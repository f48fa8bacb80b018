"""The mesh set: 11 classes of objects composed of plain trimesh primitives (cylinders, cones,
spheres, boxes, tori), built differently from the embedded procedural generator, as a stand-in
for unseen objects. STL files in the ``generic`` folder layout (``OUT/<class>/<model>.stl``)
that ``configs/mesh-set.yaml`` reads.

    rapomdp dataset build mesh-set --out runs/mesh-set/meshes
    rapomdp run -w runs/mesh-set-ws -c configs/mesh-set.yaml

Needs nothing beyond the package; a second or two.

Classes pair up on purpose so that single views are ambiguous: lamp / mushroom / rocket share a
vertical stem with something on top, stool / bench share legs under a slab, snowman / dumbbell
share spheres, arch / gate share pillars, ring stand / goblet share round bases. Each model is
drawn from its own generator, seeded by (seed, class index, model index), so a model does not
change when more are asked for.

Example:
    >>> import numpy as np
    >>> from rapomdp.data.build.mesh_set import SHAPES
    >>> len(SHAPES), len(SHAPES["snowman"](np.random.default_rng(0)))
    (11, 3)
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh
from trimesh import creation

from rapomdp.data.build.common import DatasetBuildError, building_folder, swap_in

#: Where the set is written by default (the path ``configs/mesh-set.yaml`` reads).
DEFAULT_OUT = Path("runs/mesh-set/meshes")
DEFAULT_MODELS = 11
DEFAULT_SEED = 7

#: A class's shape: the parts of one model (metres, z up) drawn from a generator.
Shape = Callable[[np.random.Generator], list[trimesh.Trimesh]]


def _at(mesh: trimesh.Trimesh, x: float = 0.0, y: float = 0.0, z: float = 0.0
        ) -> trimesh.Trimesh:
    mesh.apply_translation([x, y, z])
    return mesh


def _cyl(radius: float, height: float, z0: float, x: float = 0.0, y: float = 0.0,
         sections: int = 24) -> trimesh.Trimesh:
    return _at(creation.cylinder(radius, height, sections=sections), x, y, z0 + height / 2)


def lamp(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A lamp: a round base, a thin pole and a cone shade."""
    base_r, pole_h = rng.uniform(0.08, 0.14), rng.uniform(0.3, 0.5)
    shade_r, shade_h = rng.uniform(0.1, 0.18), rng.uniform(0.1, 0.2)
    return [_cyl(base_r, 0.02, 0.0), _cyl(0.01, pole_h, 0.02),
            _at(creation.cone(shade_r, -shade_h, sections=24), z=0.02 + pole_h + shade_h * 0.7)]


def mushroom(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A mushroom: a stem under a flattened sphere."""
    stem_r, stem_h = rng.uniform(0.03, 0.06), rng.uniform(0.12, 0.25)
    cap = creation.icosphere(3, radius=1.0)
    cap.apply_scale([rng.uniform(0.12, 0.2), rng.uniform(0.12, 0.2), rng.uniform(0.05, 0.09)])
    return [_cyl(stem_r, stem_h, 0.0), _at(cap, z=stem_h)]


def rocket(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A rocket: a cylinder, a nose cone and three or four fins."""
    r, h = rng.uniform(0.04, 0.07), rng.uniform(0.3, 0.45)
    nose = rng.uniform(0.08, 0.15)
    fins = [_at(trimesh.creation.box([0.012, rng.uniform(0.06, 0.1) + r, 0.1]), z=0.05)
            for _ in range(int(rng.integers(3, 5)))]
    for i, fin in enumerate(fins):
        fin.apply_transform(trimesh.transformations.rotation_matrix(
            2 * np.pi * i / len(fins), [0, 0, 1]))
    return [_cyl(r, h, 0.0), _at(creation.cone(r, nose, sections=24), z=h), *fins]


def _legs(width: float, depth: float, height: float, radius: float, count: int
          ) -> list[trimesh.Trimesh]:
    if count == 3:
        angles = np.linspace(0, 2 * np.pi, 4)[:3]
        spots = [(width / 2 * np.cos(a), width / 2 * np.sin(a)) for a in angles]
    else:
        spots = [(sx * width / 2, sy * depth / 2) for sx in (-1, 1) for sy in (-1, 1)]
    return [_cyl(radius, height, 0.0, x, y, sections=12) for x, y in spots]


def stool(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A stool: three legs under a round seat."""
    seat_r, h = rng.uniform(0.12, 0.18), rng.uniform(0.3, 0.45)
    return [*_legs(seat_r * 1.4, seat_r * 1.4, h, 0.012, 3), _cyl(seat_r, 0.03, h)]


def bench(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A bench: four legs under a long slab."""
    length, depth, h = rng.uniform(0.5, 0.8), rng.uniform(0.15, 0.25), rng.uniform(0.2, 0.35)
    slab = _at(creation.box([length, depth, 0.03]), z=h + 0.015)
    return [*_legs(length * 0.85, depth * 0.7, h, 0.015, 4), slab]


def snowman(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A snowman: three stacked spheres, largest at the bottom."""
    radii = np.sort(rng.uniform(0.05, 0.14, 3))[::-1]
    parts, z = [], 0.0
    for r in radii:
        parts.append(_at(creation.icosphere(2, radius=r), z=z + r))
        z += 1.7 * r
    return parts


def dumbbell(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A dumbbell: two spheres on a horizontal rod."""
    r, bar = rng.uniform(0.06, 0.1), rng.uniform(0.2, 0.35)
    rod = creation.cylinder(0.015, bar, sections=12)
    rod.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    return [_at(rod, z=r), _at(creation.icosphere(2, radius=r), x=-bar / 2, z=r),
            _at(creation.icosphere(2, radius=r), x=bar / 2, z=r)]


def arch(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """An arch: two square pillars under a half-ring."""
    span, h, t = rng.uniform(0.3, 0.5), rng.uniform(0.3, 0.45), rng.uniform(0.04, 0.07)
    ring = creation.torus(span / 2, t / 2, major_sections=32, minor_sections=12)
    ring.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    pillars = [_at(creation.box([t, t, h]), x=sx * span / 2, z=h / 2) for sx in (-1, 1)]
    return [*pillars, _at(ring, z=h)]


def gate(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A gate: two square pillars and two cross beams."""
    span, h, t = rng.uniform(0.3, 0.5), rng.uniform(0.3, 0.45), rng.uniform(0.04, 0.07)
    pillars = [_at(creation.box([t, t, h]), x=sx * span / 2, z=h / 2) for sx in (-1, 1)]
    beams = [_at(creation.box([span + 2 * t, t, t]), z=h * f) for f in (0.7, 1.0)]
    return [*pillars, *beams]


def goblet(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A goblet: a thin base, a stem and a round bowl."""
    base_r, stem_h = rng.uniform(0.05, 0.08), rng.uniform(0.08, 0.15)
    bowl = creation.icosphere(3, radius=1.0)
    bowl.apply_scale([rng.uniform(0.06, 0.09)] * 2 + [rng.uniform(0.06, 0.1)])
    return [_cyl(base_r, 0.01, 0.0), _cyl(0.01, stem_h, 0.01),
            _at(bowl, z=0.01 + stem_h + 0.05)]


def ring_stand(rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """A ring stand: a base and a pole with two or three rings."""
    base_r, pole_h = rng.uniform(0.05, 0.08), rng.uniform(0.15, 0.3)
    rings = []
    for z in np.linspace(0.06, pole_h, int(rng.integers(2, 4))):
        torus = creation.torus(rng.uniform(0.03, 0.06), 0.008, major_sections=24,
                               minor_sections=8)
        rings.append(_at(torus, z=z))
    return [_cyl(base_r, 0.01, 0.0), _cyl(0.008, pole_h, 0.01), *rings]


SHAPES: dict[str, Shape] = {
    "lamp": lamp, "mushroom": mushroom, "rocket": rocket, "stool": stool, "bench": bench,
    "snowman": snowman, "dumbbell": dumbbell, "arch": arch, "gate": gate, "goblet": goblet,
    "ring_stand": ring_stand,
}


def write_models(root: Path, models_per_class: int, seed: int) -> dict[str, int]:
    """Every class's models as STL files under ``root/<class>/<class>_<k>.stl``.

    Args:
        root: an existing folder.
        models_per_class: models a class.
        seed: the set's seed; model k of class c is drawn from ``default_rng([seed, c, k])``.

    Returns:
        Class -> number of files written.
    """
    counts: dict[str, int] = {}
    for c, (name, shape) in enumerate(SHAPES.items()):
        folder = root / name
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(models_per_class):
            rng = np.random.default_rng([seed, c, i])
            mesh = trimesh.util.concatenate(shape(rng))
            mesh.export(folder / f"{name}_{i:02d}.stl")
        counts[name] = models_per_class
    return counts


def build_mesh_set(out: Path | None = None, *, models_per_class: int = DEFAULT_MODELS,
                   seed: int = DEFAULT_SEED) -> dict[str, int]:
    """Build the mesh set's folder, swapped in whole (a rebuild replaces it).

    Args:
        out: the mesh folder (default :data:`DEFAULT_OUT`).
        models_per_class: models a class; the default split takes 11 (4 train / 3 volume /
            4 test) and ``dataset.split: auto`` at least 5.
        seed: the set's seed.

    Returns:
        Class -> number of models written.

    Raises:
        DatasetBuildError: fewer than one model a class.
    """
    if models_per_class < 1:
        raise DatasetBuildError(f"--models must be 1 or more, got {models_per_class}")
    building = building_folder(out if out is not None else DEFAULT_OUT)
    try:
        counts = write_models(building, models_per_class, seed)
    except BaseException:
        shutil.rmtree(building, ignore_errors=True)
        raise
    swap_in(building, out if out is not None else DEFAULT_OUT)
    return counts
