"""Cross-fitting: the classifier's behaviour on objects it did not train on, from the training
models themselves.

The training models of every class are dealt into ``k`` folds (stratified by class, seeded). For
each fold a small classifier is trained on the other folds' renders and classifies the fold's
models at the test viewpoints X_rho. Every training model thus gets labels at X_rho from a
classifier that never saw it: held-out evidence ``k`` times the size of the volume models',
which the observe stage fits the observation models on (``observe.evidence``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import crossfit_epochs
from rapomdp.config import Config
from rapomdp.data.dataset import ModelEntry
from rapomdp.data.splits import class_seed
from rapomdp.data.training_views import TrainingViews
from rapomdp.io import load_npz, save_npz
from rapomdp.progress import track
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.training import collect_views, train_classifier

CROSSFIT_FILE = "outcomes.npz"


def model_key(model: ModelEntry) -> str:
    """A model's identity across stages: ``class/id``."""
    return f"{model.class_name}/{model.id}"


def crossfit_folds(models: Sequence[ModelEntry], folds: int, seed: int) -> np.ndarray:
    """The fold (models,) of every model: each class's models shuffled (seeded by the class's
    name) and dealt round-robin, so every fold holds a share of every class.

    Every class needs at least ``folds`` models, so that every fold holds one of each and every
    fold's classifier still trains on every class.
    """
    if folds < 2:
        raise ValueError(f"cross-fitting needs at least 2 folds, got {folds}")
    fold = np.full(len(models), -1, dtype=np.int64)
    by_class: dict[str, list[int]] = {}
    for i, m in enumerate(models):
        by_class.setdefault(m.class_name, []).append(i)
    short = {name: len(idx) for name, idx in by_class.items() if len(idx) < folds}
    if short:
        raise ValueError(f"cross-fitting with {folds} folds needs {folds} training models per "
                         f"class; too few in {short} (lower observe.crossfit_folds)")
    for name, idx in sorted(by_class.items()):
        order = class_seed(seed, f"crossfit/{name}").permutation(len(idx))
        fold[np.asarray(idx)[order]] = np.arange(len(idx)) % folds
    return fold


@dataclass
class CrossfitOutcomes:
    """Held-out labels at X_rho: model ``keys`` (M,), true ``labels`` (M,), ``folds`` (M,),
    the held-out classifier's ``predicted`` labels (M, V), and for each fold the keys of the
    models its classifier ``trained_on``."""

    keys: np.ndarray
    labels: np.ndarray
    folds: np.ndarray
    predicted: np.ndarray
    trained_on: list[np.ndarray]

    def check_held_out(self) -> None:
        """Raise if any fold's classifier trained on a model it is evaluated on."""
        for f, seen in enumerate(self.trained_on):
            leaked = set(seen.tolist()) & set(self.keys[self.folds == f].tolist())
            if leaked:
                raise ValueError(f"fold {f}: its classifier trained on models it is evaluated "
                                 f"on: {sorted(leaked)}")

    def save(self, path: Path) -> None:
        self.check_held_out()
        save_npz(path, keys=self.keys, labels=self.labels, folds=self.folds,
                 predicted=self.predicted,
                 **{f"trained_on_{f}": seen for f, seen in enumerate(self.trained_on)})

    @classmethod
    def load(cls, path: Path) -> CrossfitOutcomes:
        data = load_npz(path)
        count = sum(1 for name in data if name.startswith("trained_on_"))
        out = cls(data["keys"].astype(str), data["labels"], data["folds"], data["predicted"],
                  [data[f"trained_on_{f}"].astype(str) for f in range(count)])
        out.check_held_out()
        return out


def crossfit_outcomes(config: Config, views: TrainingViews, device: object,
                      sensed_at_xrho: Callable[[ModelEntry], np.ndarray],
                      progress: Callable[[Classifier, int], None] | None = None,
                      bar: bool = True) -> CrossfitOutcomes:
    """Train one classifier per fold on the other folds' training renders (the train stage's
    recipe with :func:`crossfit_epochs` epochs, no validation split) and label the fold's
    models at X_rho (``sensed_at_xrho(model)`` -> depth (V, H, W)); ``progress`` is called
    after each fold, a bar shows the folds when ``bar``."""
    dataset = views.dataset
    models = dataset.with_role("train")
    k = config.observe.crossfit_folds
    fold = crossfit_folds(models, k, config.seed)
    data = collect_views(views, "train")  # data.models indexes `models`
    keys = np.array([model_key(m) for m in models])
    train_cfg = config.train.model_copy(update={"epochs": crossfit_epochs(config)})
    predicted = np.zeros((len(models), config.viewpoints.count), dtype=np.int64)
    trained_on = []
    for f in track(range(k), "crossfit: fold classifiers", bar, unit="folds"):
        inside = fold[data.models] != f
        seen = np.unique(data.models[inside])
        trained_on.append(keys[seen])
        classifier, _ = train_classifier(
            data.subset(inside), data.subset(np.zeros(len(data), dtype=bool)), dataset.classes,
            train_cfg, views.intrinsics.fx, views.intrinsics.fy, config.train_seed + 1 + f, device,
            config.render.noise)
        for i in np.flatnonzero(fold == f):
            predicted[i] = classifier.predict(sensed_at_xrho(models[i])).argmax(axis=1)
        if progress is not None:
            progress(classifier, f)
    labels = np.array([dataset.label(m) for m in models])
    out = CrossfitOutcomes(keys, labels, fold, predicted, trained_on)
    out.check_held_out()
    return out
