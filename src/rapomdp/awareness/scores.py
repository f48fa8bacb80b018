"""Viewpoint scores (paper Eq. 6): the mean saliency of the voxels visible from a viewpoint
(or their sum, the salient area seen), normalised per class to [0, 1] over the viewpoints."""

from __future__ import annotations

import numpy as np
from scipy import sparse


def viewpoint_scores(visibility: sparse.spmatrix, voxel_scores: np.ndarray) -> np.ndarray:
    """Mean saliency (views,) of the non-empty voxels each view sees (Eq. 6 before alpha).

    ``voxel_scores`` is flat (voxels,) with NaN for empty voxels; a view that sees no scored
    voxel gets NaN.
    """
    scores = np.asarray(voxel_scores, dtype=np.float64).reshape(-1)
    if visibility.shape[1] != scores.size:
        raise ValueError(f"visibility has {visibility.shape[1]} voxels, the volume {scores.size}")
    scored = ~np.isnan(scores)
    vis = sparse.csr_matrix(visibility, dtype=np.float64)
    total = vis @ np.where(scored, scores, 0.0)
    count = vis @ scored.astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1.0), np.nan)


def viewpoint_salient_area(visibility: sparse.spmatrix, voxel_scores: np.ndarray) -> np.ndarray:
    """Summed saliency (views,) of the non-empty voxels each view sees: Eq. 6 with a constant
    alpha, which grows with how much of the salient surface is in view (0 when none is)."""
    scores = np.asarray(voxel_scores, dtype=np.float64).reshape(-1)
    if visibility.shape[1] != scores.size:
        raise ValueError(f"visibility has {visibility.shape[1]} voxels, the volume {scores.size}")
    vis = sparse.csr_matrix(visibility, dtype=np.float64)
    return np.asarray(vis @ np.nan_to_num(scores, nan=0.0))


def normalise_scores(scores: np.ndarray) -> np.ndarray:
    """Scores rescaled to [0, 1] over the viewpoints (last axis), per row; NaN -> 0.

    A row whose scores are all equal becomes 0.5 everywhere (no viewpoint is better).
    """
    scores = np.asarray(scores, dtype=np.float64)
    low = np.nanmin(scores, axis=-1, keepdims=True)
    high = np.nanmax(scores, axis=-1, keepdims=True)
    span = high - low
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(span > 1e-12, (scores - low) / np.where(span > 1e-12, span, 1.0), 0.5)
    return np.nan_to_num(out, nan=0.0)
