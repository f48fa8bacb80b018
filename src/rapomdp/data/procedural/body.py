"""What a procedural class is made of: a family's shared body and the class's own parts.

A *family* is a set of confusable classes that share one body builder (the same distribution of
proportions and optional parts); each class adds the parts that tell it apart. Those parts sit on
fixed sides of the canonical pose (front = +x, Z up), so they are seen only from some directions:
from the others the classes of a family look alike.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import trimesh

Parts = list[trimesh.Trimesh]


@dataclass
class Body:
    """A family's shared parts (named) and the dimensions the class parts attach to (metres)."""

    parts: dict[str, Parts]
    dims: dict[str, float] = field(default_factory=dict)


BodyBuilder = Callable[[np.random.Generator], Body]
PartsBuilder = Callable[[Body, np.random.Generator], dict[str, Parts]]


@dataclass(frozen=True)
class ProceduralClass:
    """One class: its family's body, its own parts and where its telling part is seen from.

    ``cue`` names the part that tells the class from the rest of its family ("" when the class
    differs by the absence of parts); ``seen_from`` is an (elevation, azimuth) in degrees from
    which the cue is visible and from whose opposite azimuth the body hides it.
    """

    name: str
    family: str
    body: BodyBuilder
    parts: PartsBuilder
    cue: str = ""
    seen_from: tuple[float, float] | None = None
