"""The per-class split of models into roles: train / volume / test (the paper: 3 / 1 / 1).

Two rules (``dataset.split``):

* ``auto`` (the default): every model of a class is used. A class of :data:`AUTO_MIN_MODELS`
  models gets the paper's 3 / 1 / 1; each further model goes to the next role of
  :data:`AUTO_FILL` (test, volume, test, train, volume, test), reaching 4 / 3 / 4 at
  :data:`AUTO_FULL_MODELS`; beyond that every model goes to training. Test and volume come
  first because one model a role gives no spread: intervals resample test models, and the
  observe stage's leave-one-group-out choice needs two or more volume models a class.
* fixed counts (``{train: 4, volume: 3, test: 4}``): every class gets the same counts, the
  models beyond them trained on or left out (``extra``).

Either way the draw is deterministic from the seed, class by class, and the auto rule on a
class of 11 or more models is the draw of the fixed 4 / 3 / 4 with extra models trained on.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

ROLES = ("train", "volume", "test")
T = TypeVar("T")

#: ``split: auto``: a class's first five models (the paper's split, the least the rule takes),
#: then the role each further model goes to, in turn, up to the default 4 / 3 / 4.
AUTO_BASE = {"train": 3, "volume": 1, "test": 1}
AUTO_FILL = ("test", "volume", "test", "train", "volume", "test")
AUTO_MIN_MODELS = sum(AUTO_BASE.values())
AUTO_FULL_MODELS = AUTO_MIN_MODELS + len(AUTO_FILL)


class TooFewModelsError(ValueError):
    """A class has fewer models than the split needs (the class is named)."""


@dataclass(frozen=True)
class ModelSplit(Generic[T]):
    """Each class's models per role, and the classes left out for too few models (their
    model counts; only with ``too_few="drop"``), with the message that says why."""

    roles: dict[str, dict[str, list[T]]]
    dropped: dict[str, int]
    dropped_message: str | None = None


def class_seed(seed: int, class_name: str) -> np.random.Generator:
    """A generator for one class that depends only on the seed and the class's name."""
    digest = hashlib.sha256(class_name.encode()).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "little")])


def auto_counts(models: int) -> dict[str, int]:
    """``split: auto``'s role counts for a class of ``models`` (at least
    :data:`AUTO_MIN_MODELS`); the models beyond :data:`AUTO_FULL_MODELS` are not counted
    here: they are trained on."""
    if models < AUTO_MIN_MODELS:
        raise ValueError(f"split: auto needs at least {AUTO_MIN_MODELS} models, got {models}")
    counts = dict(AUTO_BASE)
    for role in AUTO_FILL[: models - AUTO_MIN_MODELS]:
        counts[role] += 1
    return counts


def _describe(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{counts[r]} {r}" for r in ROLES)


def too_few_message(short: Mapping[str, int], counts: Mapping[str, int] | None) -> str:
    """One sentence naming each class below the split's minimum, its count and the minimum
    (``counts``: the fixed split's; None: ``split: auto``)."""
    need = sum((counts or AUTO_BASE).values())
    classes = ", ".join(f"class '{name}' has {found} model(s)" for name, found in short.items())
    rule = (f"the split needs {need} ({_describe(counts)})" if counts is not None else
            f"split: auto needs at least {need} a class ({_describe(AUTO_BASE)})")
    return f"{classes}; {rule}"


def split_models(
    models: Mapping[str, Sequence[T]],
    counts: Mapping[str, int] | None,
    seed: int,
    too_few: str = "error",
    extra: str = "train",
) -> ModelSplit[T]:
    """Draw each class's models for every role, deterministic from the seed.

    ``counts`` are the models each role needs, or None for ``split: auto`` (the module's
    rule; every model used). Each class is shuffled by its own generator, so adding a class
    does not change the others' split. With fixed counts a class with more models gives the
    rest to training (``extra="train"``) or leaves them out (``extra="drop"``): the volume
    and test roles keep their counts, so every class is evaluated alike. A class with too few
    models is one :class:`TooFewModelsError` naming every such class, or with
    ``too_few="drop"`` it is left out (:attr:`ModelSplit.dropped`). Under ``split: auto`` the
    models beyond :data:`AUTO_FULL_MODELS` are trained on.
    """
    if extra not in ("train", "drop"):
        raise ValueError(f"unknown rule for extra models '{extra}'; use 'train' or 'drop'")
    if counts is None:
        extra = "train"
    least = sum((counts or AUTO_BASE).values())
    short = {name: len(items) for name, items in models.items() if len(items) < least}
    if short:
        message = too_few_message(short, counts)
        if too_few != "drop":
            raise TooFewModelsError(
                f"{message}: add models, leave the class out (dataset.classes), set "
                "dataset.split to fewer, or set dataset.too_few_models: drop")
    split: dict[str, dict[str, list[T]]] = {}
    for name, items in models.items():
        if name in short:
            continue
        wanted = counts if counts is not None else auto_counts(
            min(len(items), AUTO_FULL_MODELS))
        need = sum(wanted[role] for role in ROLES)
        order = class_seed(seed, name).permutation(len(items))
        picked = [items[i] for i in order[:need]]
        start = 0
        split[name] = {}
        for role in ROLES:
            split[name][role] = picked[start : start + wanted[role]]
            start += wanted[role]
        if extra == "train":
            split[name]["train"].extend(items[i] for i in order[need:])
    if not split:
        raise TooFewModelsError(f"no class has enough models for the split: "
                                f"{too_few_message(short, counts)}")
    return ModelSplit(split, short, f"{too_few_message(short, counts)}: class(es) left out"
                      if short else None)
