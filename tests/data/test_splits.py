import pytest

from rapomdp.data.splits import TooFewModelsError, split_models

COUNTS = {"train": 3, "volume": 1, "test": 1}


def test_split_is_deterministic_disjoint_and_per_class_independent() -> None:
    models = {"a": list(range(8)), "b": list(range(5))}
    first = split_models(models, COUNTS, seed=7)
    assert first == split_models(models, COUNTS, seed=7)
    for roles in first.values():
        picked = roles["train"] + roles["volume"] + roles["test"]
        assert len(roles["train"]) == 3 and len(roles["volume"]) == 1
        assert len(set(picked)) == 5
    # adding a class leaves the others' split unchanged
    more = split_models({**models, "c": list(range(6))}, COUNTS, seed=7)
    assert more["a"] == first["a"] and more["b"] == first["b"]
    # another seed gives another split
    assert any(split_models(models, COUNTS, seed=s)["a"] != first["a"] for s in range(8, 12))


def test_too_few_models_is_an_error_naming_the_class_or_a_dropped_class() -> None:
    models = {"cup": [1, 2, 3, 4, 5], "vase": [1, 2]}
    with pytest.raises(TooFewModelsError, match="class 'vase' has 2 model"):
        split_models(models, COUNTS, seed=0)
    with pytest.warns(UserWarning, match="class 'vase'.*dropped"):
        split = split_models(models, COUNTS, seed=0, too_few="drop")
    assert list(split) == ["cup"]
    with pytest.raises(TooFewModelsError, match="no class has enough"), pytest.warns(UserWarning):
        split_models({"vase": [1]}, COUNTS, seed=0, too_few="drop")
