"""rapomdp: active object recognition on depth images with recognition self-awareness.

The pipeline's stages live in one package each: ``geometry`` (viewspheres, camera, voxels),
``data`` (meshes, datasets, procedural generator, depth renderer), and the later stages that
build on them. ``rapomdp.cli`` is the command line; ``rapomdp.workspace`` caches stages.
"""

__version__ = "0.1.0"
