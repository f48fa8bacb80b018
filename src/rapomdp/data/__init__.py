"""Meshes and datasets: loading, dataset layouts, splits, the procedural generator, rendering."""
