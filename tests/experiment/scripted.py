"""A scripted closed loop for the simulator's and the methods' tests: a scene whose image is its
viewpoint, a recogniser reading a label per viewpoint from it, a policy moving on a fixed path."""

from __future__ import annotations

import numpy as np

from rapomdp.experiment.episode import Motion
from rapomdp.geometry.viewsphere import geodesic_distance_matrix, viewpoints
from rapomdp.planning.policy import ARAction

V, C = 24, 3


class ViewScene:
    """A scene whose depth image encodes the viewpoint it was taken from."""

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        return np.full((2, 3), float(viewpoint))


class TableRecogniser:
    """Returns a fixed label per viewpoint (read back from the image), as probabilities."""

    def __init__(self, labels: np.ndarray, confidence: float = 0.8) -> None:
        self.labels, self.confidence = labels, confidence

    def predict(self, depth_images: np.ndarray) -> np.ndarray:
        views = depth_images[:, 0, 0].astype(int)
        out = np.full((views.size, C), (1 - self.confidence) / (C - 1))
        out[np.arange(views.size), self.labels[views]] = self.confidence
        return out


class Scripted:
    """Moves along a fixed list of viewpoints, then declares class 0."""

    name, recogniser = "scripted", "cnn"

    def __init__(self, path: list[int]) -> None:
        self.path = path
        self.belief = np.full(C, 1 / C)

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self.remaining = list(self.path)

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        self.belief = output

    def act(self, viewpoint: int) -> ARAction:
        if self.remaining:
            return ARAction("move", self.remaining.pop(0))
        return ARAction("declare", 0)


def scripted_motion() -> Motion:
    """E_M on V hemisphere viewpoints: distance plus 0.1 per move; viewpoints 5, 6 unreachable."""
    distance = geodesic_distance_matrix(viewpoints(V, 0.6, hemisphere=True), 0.6)
    reachable = np.ones(V, dtype=bool)
    reachable[[5, 6]] = False
    energy = distance + 0.1 * (distance > 0)
    energy[:, ~reachable] = np.inf
    energy[~reachable, :] = np.inf
    return Motion(energy, distance, reachable)


def confusion(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    right = rng.uniform(0.4, 0.95, size=(V, C))
    P = np.repeat(((1 - right) / (C - 1))[:, :, None], C, axis=2)
    P[:, np.arange(C), np.arange(C)] = right
    return P
