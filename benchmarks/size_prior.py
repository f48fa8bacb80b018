"""A class prior from an object's measured size (rule: ``results/size_prior_rule.md``).

The dataset stage scales every mesh to one bounding sphere, so the classifier never sees an
object's size; a depth camera measures it. Each model's sorted bounding-box extents in its
source file's units (the procedural generator's: metres) are read back from the source; a
diagonal Gaussian on the log extents per class, fitted on the training models, turns an
object's extents into a class prior. Used by ``held_out_closed_loop.py --size-prior``; run
alone it prints the size model's accuracy on the volume models:

    python benchmarks/size_prior.py -w W
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.config import Config
from rapomdp.data.dataset import ModelEntry, load_dataset
from rapomdp.data.meshes import load_mesh
from rapomdp.data.procedural.classes import generate_model
from rapomdp.workspace import Workspace

SIZE_SD_FLOOR = 0.1
"""Each class's standard deviation of a log extent is at least this (about 10 %): fixed a
priori for a depth camera's extent estimate and few models a class."""


def source_extents(model: ModelEntry, config: Config) -> np.ndarray:
    """The model's bounding-box extents (3,), sorted, in its source's units."""
    if model.source.startswith("procedural:"):
        mesh = generate_model(model.class_name, config.seed, int(model.source.split(":")[1]))
    else:
        mesh = load_mesh(Path(model.source), int(config.limits.mesh_file_mb * 1e6))
    return np.sort(np.ptp(np.asarray(mesh.vertices, dtype=np.float64), axis=0))


@dataclass(frozen=True)
class SizeModel:
    """Per class, the mean and standard deviation (C, 3) of the log sorted extents."""

    mean: np.ndarray
    sd: np.ndarray

    @classmethod
    def fit(cls, extents: np.ndarray, labels: np.ndarray, classes: int) -> SizeModel:
        logs = np.log(np.maximum(extents, 1e-12))
        mean = np.stack([logs[labels == c].mean(axis=0) for c in range(classes)])
        sd = np.stack([np.maximum(logs[labels == c].std(axis=0), SIZE_SD_FLOOR)
                       for c in range(classes)])
        return cls(mean, sd)

    def prior(self, extents: np.ndarray) -> np.ndarray:
        """P(class | extents) (N, C) under a uniform class prior."""
        logs = np.log(np.maximum(np.atleast_2d(extents), 1e-12))
        z = (logs[:, None, :] - self.mean[None]) / self.sd[None]
        ll = -0.5 * (z ** 2).sum(-1) - np.log(self.sd).sum(-1)[None]
        p = np.exp(ll - ll.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)


def workspace_size_model(ws: Workspace) -> tuple[SizeModel, dict[str, list[np.ndarray]]]:
    """The size model fitted on the workspace's training models, and each class's volume
    models' extents in the split's order (the k-th is held-out group k)."""
    config = ws.config()
    dataset = load_dataset(ws.require("dataset"))
    classes = list(dataset.classes)
    train = dataset.with_role("train")
    extents = np.stack([source_extents(m, config) for m in train])
    labels = np.array([classes.index(m.class_name) for m in train])
    volume: dict[str, list[np.ndarray]] = {}
    for m in dataset.with_role("volume"):
        volume.setdefault(m.class_name, []).append(source_extents(m, config))
    return SizeModel.fit(extents, labels, len(classes)), volume


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    args = parser.parse_args()
    for path in args.workspace:
        ws = Workspace(path)
        model, volume = workspace_size_model(ws)
        classes = list(load_dataset(ws.require("dataset")).classes)
        right = [np.argmax(model.prior(e)[0]) == classes.index(c)
                 for c, extents in volume.items() for e in extents]
        print(f"{path}: the size model names {np.mean(right):.3f} of {len(right)} volume "
              f"models (chance {1 / len(classes):.3f})")


if __name__ == "__main__":
    main()
