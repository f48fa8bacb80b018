"""The embedded default dataset: parametric 3D models of everyday classes, from a seed."""

from rapomdp.data.procedural.classes import CLASS_BUILDERS, PROCEDURAL_CLASSES, generate_model

__all__ = ["CLASS_BUILDERS", "PROCEDURAL_CLASSES", "generate_model"]
