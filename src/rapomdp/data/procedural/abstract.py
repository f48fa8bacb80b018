"""Abstract shape families: many classes of primitive assemblies, for pretraining a backbone.

The 35 procedural classes (:mod:`rapomdp.data.procedural.classes`) are named objects built for
evaluation. A pretraining corpus needs the opposite: many classes that are *not* any evaluation
class, so that what a backbone learns from them is depth shape in general. A family here is a
body primitive (box, cylinder, ellipsoid, cone, torus, capsule or prism, with its own
proportions and taper) and one to four part rules (a primitive of its own size, on a side of
the body, single, mirrored or in a ring), all drawn from the family's index. A model of the
family varies every proportion, anchor and taper around the family's values (part-level
deformations) and may lose an optional part, so models of a family are alike but not copies,
and families differ in structure, not only in size. Families are named ``abstract_NNN``.

Example:
    >>> from rapomdp.data.procedural.abstract import abstract_family, generate_abstract
    >>> family = abstract_family(3)
    >>> family.name, 1 <= len(family.parts) <= 4
    ('abstract_003', True)
    >>> mesh = generate_abstract(family, seed=0, index=0)
    >>> bool(mesh.is_volume or len(mesh.faces) > 0), float(mesh.bounds[0, 2]) == 0.0
    (True, True)
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
import trimesh
from trimesh import creation

from rapomdp.data.procedural.parts import assemble

#: The primitives a body or a part is made of, each built in the unit cube [-0.5, 0.5]^3.
PRIMITIVES = ("box", "cylinder", "ellipsoid", "cone", "torus", "capsule", "prism")
#: Where a part sits on the body: the side's unit direction in body coordinates.
SIDES = {"front": (1, 0, 0), "back": (-1, 0, 0), "left": (0, 1, 0), "right": (0, -1, 0),
         "top": (0, 0, 1), "bottom": (0, 0, -1)}
#: How a part rule places copies: one, a pair mirrored across the xz plane, or a ring of 3-4
#: about the vertical axis (legs, feet, knobs).
LAYOUTS = ("single", "mirrored", "ring")


@dataclass(frozen=True)
class PartRule:
    """One part of a family: its primitive, size and place relative to the body.

    Attributes:
        primitive: one of :data:`PRIMITIVES`.
        size: (3,) the part's extents as fractions of the body's.
        side: the body side it sits on (:data:`SIDES`).
        offset: (2,) where on that side, in [-1, 1] of the side's two other axes.
        layout: one of :data:`LAYOUTS`.
        count: copies of a ring (3 or 4; 1 or 2 otherwise).
        optional: a model drops the part with probability 0.3.
    """

    primitive: str
    size: tuple[float, ...]
    side: str
    offset: tuple[float, ...]
    layout: str
    count: int
    optional: bool


@dataclass(frozen=True)
class AbstractFamily:
    """A family's rules: the body primitive, its extents (metres), taper and parts."""

    name: str
    body: str
    extents_m: tuple[float, ...]
    taper: float
    parts: tuple[PartRule, ...]
    spread: float


