"""The VP-tree baseline: depth descriptors, vocabulary tree, classifier, artefacts, stage."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.procedural.classes import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints
from rapomdp.io import ArtefactError, load_npz, save_npz
from rapomdp.recognition.vocabulary_tree import (
    DescriptorParams,
    VocabularyTree,
    VocabularyTreeClassifier,
    depth_descriptors,
)

PARAMS = DescriptorParams(patch_size_m=0.06, samples=5, stride_px=4)


def _tilted_strip(distance_m: float, slope: float, half_width_px: int = 16, width: int = 160,
                  height: int = 120) -> tuple[np.ndarray, float, float]:
    """Z-depth of the plane z = distance + slope * x (camera frame), seen only in a vertical
    strip around the optical axis (away from it, perspective bends a patch's depth profile)."""
    k = xtion_intrinsics(width, height)
    u = np.arange(width) - k.cx
    # a pixel's ray x = u z / f meets the plane where z = d + slope u z / f
    z = np.where(np.abs(u) < half_width_px, distance_m / (1.0 - slope * u / k.fx), 0.0)
    return np.broadcast_to(z, (height, width)).astype(np.float32), k.fx, k.fy


def test_descriptors_of_a_slanted_plane_do_not_depend_on_its_distance() -> None:
    slope = 0.5
    half = PARAMS.patch_size_m / 2
    grid = np.linspace(-half, half, PARAMS.samples)
    off_x = np.meshgrid(grid, grid, indexing="ij")[1].reshape(-1)
    expected = np.delete(slope * off_x / half, off_x.size // 2)  # centre sample left out
    for distance in (0.6, 0.7, 0.9):
        depth, fx, fy = _tilted_strip(distance, slope)
        desc, image = depth_descriptors(depth, fx, fy, PARAMS)
        assert desc.shape[1] == PARAMS.dimension == 24 and desc.dtype == np.float32
        assert np.all(image == 0)
        inside = desc.max(axis=1) < 1.0  # patches wholly on the plane
        assert inside.sum() >= 20
        # the same values at every distance, up to rounding sample positions to pixels (half a
        # pixel: ~2 mm at 0.6 m) and perspective (offsets ~ patch / distance)
        np.testing.assert_allclose(desc[inside], np.broadcast_to(expected, desc[inside].shape),
                                   atol=0.08)


def test_empty_images_give_no_descriptors_and_keep_the_image_index() -> None:
    empty = np.zeros((2, 30, 40), np.float32)
    desc, image = depth_descriptors(empty, 40.0, 40.0, PARAMS)
    assert desc.shape == (0, 24) and image.shape == (0,)
    batch = np.zeros((3, 30, 40), np.float32)
    batch[0, 10:20, 10:20] = 0.6
    batch[2, 5:25, 5:35] = 0.8
    desc, image = depth_descriptors(batch, 40.0, 40.0, PARAMS)
    assert set(image.tolist()) == {0, 2}
    assert np.all(np.diff(image) >= 0)
    assert desc.min() >= -1.0 and desc.max() <= 1.0


def _clustered(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Nine tight clusters in three far-apart groups of three: a tree of 3 x 2 levels."""
    centres = np.array([[10.0 * g, 1.0 * j] for g in range(3) for j in range(3)])
    cluster = np.repeat(np.arange(9), 40)
    return centres[cluster] + rng.normal(0, 0.02, (cluster.size, 2)), cluster


def test_quantise_gives_each_separated_cluster_its_own_leaf() -> None:
    x, cluster = _clustered(np.random.default_rng(0))
    tree = VocabularyTree(3, 2).fit(x, rng_seed=1)
    assert tree.centres.shape == (3 + 9, 2) and tree.leaves == 9
    leaves = tree.quantise(x)
    per_cluster = [np.unique(leaves[cluster == c]) for c in range(9)]
    assert all(len(found) == 1 for found in per_cluster)
    assert len({int(found[0]) for found in per_cluster}) == 9
    # each leaf centre, quantised, lands in its own leaf
    leaf_centres = tree.centres[3:]
    np.testing.assert_array_equal(tree.quantise(leaf_centres), np.arange(9))


def test_leaf_ids_are_in_range_even_with_too_few_descriptors() -> None:
    rng = np.random.default_rng(2)
    tree = VocabularyTree(4, 3).fit(rng.normal(size=(10, 5)), rng_seed=0)
    ids = tree.quantise(rng.normal(size=(500, 5)))
    assert ids.min() >= 0 and ids.max() < 64 and ids.dtype == np.int64
    with pytest.raises(ValueError, match=r"descriptors must be \(N, 5\)"):
        tree.quantise(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="branching >= 2"):
        VocabularyTree(1, 2)


def _class_views(class_name: str, index: int, count: int, size_px: int) -> np.ndarray:
    """Depth images of a procedural model (bounding radius 0.2 m) from ``count`` directions."""
    mesh = normalise_mesh(generate_model(class_name, seed=7, index=index), 0.2)
    centre = np.array([0.0, 0.0, np.ptp(mesh.vertices[:, 2]) / 2])
    poses = look_at_many(viewpoints(count, 0.6, hemisphere=False, centre=centre), centre)
    k = xtion_intrinsics(size_px, size_px * 3 // 4)
    return DepthRenderer(mesh, k).render(poses)


@pytest.fixture(scope="module")
def separable() -> dict[str, np.ndarray]:
    """Bottles and bicycles: two train models each, a third held out, 48 x 36 px."""
    classes = ["bottle", "bicycle"]
    train = [_class_views(c, i, 40, 48) for c in classes for i in range(2)]
    test = [_class_views(c, 2, 30, 48) for c in classes]
    k = xtion_intrinsics(48, 36)
    return {"train": np.concatenate(train), "train_labels": np.repeat([0, 0, 1, 1], 40),
            "test": np.concatenate(test), "test_labels": np.repeat([0, 1], 30),
            "f": np.array([k.fx, k.fy])}


@pytest.fixture(scope="module")
def fitted(separable: dict[str, np.ndarray]) -> VocabularyTreeClassifier:
    fx, fy = separable["f"]
    return VocabularyTreeClassifier.fit(
        separable["train"], separable["train_labels"], ["bottle", "bicycle"], fx, fy,
        DescriptorParams(0.08, 5, 2), seed=0, branching=4, levels=3)


def test_classifier_tells_bottles_from_bicycles_on_held_out_models(
        fitted: VocabularyTreeClassifier, separable: dict[str, np.ndarray]) -> None:
    scores = fitted.predict(separable["test"])
    assert scores.shape == (60, 2)
    np.testing.assert_allclose(scores.sum(axis=1), 1.0, atol=1e-6)
    assert set(np.unique(scores).tolist()) <= {0.0, 1.0}  # top_k = 1: one-hot
    accuracy = (scores.argmax(axis=1) == separable["test_labels"]).mean()
    assert accuracy >= 0.9
    # an image with no object is no evidence: the uniform row
    np.testing.assert_allclose(fitted.predict(np.zeros((36, 48), np.float32)), [[0.5, 0.5]])


def test_top_k_votes_are_normalised_similarities(separable: dict[str, np.ndarray]) -> None:
    fx, fy = separable["f"]
    model = VocabularyTreeClassifier.fit(
        separable["train"], separable["train_labels"], ["bottle", "bicycle"], fx, fy,
        DescriptorParams(0.08, 5, 2), seed=0, branching=4, levels=2, top_k=5)
    scores = model.predict(separable["test"][:10])
    np.testing.assert_allclose(scores.sum(axis=1), 1.0, atol=1e-6)
    assert np.all(scores >= 0) and (scores.argmax(axis=1) == 0).mean() >= 0.9


def test_save_load_round_trip_and_bad_files(fitted: VocabularyTreeClassifier,
                                            separable: dict[str, np.ndarray],
                                            tmp_path: Path) -> None:
    path = tmp_path / "vocabulary_tree.npz"
    fitted.save(path)
    loaded = VocabularyTreeClassifier.load(path)
    assert loaded.classes == fitted.classes and loaded.params == fitted.params
    np.testing.assert_array_equal(loaded.predict(separable["test"]),
                                  fitted.predict(separable["test"]))
    # the tree alone, round trip, and refused as a classifier
    tree_path = tmp_path / "tree.npz"
    fitted.tree.save(tree_path)
    np.testing.assert_array_equal(VocabularyTree.load(tree_path).centres, fitted.tree.centres)
    with pytest.raises(ArtefactError, match=r"tree\.npz: not a rapomdp VP-tree classifier"):
        VocabularyTreeClassifier.load(tree_path)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file")
    with pytest.raises(ArtefactError, match=r"garbage\.npz"):
        VocabularyTreeClassifier.load(garbage)
    arrays = load_npz(path)
    arrays["db_indptr"] = arrays["db_indptr"][:-5]  # a damaged index
    save_npz(tmp_path / "damaged.npz", **arrays)
    with pytest.raises(ArtefactError, match=r"damaged\.npz: not a valid vocabulary-tree"):
        VocabularyTreeClassifier.load(tmp_path / "damaged.npz")
    arrays = load_npz(path)
    arrays["tree_centres"] = arrays["tree_centres"][:, :3]  # descriptors of another size
    save_npz(tmp_path / "resized.npz", **arrays)
    with pytest.raises(ArtefactError, match=r"resized\.npz: .*dimension 3"):
        VocabularyTreeClassifier.load(tmp_path / "resized.npz")




def test_the_tree_does_not_depend_on_the_threads_pytorch_was_given() -> None:
    """scikit-learn's k-means follows PyTorch's OpenMP threads in a process that imported
    PyTorch first; the tree fits on one thread whatever they are."""
    import torch

    rng = np.random.default_rng(0)
    descriptors = (rng.normal(size=(6000, 24)) + rng.integers(0, 6, (6000, 1))).astype(
        np.float32)
    before = torch.get_num_threads()
    centres = []
    try:
        for threads in (1, 2):
            torch.set_num_threads(threads)
            centres.append(VocabularyTree(4, 2).fit(descriptors, 3).centres)
    finally:
        torch.set_num_threads(before)
    np.testing.assert_array_equal(centres[0], centres[1])
