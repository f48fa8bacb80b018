"""The per-class split of models into roles: train / volume / test (the paper: 3 / 1 / 1)."""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Mapping, Sequence
from typing import TypeVar

import numpy as np

ROLES = ("train", "volume", "test")
T = TypeVar("T")


class TooFewModelsError(ValueError):
    """A class has fewer models than the split needs (the class is named)."""


def class_seed(seed: int, class_name: str) -> np.random.Generator:
    """A generator for one class that depends only on the seed and the class's name."""
    digest = hashlib.sha256(class_name.encode()).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "little")])


def split_models(
    models: Mapping[str, Sequence[T]],
    counts: Mapping[str, int],
    seed: int,
    too_few: str = "error",
    extra: str = "train",
) -> dict[str, dict[str, list[T]]]:
    """Draw each class's models for every role, deterministic from the seed.

    Each class is shuffled by its own generator, so adding a class does not change the others'
    split. ``counts`` are the models each role needs; a class with more models gives the rest
    to training (``extra="train"``) or leaves them out (``extra="drop"``): the volume and test
    roles keep their counts, so every class is evaluated alike. With ``too_few="drop"`` a class
    with too few models is dropped with a warning; otherwise it is an error.
    """
    if extra not in ("train", "drop"):
        raise ValueError(f"unknown rule for extra models '{extra}'; use 'train' or 'drop'")
    need = sum(counts[role] for role in ROLES)
    split: dict[str, dict[str, list[T]]] = {}
    for name, items in models.items():
        if len(items) < need:
            message = (
                f"class '{name}' has {len(items)} model(s); the split needs {need} "
                f"({', '.join(f'{counts[r]} {r}' for r in ROLES)}): set dataset.split to "
                "fewer, or dataset.too_few_models: drop"
            )
            if too_few == "drop":
                warnings.warn(f"{message}: class dropped", stacklevel=2)
                continue
            raise TooFewModelsError(message)
        order = class_seed(seed, name).permutation(len(items))
        picked = [items[i] for i in order[:need]]
        start = 0
        split[name] = {}
        for role in ROLES:
            split[name][role] = picked[start : start + counts[role]]
            start += counts[role]
        if extra == "train":
            split[name]["train"] += [items[i] for i in order[need:]]
    if not split:
        raise TooFewModelsError("no class has enough models for the split")
    return split
