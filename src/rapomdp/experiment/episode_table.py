"""The evaluate stage's artefacts: the closed loop's episodes as a table (one row per episode,
plus the concatenated steps) and the names of every file the stage writes.

``W/evaluate/``: :data:`EPISODES_FILE` and :data:`EPISODES_CSV` (the table; metrics, figures and
the report read it back with :meth:`EpisodeTable.load`), :data:`TABLE1_MD` / :data:`TABLE1_CSV`,
:data:`PER_CLASS_MD` / :data:`PER_CLASS_CSV`, :data:`FIG3_FILE`, :data:`TRAJECTORIES_FILE` and
:data:`SUMMARY_FILE` (counts, time, the figure class).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.data.dataset import Dataset
from rapomdp.experiment.episode import Episode, score
from rapomdp.io import load_npz

EPISODES_FILE = "episodes.npz"
EPISODES_CSV = "episodes.csv"
TABLE1_MD = "table1.md"
TABLE1_CSV = "table1.csv"
PER_CLASS_MD = "per_class.md"
PER_CLASS_CSV = "per_class.csv"
FIG3_FILE = "fig3.png"
TRAJECTORIES_FILE = "trajectories.png"
SUMMARY_FILE = "evaluate.json"
PAIRED_CSV = "paired.csv"
TRADEOFF_CSV = "tradeoff.csv"
TRADEOFF_MD = "tradeoff.md"
TRADEOFF_FIGURE = "tradeoff.png"


@dataclass(frozen=True)
class EpisodeRecord:
    """One episode as run: method key, test model (its file in the dataset), start viewpoint."""

    method: str
    model: str
    start: int
    episode: Episode
    cpu_seconds: float


@dataclass
class EpisodeTable:
    """Episodes and their scores as arrays (one row per episode) plus the concatenated steps."""

    classes: list[str]
    methods: list[str]
    method: np.ndarray
    class_index: np.ndarray
    model: np.ndarray
    start: np.ndarray
    declared: np.ndarray
    exhausted: np.ndarray
    correct: np.ndarray
    belief: np.ndarray
    moves: np.ndarray
    distance_m: np.ndarray
    energy: np.ndarray
    offsets: np.ndarray
    step_viewpoints: np.ndarray
    step_outputs: np.ndarray
    step_beliefs: np.ndarray
    cpu_seconds: np.ndarray

    @classmethod
    def from_records(cls, records: Sequence[EpisodeRecord], dataset: Dataset,
                     methods: Sequence[str]) -> EpisodeTable:
        by_file = {m.file: m for m in dataset.with_role("test")}
        truth = np.array([dataset.label(by_file[r.model]) for r in records])
        scores = [score(r.episode, int(t)) for r, t in zip(records, truth, strict=True)]
        lengths = np.array([r.episode.viewpoints.size for r in records])
        return cls(
            classes=list(dataset.classes),
            methods=list(methods),
            method=np.array([r.method for r in records]),
            class_index=truth,
            model=np.array([r.model for r in records]),
            start=np.array([r.start for r in records]),
            declared=np.array([r.episode.declared for r in records]),
            exhausted=np.array([r.episode.exhausted for r in records]),
            correct=np.array([s.correct for s in scores]),
            belief=np.array([s.belief for s in scores]),
            moves=np.array([s.moves for s in scores]),
            distance_m=np.array([s.distance_m for s in scores]),
            energy=np.array([s.energy for s in scores]),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            step_viewpoints=np.concatenate([r.episode.viewpoints for r in records]),
            step_outputs=np.concatenate([r.episode.outputs for r in records]),
            step_beliefs=np.concatenate([r.episode.beliefs for r in records]),
            cpu_seconds=np.array([r.cpu_seconds for r in records]),
        )

    def arrays(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if isinstance(v, np.ndarray)}
        return {**out, "classes": np.array(self.classes), "methods": np.array(self.methods)}

    @classmethod
    def load(cls, path: str | Path) -> EpisodeTable:
        data = load_npz(path)
        fields = {k: data[k] for k in cls.__dataclass_fields__ if k not in ("classes", "methods")}
        return cls(classes=[str(c) for c in data["classes"]],
                   methods=[str(m) for m in data["methods"]], **fields)

    def final_confidence(self) -> np.ndarray:
        """Each episode's final belief in the class it declared: the confidence a calibrated
        belief matches its accuracy with (the belief in the true class falls short of the
        accuracy even for a calibrated belief whenever that belief is not one-hot)."""
        return self.step_beliefs[self.offsets[1:] - 1, self.declared]

    def beliefs_in_true_class(self, episode: int) -> np.ndarray:
        """Belief in the true class after each image of one episode."""
        rows = slice(self.offsets[episode], self.offsets[episode + 1])
        return self.step_beliefs[rows, self.class_index[episode]]

    def viewpoints_of(self, episode: int) -> np.ndarray:
        return self.step_viewpoints[self.offsets[episode]:self.offsets[episode + 1]]


def episodes_csv(table: EpisodeTable) -> str:
    lines = ["method,class,model,start,declared,correct,belief,moves,distance_m,energy,"
             "exhausted,viewpoints"]
    for i in range(table.method.size):
        views = " ".join(str(v) for v in table.viewpoints_of(i))
        lines.append(
            f"{table.method[i]},{table.classes[table.class_index[i]]},{table.model[i]},"
            f"{table.start[i]},{table.classes[table.declared[i]]},{int(table.correct[i])},"
            f"{table.belief[i]:.6g},{table.moves[i]},{table.distance_m[i]:.6g},"
            f"{table.energy[i]:.6g},{int(table.exhausted[i])},{views}")
    return "\n".join(lines) + "\n"
