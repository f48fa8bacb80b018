"""The embedded default dataset: parametric 3D models in families of confusable classes."""

from rapomdp.data.procedural.classes import (
    CLASSES,
    FAMILIES,
    PROCEDURAL_CLASSES,
    generate_model,
    generate_parts,
)

__all__ = ["CLASSES", "FAMILIES", "PROCEDURAL_CLASSES", "generate_model", "generate_parts"]
