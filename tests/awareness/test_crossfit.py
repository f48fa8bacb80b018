"""Cross-fitting folds: stratified by class, seeded, refused when a class is too small."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.crossfit import crossfit_folds
from rapomdp.data.dataset import ModelEntry


def _models(counts: dict[str, int]) -> list[ModelEntry]:
    return [ModelEntry(f"{name}_{i}", name, "train", "procedural", f"{name}/{i}.ply", 0.3, 10)
            for name, n in counts.items() for i in range(n)]


def test_folds_deal_every_class_across_every_fold():
    models = _models({"a": 5, "b": 3, "c": 4})
    fold = crossfit_folds(models, 3, seed=0)
    assert fold.min() == 0 and fold.max() == 2
    for name in "abc":
        mine = fold[[m.class_name == name for m in models]]
        counts = np.bincount(mine, minlength=3)
        assert counts.max() - counts.min() <= 1 and counts.min() >= 1
    assert np.array_equal(fold, crossfit_folds(models, 3, seed=0))
    assert any(not np.array_equal(fold, crossfit_folds(models, 3, seed=s)) for s in (1, 2, 3))


def test_folds_refuse_a_class_with_fewer_models_than_folds():
    with pytest.raises(ValueError, match=r"needs 3 training models per class; too few in "
                                         r"\{'b': 2\}"):
        crossfit_folds(_models({"a": 3, "b": 2}), 3, seed=0)
    with pytest.raises(ValueError, match="at least 2 folds"):
        crossfit_folds(_models({"a": 3}), 1, seed=0)
