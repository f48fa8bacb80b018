"""The procedural classes (second generation): 35 classes in 10 families of confusable classes.

Every class of a family is built on the family's shared body (the same distribution of
proportions and optional parts) and adds its own parts on fixed sides of a canonical pose:
front = +x, Z up, standing on z = 0, in metres at roughly real scale (the dataset stage
normalises the size). So a single view is ambiguous wherever the body hides a class's telling
parts, and telling from another side: a mug seen from -x is a cup, a dresser seen from behind is
a cabinet, a pickup seen from the front is a van. Within a class, proportions, part shapes and
optional parts vary widely, so that models of a class are not near-copies.

The families and what tells their classes apart (see each module's docstring):

- storage (furniture): cabinet, dresser, bookshelf, crate: the front (+x) or the open top;
- tables (furniture): table, desk, workbench: a drawer pedestal or a low shelf under the top;
- seating (furniture): stool, chair, armchair, wheelchair: back (-x), arms, wheels;
- cups (vessels): cup, mug, jug, beaker: a handle at +x, or at -x with a lip at +x, a lip;
- pots (vessels): teapot, kettle, saucepan: spouts at +x and handles;
- bottles (vessels): bottle, vase, jar, amphora: the top (capped, open, lidded) and handles;
- cars (vehicles): car, van, suv, pickup: the rear (-x);
- two-wheelers (vehicles): bicycle, motorbike, scooter: what is between the wheels;
- panels (objects): monitor, television, picture_frame: the front's relief and the stand;
- small (objects): eyeglasses, sunglasses, scissors: thin rings, lenses.
"""

from __future__ import annotations

import hashlib

import numpy as np
import trimesh

from rapomdp.data.procedural import furniture, objects, vehicles, vessels
from rapomdp.data.procedural.body import BodyBuilder, ProceduralClass
from rapomdp.data.procedural.parts import assemble

FRONT, BACK = 0.0, 180.0


def _family(family: str, body: BodyBuilder,
            *classes: tuple[object, str, tuple[float, float] | None]) -> list[ProceduralClass]:
    out = []
    for builder, cue, seen_from in classes:
        name = builder.__name__  # type: ignore[attr-defined]
        out.append(ProceduralClass(name, family, body, builder, cue, seen_from))  # type: ignore[arg-type]
    return out


_CLASSES: list[ProceduralClass] = [
    *_family("storage", furniture.storage_body,
             (furniture.cabinet, "doors", (0.0, FRONT)),
             (furniture.dresser, "drawers", (0.0, FRONT)),
             (furniture.bookshelf, "shelves", (0.0, FRONT)),
             (furniture.crate, "", None)),
    *_family("tables", furniture.table_body,
             (furniture.table, "", None),
             (furniture.desk, "drawers", (0.0, FRONT)),
             (furniture.workbench, "shelf", None)),
    *_family("seating", furniture.seat_body,
             (furniture.stool, "", None),
             (furniture.chair, "back", None),
             (furniture.armchair, "arms", None),
             (furniture.wheelchair, "wheels", None)),
    *_family("cups", vessels.cup_body,
             (vessels.cup, "", None),
             (vessels.mug, "handle", (0.0, FRONT)),
             (vessels.jug, "handle", (0.0, BACK)),
             (vessels.beaker, "lip", None)),
    *_family("pots", vessels.pot_body,
             (vessels.teapot, "spout", (0.0, FRONT)),
             (vessels.kettle, "spout", (0.0, FRONT)),
             (vessels.saucepan, "handle", (0.0, BACK))),
    *_family("bottles", vessels.bottle_body,
             (vessels.bottle, "neck", None),
             (vessels.vase, "neck", None),
             (vessels.jar, "lid", None),
             (vessels.amphora, "handles", None)),
    *_family("cars", vehicles.car_body,
             (vehicles.car, "rear", (0.0, BACK)),
             (vehicles.van, "rear", None),
             (vehicles.suv, "spare", (0.0, BACK)),
             (vehicles.pickup, "bed", (0.0, BACK))),
    *_family("two-wheelers", vehicles.two_wheeler_body,
             (vehicles.bicycle, "pedals", None),
             (vehicles.motorbike, "engine", None),
             (vehicles.scooter, "floor", None)),
    *_family("panels", objects.panel_body,
             (objects.monitor, "housing", (0.0, BACK)),
             (objects.television, "feet", None),
             (objects.picture_frame, "frame", (0.0, FRONT))),
    *_family("small", objects.small_body,
             (objects.eyeglasses, "", None),
             (objects.sunglasses, "", None),
             (objects.scissors, "", None)),
]

CLASSES: dict[str, ProceduralClass] = {c.name: c for c in _CLASSES}
PROCEDURAL_CLASSES: tuple[str, ...] = tuple(CLASSES)
FAMILIES: dict[str, tuple[str, ...]] = {
    family: tuple(c.name for c in _CLASSES if c.family == family)
    for family in dict.fromkeys(c.family for c in _CLASSES)
}


def _class(class_name: str) -> ProceduralClass:
    if class_name not in CLASSES:
        raise KeyError(
            f"unknown procedural class '{class_name}'; classes are: {', '.join(CLASSES)}"
        )
    return CLASSES[class_name]


def model_rng(class_name: str, seed: int, index: int) -> np.random.Generator:
    """The generator of model ``index`` of a class: from the seed, the class's name, the index."""
    if index < 0:
        raise ValueError(f"model index must be non-negative, got {index}")
    digest = hashlib.sha256(f"procedural/{class_name}".encode()).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "little"), index])


def build_parts(class_name: str, rng: np.random.Generator) -> dict[str, trimesh.Trimesh]:
    """A model's named parts: the family body's (``body/<name>``) then the class's own.

    The body is drawn first from ``rng``: two classes of a family given generators in the same
    state get the same body.
    """
    spec = _class(class_name)
    body = spec.body(rng)
    own = spec.parts(body, rng)
    named = {f"body/{k}": v for k, v in body.parts.items()}
    named.update(own)
    return {name: assemble(parts) for name, parts in named.items() if parts}


def generate_parts(class_name: str, seed: int, index: int) -> dict[str, trimesh.Trimesh]:
    """The named parts of model ``index`` of a class, stood on the floor (z = 0) together."""
    parts = build_parts(class_name, model_rng(class_name, seed, index))
    floor = min(float(p.vertices[:, 2].min()) for p in parts.values())
    for part in parts.values():
        part.vertices[:, 2] -= floor
    return parts


def generate_model(class_name: str, seed: int, index: int) -> trimesh.Trimesh:
    """Model ``index`` of a procedural class; the same (seed, class, index) gives the same mesh."""
    return assemble(list(generate_parts(class_name, seed, index).values()))