def _rng(*words: object) -> np.random.Generator:
    digest = hashlib.sha256("/".join(str(w) for w in words).encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


def abstract_family(index: int, seed: int = 0) -> AbstractFamily:
    """Family ``index``'s rules (the same ``(index, seed)`` always gives the same family).

    Args:
        index: the family's number (its name is ``abstract_{index:03d}``).
        seed: the generator's seed (another seed gives other families).

    Returns:
        The family.
    """
    if index < 0:
        raise ValueError(f"family index must be non-negative, got {index}")
    rng = _rng("abstract-family", seed, index)
    body = str(rng.choice(PRIMITIVES))
    extents = tuple(float(v) for v in 0.3 * np.exp(rng.uniform(np.log(0.25), 0.0, 3)))
    parts = []
    for _ in range(int(rng.integers(1, 5))):
        layout = str(rng.choice(LAYOUTS, p=(0.5, 0.3, 0.2)))
        parts.append(PartRule(
            primitive=str(rng.choice(PRIMITIVES)),
            size=tuple(float(v) for v in np.exp(rng.uniform(np.log(0.12), np.log(0.8), 3))),
            side=str(rng.choice(list(SIDES))),
            offset=tuple(float(v) for v in rng.uniform(-0.8, 0.8, 2)),
            layout=layout,
            count=int(rng.integers(3, 5)) if layout == "ring" else (2 if layout == "mirrored"
                                                                    else 1),
            optional=bool(rng.random() < 0.3),
        ))
    return AbstractFamily(f"abstract_{index:03d}", body, extents,
                          float(rng.uniform(-0.5, 0.5)) if rng.random() < 0.5 else 0.0,
                          tuple(parts), float(rng.uniform(0.08, 0.2)))


def unit_primitive(kind: str) -> trimesh.Trimesh:
    """A closed primitive filling the unit cube [-0.5, 0.5]^3 (its axis along z).

    Args:
        kind: one of :data:`PRIMITIVES`.

    Returns:
        The mesh.
    """
    if kind == "box":
        return creation.box(extents=(1.0, 1.0, 1.0))
    if kind == "cylinder":
        return creation.cylinder(radius=0.5, height=1.0, sections=16)
    if kind == "ellipsoid":
        return creation.icosphere(subdivisions=2, radius=0.5)
    if kind == "cone":
        mesh = creation.cone(radius=0.5, height=1.0, sections=16)
        mesh.apply_translation((0.0, 0.0, -0.5))
        return mesh
    if kind == "torus":
        mesh = creation.torus(0.36, 0.14, major_sections=20, minor_sections=8)
        mesh.vertices[:, 2] *= 0.5 / 0.14
        return mesh
    if kind == "capsule":
        mesh = creation.capsule(height=0.5, radius=0.25, count=(12, 12))
        mesh.vertices *= (2.0, 2.0, 1.0)
        return mesh
    if kind == "prism":
        return creation.cylinder(radius=0.5, height=1.0, sections=3)
    raise ValueError(f"unknown primitive {kind!r}; primitives are: {', '.join(PRIMITIVES)}")


def _shaped(kind: str, extents: np.ndarray, centre: np.ndarray, taper: float = 0.0,
            yaw: float = 0.0) -> trimesh.Trimesh:
    mesh = unit_primitive(kind)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if taper:
        vertices[:, :2] *= (1.0 - taper * vertices[:, 2:3])[:, :1]
    vertices = vertices * extents
    cos, sin = np.cos(yaw), np.sin(yaw)
    vertices = vertices @ np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]]).T
    return trimesh.Trimesh(vertices=vertices + centre, faces=mesh.faces, process=False)


def generate_abstract(family: AbstractFamily, seed: int, index: int) -> trimesh.Trimesh:
    """Model ``index`` of a family, standing on z = 0 (metres); the same arguments give the
    same mesh.

    Args:
        family: the family (:func:`abstract_family`).
        seed: the corpus seed.
        index: the model's number within the family.

    Returns:
        The model's mesh (its parts concatenated; overlaps are hidden).
    """
    rng = _rng("abstract-model", seed, family.name, index)
    jitter = family.spread

    def vary(values: tuple[float, ...]) -> np.ndarray:
        return np.asarray(values) * np.exp(rng.normal(0.0, jitter, len(values)))

    body = vary(family.extents_m)
    meshes = [_shaped(family.body, body, np.zeros(3),
                      float(np.clip(family.taper + rng.normal(0.0, 0.1), -0.7, 0.7)))]
    half = body / 2.0
    for rule in family.parts:
        if rule.optional and rng.random() < 0.3:
            continue
        size = vary(rule.size) * body
        direction = np.asarray(SIDES[rule.side], dtype=np.float64)
        axis = int(np.flatnonzero(direction)[0])
        others = [a for a in range(3) if a != axis]
        anchor = np.zeros(3)
        anchor[axis] = direction[axis] * (half[axis] + size[axis] * 0.35)
        offset = np.clip(np.asarray(rule.offset) + rng.normal(0.0, 0.1, 2), -1.0, 1.0)
        anchor[others] = offset * half[others] * 0.8
        if rule.layout == "single":
            centres = [anchor]
        elif rule.layout == "mirrored":
            mirrored = anchor.copy()
            mirrored[1] = -mirrored[1] if abs(mirrored[1]) > 1e-6 else -anchor[1] - half[1]
            centres = [anchor, mirrored]
        else:
            angles = np.arange(rule.count) * 2.0 * np.pi / rule.count
            radius = np.hypot(anchor[0], anchor[1]) or float(half[:2].mean())
            centres = [np.array([radius * np.cos(a), radius * np.sin(a), anchor[2]])
                       for a in angles]
        yaw = float(rng.normal(0.0, 0.15))
        meshes += [_shaped(rule.primitive, size, c, yaw=yaw) for c in centres]
    mesh = assemble(meshes)
    mesh.vertices[:, 2] -= mesh.vertices[:, 2].min()
    return mesh
