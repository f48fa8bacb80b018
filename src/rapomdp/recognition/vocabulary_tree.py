"""The VP-tree baseline's classifier: a vocabulary tree over local depth descriptors.

After Atanasov et al. (T-RO 2014), who match a query against a database of training views with
a vocabulary tree (Nistér & Stewénius, CVPR 2006), and report the best match's object as the
observation. Here:

* **Descriptor** (:func:`depth_descriptors`): keypoints on a regular pixel grid over the object
  pixels; around each, a ``samples x samples`` grid of depth samples spaced in *metres* at the
  keypoint's depth (pixel offset = offset_m * f / z), each the depth relative to the keypoint's
  divided by the patch half-side and clipped to [-1, 1]; background and off-image samples read
  +1 (far behind). The patch covers the same surface area at any distance and its values are
  depth differences in metres, so the descriptor is invariant to the object's distance (up to
  the pixel rounding) and to a shift along the optical axis.
* **Tree** (:class:`VocabularyTree`): hierarchical k-means, ``branching`` children per node and
  ``levels`` levels (``branching ** levels`` leaves), each node's k-means (scikit-learn,
  ``n_init=1``) fitted on the training descriptors that reached it. A descriptor descends by
  the nearest child centre at each level.
* **Matching** (:class:`VocabularyTreeClassifier`): an image is its TF-IDF weighted histogram of
  leaves, L2-normalised; the training views form the database; a query's similarity to a view is
  the cosine of their histograms. The prediction is the similarity-weighted vote of the ``top_k``
  best-matching training views (``top_k = 1``: the best match's class, as the paper's baseline).

Everything is stored as plain arrays in one ``.npz`` (no pickle).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from sklearn.cluster import KMeans
from threadpoolctl import threadpool_limits

from rapomdp.io import ArtefactError, load_npz, save_npz
from rapomdp.recognition.preprocess import as_depth_batch

TREE_FORMAT = "rapomdp-vocabulary-tree/1"
CLASSIFIER_FORMAT = "rapomdp-vptree-classifier/1"
BACKGROUND_VALUE = 1.0
"""A descriptor sample on the background or off the image: as far behind as the clip allows."""


@dataclass(frozen=True)
class DescriptorParams:
    """Parameters of :func:`depth_descriptors` (stored with the classifier)."""

    patch_size_m: float = 0.06
    samples: int = 5
    stride_px: int = 4

    def __post_init__(self) -> None:
        if self.patch_size_m <= 0 or self.samples < 2 or self.stride_px < 1:
            raise ValueError(f"bad descriptor parameters {self}")

    @property
    def dimension(self) -> int:
        return self.samples * self.samples - 1

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def depth_descriptors(
    depth_m: np.ndarray, fx_px: float, fy_px: float, params: DescriptorParams
) -> tuple[np.ndarray, np.ndarray]:
    """Local depth descriptors of a batch of depth images (n, H, W) in metres (0 = background).

    Returns ``descriptors`` (N, samples² - 1) float32 in [-1, 1] and ``image_index`` (N,), the
    image each came from. Keypoints: every ``stride_px``-th pixel (both axes) that is on the
    object. The centre sample (always 0) is left out. An empty image contributes nothing.
    """
    depth = as_depth_batch(depth_m)
    n, h, w = depth.shape
    half = (params.samples - 1) / 2
    grid = (np.arange(params.samples) - half) / half * (params.patch_size_m / 2)  # metres
    off_y, off_x = (a.reshape(-1) for a in np.meshgrid(grid, grid, indexing="ij"))
    keep = np.ones(off_x.size, dtype=bool)
    keep[off_x.size // 2] = False  # the centre: depth relative to itself is always 0
    off_x, off_y = off_x[keep], off_y[keep]

    s = params.stride_px
    sub = depth[:, s // 2 :: s, s // 2 :: s]
    img, row, col = np.nonzero(sub > 0)
    row = row * s + s // 2
    col = col * s + s // 2
    if img.size == 0:
        return np.zeros((0, params.dimension), np.float32), np.zeros(0, np.int64)
    z = depth[img, row, col]  # (N,)
    u = np.rint(col[:, None] + off_x[None] * (fx_px / z[:, None])).astype(np.int64)
    v = np.rint(row[:, None] + off_y[None] * (fy_px / z[:, None])).astype(np.int64)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    sampled = depth[img[:, None], np.clip(v, 0, h - 1), np.clip(u, 0, w - 1)]
    values = (sampled - z[:, None]) / np.float32(params.patch_size_m / 2)
    values = np.where(inside & (sampled > 0), values, BACKGROUND_VALUE)
    return np.clip(values, -1.0, 1.0).astype(np.float32), img.astype(np.int64)


class VocabularyTree:
    """Hierarchical k-means: a complete tree of ``levels`` levels, ``branching`` children each.

    ``centres`` (branching + branching² + ... + branching^levels, D): level l's nodes (l = 1..L)
    in one block, in node order; node i of level l has children i*branching + (0..branching-1)
    in level l + 1. Leaves are level L's nodes, ids 0 .. branching^levels - 1.
    """

    def __init__(self, branching: int, levels: int, centres: np.ndarray | None = None) -> None:
        if branching < 2 or levels < 1:
            raise ValueError(f"a vocabulary tree needs branching >= 2 and levels >= 1, got "
                             f"{branching}, {levels}")
        self.branching, self.levels = int(branching), int(levels)
        self.centres = None if centres is None else np.asarray(centres, dtype=np.float32)
        if self.centres is not None and (self.centres.ndim != 2
                                         or self.centres.shape[0] != self.nodes):
            raise ValueError(f"centres must be ({self.nodes}, D) for branching {branching} and "
                             f"{levels} levels, got shape {self.centres.shape}")

    @property
    def leaves(self) -> int:
        return self.branching**self.levels

    @property
    def nodes(self) -> int:
        return sum(self.branching**level for level in range(1, self.levels + 1))

    def _level(self, level: int) -> np.ndarray:
        """Centres of level ``level`` (1-based), (branching^level, D)."""
        start = sum(self.branching**k for k in range(1, level))
        return self.centres[start : start + self.branching**level]  # type: ignore[index]

    def fit(self, descriptors: np.ndarray, rng_seed: int, max_iter: int = 100) -> VocabularyTree:
        """Fit every node's k-means on the descriptors that reach it (top-down).

        A node with fewer descriptors than ``branching`` keeps them as its first centres and
        repeats the last (an empty node repeats its own centre): such leaves stay unused.
        The k-means run on one OpenMP thread: scikit-learn's thread count follows PyTorch's in
        a process that imported PyTorch first, and the centres depend on it (another tree in
        ``make demo`` than in a study of the same seed, before).
        """
        with threadpool_limits(limits=1, user_api="openmp"):
            return self._fit(descriptors, rng_seed, max_iter)

    def _fit(self, descriptors: np.ndarray, rng_seed: int, max_iter: int) -> VocabularyTree:
        x = np.asarray(descriptors, dtype=np.float32)
        if x.ndim != 2 or x.shape[0] == 0:
            raise ValueError(f"descriptors must be a non-empty (N, D) array, got {x.shape}")
        k = self.branching
        rng = np.random.default_rng(rng_seed)
        blocks = []
        node = np.zeros(x.shape[0], dtype=np.int64)
        parents = x.mean(axis=0, keepdims=True)
        for _level in range(self.levels):
            centres = np.repeat(parents, k, axis=0)
            order = np.argsort(node, kind="stable")
            bounds = np.searchsorted(node[order], np.arange(parents.shape[0] + 1))
            for parent in range(parents.shape[0]):
                members = x[order[bounds[parent] : bounds[parent + 1]]]
                unique = np.unique(members, axis=0) if members.shape[0] <= 4 * k else members
                if unique.shape[0] <= k:
                    if unique.shape[0]:
                        pad = np.repeat(unique[-1:], k - unique.shape[0], axis=0)
                        centres[parent * k : parent * k + k] = np.vstack([unique, pad])
                    continue
                km = KMeans(k, n_init=1, max_iter=max_iter,
                            random_state=int(rng.integers(2**31)))
                centres[parent * k : parent * k + k] = km.fit(members).cluster_centers_
            blocks.append(centres)
            node = node * k + _nearest(x, centres, node, k)
            parents = centres
        self.centres = np.vstack(blocks).astype(np.float32)
        return self

    def quantise(self, descriptors: np.ndarray) -> np.ndarray:
        """Leaf ids (N,) in [0, leaves): descend by the nearest child centre at each level."""
        if self.centres is None:
            raise ValueError("the vocabulary tree has not been fitted")
        x = np.asarray(descriptors, dtype=np.float32)
        if x.ndim != 2 or x.shape[1] != self.centres.shape[1]:
            raise ValueError(f"descriptors must be (N, {self.centres.shape[1]}), got {x.shape}")
        node = np.zeros(x.shape[0], dtype=np.int64)
        for level in range(1, self.levels + 1):
            node = node * self.branching + _nearest(x, self._level(level), node, self.branching)
        return node

    def to_arrays(self) -> dict[str, np.ndarray]:
        if self.centres is None:
            raise ValueError("the vocabulary tree has not been fitted")
        return {"tree_branching": np.array(self.branching), "tree_levels": np.array(self.levels),
                "tree_centres": self.centres}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], path: str | Path) -> VocabularyTree:
        try:
            return cls(int(arrays["tree_branching"]), int(arrays["tree_levels"]),
                       arrays["tree_centres"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ArtefactError(f"{path}: not a valid vocabulary tree ({exc})") from None

    def save(self, path: str | Path) -> None:
        """The tree alone as ``.npz``: format, branching, levels, centres."""
        save_npz(path, format=np.array(TREE_FORMAT), **self.to_arrays())

    @classmethod
    def load(cls, path: str | Path) -> VocabularyTree:
        arrays = load_npz(path)
        _check_format(arrays, path, TREE_FORMAT, "vocabulary tree")
        return cls.from_arrays(arrays, path)


def _nearest(x: np.ndarray, centres: np.ndarray, node: np.ndarray, k: int,
             chunk: int = 32768) -> np.ndarray:
    """Index (N,) in [0, k) of the nearest of each row's ``k`` child centres of ``node``
    (``chunk`` rows at a time: the gathered centres take N k D floats)."""
    grouped = centres.reshape(-1, k, centres.shape[1])
    out = np.empty(x.shape[0], dtype=np.int64)
    for start in range(0, x.shape[0], chunk):
        children = grouped[node[start : start + chunk]]  # (n, k, D)
        distance = np.einsum("nkd,nkd->nk", children, children) - 2 * np.einsum(
            "nd,nkd->nk", x[start : start + chunk], children)
        out[start : start + chunk] = distance.argmin(axis=1)
    return out


def _check_format(arrays: dict[str, np.ndarray], path: str | Path, expected: str,
                  what: str) -> None:
    found = str(arrays["format"]) if "format" in arrays else None
    if found != expected:
        raise ArtefactError(f"{path}: not a rapomdp {what} (format {found!r}, "
                            f"expected {expected!r})")


def bag_of_words(leaf_ids: np.ndarray, image_index: np.ndarray, images: int,
                 leaves: int) -> sp.csr_matrix:
    """Leaf counts per image as a sparse (images, leaves) matrix."""
    ones = np.ones(leaf_ids.size, dtype=np.float32)
    return sp.csr_matrix((ones, (image_index, leaf_ids)), shape=(images, leaves))


def _tfidf(counts: sp.csr_matrix, idf: np.ndarray) -> sp.csr_matrix:
    """TF-IDF rows (term frequency x idf), L2-normalised (an empty row stays zero)."""
    totals = np.asarray(counts.sum(axis=1)).ravel()
    weighted = sp.diags(1.0 / np.maximum(totals, 1.0)) @ counts @ sp.diags(idf)
    norms = np.sqrt(np.asarray(weighted.multiply(weighted).sum(axis=1)).ravel())
    return sp.csr_matrix(sp.diags(1.0 / np.where(norms > 0, norms, 1.0)) @ weighted,
                         dtype=np.float32)


class VocabularyTreeClassifier:
    """Depth images in, class scores out: the best-matching training views' classes."""

    def __init__(self, tree: VocabularyTree, params: DescriptorParams, classes: Sequence[str],
                 fx_px: float, fy_px: float, idf: np.ndarray, database: sp.csr_matrix,
                 labels: np.ndarray, top_k: int = 1, fit_descriptors: int = 0) -> None:
        if top_k < 1:
            raise ValueError(f"top_k must be at least 1, got {top_k}")
        self.tree, self.params, self.classes = tree, params, list(classes)
        self.fx_px, self.fy_px = float(fx_px), float(fy_px)
        self.idf = np.asarray(idf, dtype=np.float32)
        self.database = sp.csr_matrix(database, dtype=np.float32)
        self.labels = np.asarray(labels, dtype=np.int64)
        self.top_k = int(top_k)
        self.fit_descriptors = int(fit_descriptors)  # how many the tree was fitted on (a record)
        if self.database.shape != (self.labels.size, tree.leaves) or self.idf.size != tree.leaves:
            raise ValueError(f"database {self.database.shape}, labels {self.labels.shape} and idf "
                             f"{self.idf.shape} do not fit a tree of {tree.leaves} leaves")

    @classmethod
    def fit(cls, depth_images: np.ndarray, labels: np.ndarray, classes: Sequence[str],
            fx_px: float, fy_px: float, params: DescriptorParams, seed: int,
            branching: int = 10, levels: int = 3, max_fit_descriptors: int = 100_000,
            top_k: int = 1) -> VocabularyTreeClassifier:
        """Fit the tree on a random subsample of at most ``max_fit_descriptors`` descriptors
        (k-means time grows with it, the vocabulary hardly improves), then index every image."""
        depth = as_depth_batch(depth_images)
        labels = np.asarray(labels, dtype=np.int64)
        if labels.shape != (depth.shape[0],):
            raise ValueError(f"{depth.shape[0]} images but labels of shape {labels.shape}")
        # in chunks of images: the gather's temporaries for all 4200 default images at once
        # would take ~1 GB
        parts = [depth_descriptors(depth[i : i + 512], fx_px, fy_px, params)
                 for i in range(0, depth.shape[0], 512)]
        descriptors = np.concatenate([d for d, _ in parts])
        image = np.concatenate([j + i for (_, j), i in zip(parts, range(0, depth.shape[0], 512),
                                                            strict=True)])
        if descriptors.shape[0] == 0:
            raise ValueError("the training images hold no object pixels")
        rng = np.random.default_rng(seed)
        pick = (rng.choice(descriptors.shape[0], max_fit_descriptors, replace=False)
                if descriptors.shape[0] > max_fit_descriptors else slice(None))
        tree = VocabularyTree(branching, levels).fit(descriptors[pick], int(rng.integers(2**31)))
        counts = bag_of_words(tree.quantise(descriptors), image, depth.shape[0], tree.leaves)
        seen = np.asarray((counts > 0).sum(axis=0)).ravel()
        idf = np.where(seen > 0, np.log(depth.shape[0] / np.maximum(seen, 1)), 0.0)
        return cls(tree, params, classes, fx_px, fy_px, idf, _tfidf(counts, idf), labels, top_k,
                   fit_descriptors=int(descriptors[pick].shape[0]))

    def histograms(self, depth_images: np.ndarray) -> np.ndarray:
        """TF-IDF leaf histograms (n, leaves) of depth images, L2-normalised, dense."""
        depth = as_depth_batch(depth_images)
        descriptors, image = depth_descriptors(depth, self.fx_px, self.fy_px, self.params)
        leaves = self.tree.leaves
        counts = np.bincount(image * leaves + self.tree.quantise(descriptors),
                             minlength=depth.shape[0] * leaves).reshape(depth.shape[0], leaves)
        weighted = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1) * self.idf
        norms = np.linalg.norm(weighted, axis=1, keepdims=True)
        return (weighted / np.where(norms > 0, norms, 1.0)).astype(np.float32)

    def predict(self, depth_images: np.ndarray, batch_size: int = 256) -> np.ndarray:
        """Class scores (n, C) of depth images (n, H, W) in metres, rows summing to 1.

        Row = the ``top_k`` best-matching training views' cosine similarities summed per class
        and normalised (``top_k = 1``: one-hot on the best match's class). An image without
        object pixels, or matching nothing, gets the uniform row.
        """
        depth = as_depth_batch(depth_images)
        c = len(self.classes)
        out = np.full((depth.shape[0], c), 1.0 / c, dtype=np.float32)
        k = min(self.top_k, self.labels.size)
        for start in range(0, depth.shape[0], batch_size):
            query = self.histograms(depth[start : start + batch_size])
            similarity = np.asarray(self.database @ query.T).T  # (b, training views)
            best = np.argpartition(-similarity, k - 1, axis=1)[:, :k]
            weight = np.take_along_axis(similarity, best, axis=1)
            votes = np.zeros((similarity.shape[0], c), dtype=np.float64)
            np.add.at(votes, (np.repeat(np.arange(votes.shape[0]), k), self.labels[best].ravel()),
                      weight.ravel())
            total = votes.sum(axis=1, keepdims=True)
            rows = total[:, 0] > 0
            out[start : start + batch_size][rows] = votes[rows] / total[rows]
        return out

    # -- artefact --------------------------------------------------------------------------

    def save(self, path: str | Path) -> None:
        """One ``.npz`` of plain arrays: format, tree, descriptor parameters, camera, index."""
        db = self.database
        save_npz(
            path, compressed=True, format=np.array(CLASSIFIER_FORMAT),
            classes=np.array(self.classes), **self.tree.to_arrays(),
            descriptor=np.array([self.params.patch_size_m, self.params.samples,
                                 self.params.stride_px], dtype=np.float64),
            camera=np.array([self.fx_px, self.fy_px]), idf=self.idf, labels=self.labels,
            top_k=np.array(self.top_k), db_indptr=db.indptr, db_indices=db.indices,
            db_data=db.data,
        )

    @classmethod
    def load(cls, path: str | Path) -> VocabularyTreeClassifier:
        """Read :meth:`save`'s file; a wrong or damaged file raises :class:`ArtefactError`."""
        arrays = load_npz(path)
        _check_format(arrays, path, CLASSIFIER_FORMAT, "VP-tree classifier")
        tree = VocabularyTree.from_arrays(arrays, path)
        try:
            patch, samples, stride = (float(v) for v in arrays["descriptor"])
            params = DescriptorParams(patch, int(samples), int(stride))
            fx, fy = (float(v) for v in arrays["camera"])
            labels = arrays["labels"]
            database = sp.csr_matrix(
                (arrays["db_data"], arrays["db_indices"], arrays["db_indptr"]),
                shape=(labels.size, tree.leaves))
            dimension = tree.centres.shape[1]  # type: ignore[union-attr]
            if dimension != params.dimension:
                raise ValueError(f"centres of dimension {dimension} for descriptors of "
                                 f"dimension {params.dimension}")
            classes = [str(c) for c in arrays["classes"]]
            if labels.size and (labels.min() < 0 or labels.max() >= len(classes)):
                raise ValueError("labels outside the class list")
            return cls(tree, params, classes, fx, fy, arrays["idf"], database, labels,
                       int(arrays["top_k"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise ArtefactError(f"{path}: not a valid vocabulary-tree classifier ({exc})") from None
