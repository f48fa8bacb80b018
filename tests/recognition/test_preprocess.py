"""The one preprocessing function: crop, depth normalisation, resize, and its inverse."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.recognition.preprocess import (
    PreprocessParams,
    crop_boxes,
    input_to_image,
    object_extents,
    preprocess,
)

PARAMS = PreprocessParams()


@pytest.mark.parametrize("class_name", ["bicycle", "table", "mug", "eyeglasses"])
def test_crop_contains_the_object(class_name, intrinsics, render_model):
    directions = fibonacci_directions(24)
    for radius_m in (0.45, 0.6, 0.9):
        depth = render_model(class_name, directions * radius_m)
        boxes, reference = crop_boxes(depth, intrinsics.fx, intrinsics.fy, PARAMS)
        rows, cols = np.nonzero(depth.any(axis=2)), np.nonzero(depth.any(axis=1))
        for i in range(depth.shape[0]):
            v = rows[1][rows[0] == i]
            u = cols[1][cols[0] == i]
            u_c, v_c, width, height = boxes[i]
            assert u_c - width / 2 <= u.min() - 0.5 and u.max() + 0.5 <= u_c + width / 2
            assert v_c - height / 2 <= v.min() - 0.5 and v.max() + 0.5 <= v_c + height / 2
        assert np.all(np.abs(reference - radius_m) < 0.2 + 1e-6)
        images = preprocess(depth, intrinsics.fx, intrinsics.fy, PARAMS).images[:, 0]
        # nothing is cut: the input's outer ring is pure background
        ring = np.concatenate([images[:, 0], images[:, -1], images[:, :, 0], images[:, :, -1]], 1)
        np.testing.assert_allclose(ring, PARAMS.background, atol=1e-5)


def test_object_wider_than_the_crop_still_fits(intrinsics):
    depth = np.zeros((1, 120, 160), np.float32)
    depth[0, 10:110, 5:155] = 0.6  # a 0.62 m wide slab at 0.6 m, wider than crop_size_m
    boxes, _ = crop_boxes(depth, intrinsics.fx, intrinsics.fy, PARAMS)
    assert boxes[0, 2] >= 150 * (1 + PARAMS.fit_margin) - 1e-9


def test_a_scale_scales_the_crop_about_its_centre(intrinsics):
    depth = np.zeros((2, 120, 160), np.float32)
    depth[:, 40:80, 60:100] = 0.6
    plain, _ = crop_boxes(depth, intrinsics.fx, intrinsics.fy, PARAMS)
    iso, _ = crop_boxes(depth, intrinsics.fx, intrinsics.fy, PARAMS, scale=np.array([1.1, 0.9]))
    np.testing.assert_allclose(iso[:, 2:], plain[:, 2:] * np.array([[1.1], [0.9]]))
    np.testing.assert_allclose(iso[:, :2], plain[:, :2])  # the centre stays


def test_input_barely_changes_with_the_camera_distance(intrinsics, render_model):
    directions = fibonacci_directions(12)
    near, mid, far = (
        preprocess(render_model("chair", directions * r), intrinsics.fx,
                   intrinsics.fy, PARAMS).images
        for r in (0.45, 0.6, 0.9)
    )
    between_views = np.abs(mid[1:] - mid[:-1]).mean()
    for other in (near, far):
        assert np.abs(other - mid).mean() < 0.5 * between_views


def test_depth_is_normalised_around_the_median(intrinsics, render_model):
    depth = render_model("teapot", fibonacci_directions(6) * 0.6)
    shifted = np.where(depth > 0, depth + 0.3, 0.0)  # the same view 0.3 m further along the axis
    out, out_shifted = (preprocess(d, intrinsics.fx, intrinsics.fy, PARAMS) for d in
                        (depth, shifted))
    np.testing.assert_allclose(out_shifted.reference_depth_m, out.reference_depth_m + 0.3,
                               atol=1e-5)
    assert out.images.min() >= PARAMS.background - 1e-6 and out.images.max() <= 1.0 + 1e-6
    assert out.images.shape == (6, 1, PARAMS.input_size_px, PARAMS.input_size_px)
    assert out.images.dtype == np.float32
    # mid-depth pixels map to ~0, the median to exactly 0 in the source
    median_px = np.abs(depth - out.reference_depth_m[:, None, None]) < 1e-6
    assert median_px.any(axis=(1, 2)).all()


def test_empty_image_gives_background_and_nan_reference(intrinsics):
    out = preprocess(np.zeros((120, 160), np.float32), intrinsics.fx, intrinsics.fy, PARAMS)
    assert np.isnan(out.reference_depth_m[0])
    np.testing.assert_array_equal(out.images, PARAMS.background)


def test_shift_augmentation_moves_the_content(intrinsics, render_model):
    depth = render_model("mug", fibonacci_directions(4) * 0.6)
    base = preprocess(depth, intrinsics.fx, intrinsics.fy, PARAMS).images[:, 0]
    moved = preprocess(depth, intrinsics.fx, intrinsics.fy, PARAMS,
                       shift=np.tile([0.1, 0.0], (4, 1))).images[:, 0]

    def column_centroid(images: np.ndarray) -> np.ndarray:
        mass = images - PARAMS.background
        cols = np.arange(images.shape[2])
        return (mass.sum(axis=1) * cols).sum(axis=1) / mass.sum(axis=(1, 2))

    # the crop moves right by 10 % of its side, so the object moves left by 6.4 input pixels
    np.testing.assert_allclose(column_centroid(base) - column_centroid(moved),
                               0.1 * PARAMS.input_size_px, atol=0.6)


def test_input_to_image_inverts_the_crop(intrinsics, render_model):
    depth = render_model("car", fibonacci_directions(8) * 0.6)
    out = preprocess(depth, intrinsics.fx, intrinsics.fy, PARAMS)
    mask = input_to_image(out.images[:, 0] - PARAMS.background, out.boxes, 120, 160)
    agreement = ((mask > 0.5) == (depth > 0)).mean()
    assert agreement > 0.98
    # a constant map comes back as that constant inside the crop and 0 outside it
    ones = input_to_image(np.ones((8, 64, 64), np.float32), out.boxes, 120, 160)
    assert np.all(ones[depth > 0] > 0.999)
    assert ones.max() <= 1.0 + 1e-5


def test_bad_shape_is_refused(intrinsics):
    with pytest.raises(ValueError, match="depth images must be"):
        preprocess(np.zeros((2, 3, 4, 5)), intrinsics.fx, intrinsics.fy, PARAMS)


def test_known_extents_give_the_inputs_of_extents_found_in_the_batch(intrinsics, render_model):
    depth = render_model("bicycle", fibonacci_directions(9) * 0.6)
    depth = np.concatenate([depth, np.zeros((1, *depth.shape[1:]), np.float32)])  # + empty
    extents = object_extents(depth)
    assert extents.reference_depth_m.shape == (10,) and np.isnan(extents.reference_depth_m[-1])
    in_threes = object_extents(depth, batch_size=3)
    for name in ("u_min", "u_max", "v_min", "v_max", "reference_depth_m"):
        np.testing.assert_array_equal(getattr(in_threes, name), getattr(extents, name))
    rng = np.random.default_rng(0)
    shift, scale = rng.uniform(-0.05, 0.05, (4, 2)), rng.uniform(0.9, 1.1, 4)
    pick = np.array([1, 4, 5, 9])
    found = preprocess(depth[pick], intrinsics.fx, intrinsics.fy, PARAMS, shift, scale)
    known = preprocess(depth[pick], intrinsics.fx, intrinsics.fy, PARAMS, shift, scale,
                       extents[pick])
    for a, b in ((found.images, known.images), (found.boxes, known.boxes),
                 (found.reference_depth_m, known.reference_depth_m)):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="extents of 3 images"):
        preprocess(depth[pick], intrinsics.fx, intrinsics.fy, PARAMS, extents=extents[:3])
