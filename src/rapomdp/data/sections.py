"""What the data stages' keys hash besides the dataset (a light module: the stage graph, e.g.
for ``rapomdp status``, is read without loading the renderer)."""

from __future__ import annotations

#: The xrho stage's images depend on these sections (the dataset is its input).
XRHO_SECTIONS = ("seed", "camera", "render", "viewpoints")
