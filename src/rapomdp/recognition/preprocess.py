"""The one preprocessing function from a depth image to the network's input.

Training, saliency and run time all call :func:`preprocess`, so the network never sees an input
made another way. For each depth image (metres, 0 = background):

1. the object is the set of pixels with depth > 0 (segment the floor and walls away first);
2. its *reference depth* is the median depth of those pixels, estimated from the image itself
   so that run time needs no pose (the camera looks at the centroid, so this is the distance of
   the object's visible middle);
3. a square crop of ``crop_size_m`` metres at the reference depth is centred on the object's
   pixel bounding box, widened if the object would not fit, so its size in pixels scales with
   1 / distance and the input barely changes with the camera's distance;
4. depth becomes ``clip((reference - depth) / depth_range_m, -1, 1)`` (near is positive) and the
   background gets ``background``;
5. the crop is resampled to ``input_size_px`` squared with an exact box filter (each input pixel
   averages the source area it covers; two batched matrix products, separable), so thin parts
   neither vanish nor alias when the crop is downscaled.

Augmentation (training only) moves and scales the crop box; it is an argument of the same
function. :func:`input_to_image` maps a map over the input (a saliency map) back onto the
source image's pixels through the same boxes.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class PreprocessParams:
    """Parameters of :func:`preprocess`; stored in every checkpoint and checked on load."""

    input_size_px: int = 64
    crop_size_m: float = 0.5
    depth_range_m: float = 0.2
    background: float = -1.0
    fit_margin: float = 0.05

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


@dataclass
class Preprocessed:
    """Network inputs and how they were cut from the source images.

    ``boxes`` (n, 4) holds each crop's centre (u, v) and its width and height in source pixels;
    ``reference_depth_m`` (n,) is NaN for an image without any object pixel.
    """

    images: np.ndarray
    boxes: np.ndarray
    reference_depth_m: np.ndarray


def as_depth_batch(depth_m: np.ndarray) -> np.ndarray:
    """Depth images as a float32 batch (n, H, W); one image (H, W) becomes a batch of one."""
    depth = np.asarray(depth_m, dtype=np.float32)
    if depth.ndim == 2:
        depth = depth[None]
    if depth.ndim != 3:
        raise ValueError(f"depth images must be (H, W) or (n, H, W), got shape {depth.shape}")
    return depth


@dataclass
class ObjectExtents:
    """What :func:`crop_boxes` reads of each depth image (n,): the object's pixel bounding box
    (rows ``v_min..v_max``, columns ``u_min..u_max``) and its reference depth in metres (the
    lower median of its depths), NaN and an arbitrary box for an image without object pixels.

    They depend on the image alone: training computes them once per image
    (:func:`object_extents`) and only the augmentation's shift and scale change per epoch.
    """

    u_min: np.ndarray
    u_max: np.ndarray
    v_min: np.ndarray
    v_max: np.ndarray
    reference_depth_m: np.ndarray
    image_shape: tuple[int, int]

    def __getitem__(self, index: np.ndarray | slice) -> ObjectExtents:
        return ObjectExtents(self.u_min[index], self.u_max[index], self.v_min[index],
                             self.v_max[index], self.reference_depth_m[index], self.image_shape)

    def __len__(self) -> int:
        return int(self.reference_depth_m.shape[0])


def object_extents(depth_m: np.ndarray, batch_size: int = 512) -> ObjectExtents:
    """The :class:`ObjectExtents` of depth images (n, H, W) or (H, W) in metres, ``batch_size``
    images at a time (each image's result is the same in any batch)."""
    depth = as_depth_batch(depth_m)
    n, h, w = depth.shape
    parts = []
    for start in range(0, max(n, 1), batch_size):
        d = depth[start : start + batch_size]
        valid = d > 0
        rows, cols = valid.any(axis=2), valid.any(axis=1)
        has_object = rows.any(axis=1)
        flat = torch.from_numpy(np.where(valid, d, np.float32(np.nan)).reshape(d.shape[0], -1))
        reference = torch.nanmedian(flat, dim=1).values.double().numpy()  # lower median
        parts.append((np.argmax(cols, axis=1), w - 1 - np.argmax(cols[:, ::-1], axis=1),
                      np.argmax(rows, axis=1), h - 1 - np.argmax(rows[:, ::-1], axis=1),
                      np.where(has_object, reference, np.nan)))
    u_min, u_max, v_min, v_max, reference = (np.concatenate(a) for a in zip(*parts, strict=True))
    return ObjectExtents(u_min, u_max, v_min, v_max, reference, (h, w))


def crop_boxes(
    depth_m: np.ndarray,
    fx_px: float,
    fy_px: float,
    params: PreprocessParams,
    shift: np.ndarray | None = None,
    scale: np.ndarray | None = None,
    extents: ObjectExtents | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Crop boxes (n, 4) = (u, v, width, height) in pixels and reference depths (n,) in metres.

    ``shift`` (n, 2) moves a box by that fraction of its size; ``scale`` (n,) multiplies its
    size (augmentation). An image without object pixels gets the whole image as its box.
    ``extents``: the images' :func:`object_extents`, when already known.
    """
    depth = as_depth_batch(depth_m)
    n, h, w = depth.shape
    e = extents if extents is not None else object_extents(depth)
    if len(e) != n or e.image_shape != (h, w):
        raise ValueError(f"extents of {len(e)} images of {e.image_shape} for images {depth.shape}")
    reference = e.reference_depth_m
    has_object = ~np.isnan(reference)
    u_min, u_max, v_min, v_max = e.u_min, e.u_max, e.v_min, e.v_max
    safe_ref = np.where(has_object, reference, 1.0)
    # the object's extent in metres at the reference depth, and the square side that holds it
    extent_m = np.maximum((u_max - u_min + 1) / fx_px, (v_max - v_min + 1) / fy_px) * safe_ref
    side_m = np.maximum(params.crop_size_m, (1.0 + params.fit_margin) * extent_m)
    boxes = np.stack(
        [
            (u_min + u_max) / 2.0,
            (v_min + v_max) / 2.0,
            side_m * fx_px / safe_ref,
            side_m * fy_px / safe_ref,
        ],
        axis=1,
    )
    if scale is not None:
        boxes[:, 2:] *= np.asarray(scale, dtype=np.float64).reshape(n, 1)
    if shift is not None:
        boxes[:, :2] += np.asarray(shift, dtype=np.float64).reshape(n, 2) * boxes[:, 2:]
    whole = np.array([(w - 1) / 2.0, (h - 1) / 2.0, float(w), float(h)])
    boxes[~has_object] = whole
    return boxes, reference


def _area_weights(start: np.ndarray, length: np.ndarray, n_out: int, n_in: int) -> torch.Tensor:
    """Box-filter resampling weights (n, n_out, n_in) along one axis.

    In edge coordinates (input pixel i spans [i, i + 1]), output pixel j of image k spans
    ``start[k] + [j, j + 1] * length[k] / n_out``; its weight on input pixel i is the overlap
    divided by its own length, so weights sum to the covered fraction (1 inside the input).
    """
    step = torch.from_numpy(np.asarray(length, dtype=np.float32) / n_out)[:, None, None]
    lo = torch.from_numpy(np.asarray(start, dtype=np.float32))[:, None, None] + (
        torch.arange(n_out, dtype=torch.float32)[None, :, None] * step
    )
    edges = torch.arange(n_in, dtype=torch.float32)[None, None, :]
    # overlap of [lo, lo + step] with [i, i + 1]: clip(hi - i, 0, 1) - clip(lo - i, 0, 1)
    overlap = (lo + step - edges).clamp_(0.0, 1.0).sub_((lo - edges).clamp_(0.0, 1.0))
    return overlap.div_(step)


def _resample(images: torch.Tensor, rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
    """``rows @ image @ cols^T`` for every image: separable resampling, two batched matmuls."""
    return torch.bmm(torch.bmm(rows, images), cols.mT)


def preprocess(
    depth_m: np.ndarray,
    fx_px: float,
    fy_px: float,
    params: PreprocessParams,
    shift: np.ndarray | None = None,
    scale: np.ndarray | None = None,
    extents: ObjectExtents | None = None,
) -> Preprocessed:
    """Network inputs (n, 1, S, S) float32 from depth images (n, H, W) or (H, W) in metres.

    ``fx_px``, ``fy_px`` are the camera's focal lengths at the images' resolution; ``shift`` and
    ``scale`` are the training augmentation, ``extents`` the images' :func:`object_extents`
    when already known (see :func:`crop_boxes`).
    """
    depth = as_depth_batch(depth_m)
    n, h, w = depth.shape
    boxes, reference = crop_boxes(depth, fx_px, fy_px, params, shift, scale, extents)
    ref = torch.from_numpy(np.where(np.isnan(reference), 0.0, reference).astype(np.float32))
    size = params.input_size_px
    rows = _area_weights(boxes[:, 1] + 0.5 - boxes[:, 3] / 2, boxes[:, 3], size, h)
    cols = _area_weights(boxes[:, 0] + 0.5 - boxes[:, 2] / 2, boxes[:, 2], size, w)
    with torch.no_grad():
        d = torch.from_numpy(depth)
        value = (ref[:, None, None] - d).div_(params.depth_range_m).clamp_(-1.0, 1.0)
        # resample (value - background), which is 0 off the object and outside the image
        offset = value.sub_(params.background).masked_fill_(d <= 0, 0.0)
        images = _resample(offset, rows, cols)[:, None] + params.background
    return Preprocessed(images.numpy().astype(np.float32), boxes, reference)


def input_to_image(maps: np.ndarray, boxes: np.ndarray, height: int, width: int) -> np.ndarray:
    """Maps over the network input (n, S, S) resampled onto source pixels (n, height, width).

    Pixels outside a crop get 0. This inverts the crop of :func:`preprocess` for saliency.
    """
    maps = np.asarray(maps, dtype=np.float32)
    if maps.ndim == 2:
        maps = maps[None]
    n, size, _ = maps.shape
    boxes = np.asarray(boxes, dtype=np.float64).reshape(n, 4)
    # source pixel i spans [i, i + 1] in edge coordinates, i.e. this span over the map's pixels
    start = np.asarray(boxes[:, :2] + 0.5 - boxes[:, 2:] / 2)
    per_px = size / boxes[:, 2:]
    rows = _area_weights(-start[:, 1] * per_px[:, 1], height * per_px[:, 1], height, size)
    cols = _area_weights(-start[:, 0] * per_px[:, 0], width * per_px[:, 0], width, size)
    with torch.no_grad():
        out = _resample(torch.from_numpy(maps), rows, cols)
    return out.numpy()
