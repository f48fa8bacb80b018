import pytest

from rapomdp.data.splits import TooFewModelsError, split_models

COUNTS = {"train": 3, "volume": 1, "test": 1}


def test_split_is_deterministic_disjoint_and_per_class_independent() -> None:
    models = {"a": list(range(8)), "b": list(range(5))}
    first = split_models(models, COUNTS, seed=7, extra="drop")
    assert first == split_models(models, COUNTS, seed=7, extra="drop")
    for roles in first.values():
        picked = roles["train"] + roles["volume"] + roles["test"]
        assert len(roles["train"]) == 3 and len(roles["volume"]) == 1
        assert len(set(picked)) == 5
    # adding a class leaves the others' split unchanged
    more = split_models({**models, "c": list(range(6))}, COUNTS, seed=7, extra="drop")
    assert more["a"] == first["a"] and more["b"] == first["b"]
    # another seed gives another split
    assert any(split_models(models, COUNTS, seed=s, extra="drop")["a"] != first["a"]
               for s in range(8, 12))


def test_too_few_models_is_an_error_naming_the_class_or_a_dropped_class() -> None:
    models = {"cup": [1, 2, 3, 4, 5], "vase": [1, 2]}
    with pytest.raises(TooFewModelsError, match="class 'vase' has 2 model"):
        split_models(models, COUNTS, seed=0)
    with pytest.warns(UserWarning, match="class 'vase'.*dropped"):
        split = split_models(models, COUNTS, seed=0, too_few="drop")
    assert list(split) == ["cup"]
    with pytest.raises(TooFewModelsError, match="no class has enough"), pytest.warns(UserWarning):
        split_models({"vase": [1]}, COUNTS, seed=0, too_few="drop")


def test_extra_models_go_to_training_or_are_dropped_and_the_other_roles_keep_their_counts() -> None:
    models = {"chair": list(range(12)), "cup": list(range(5))}
    used = split_models(models, COUNTS, seed=4)
    assert [len(used["chair"][r]) for r in ("train", "volume", "test")] == [10, 1, 1]
    assert sorted(used["chair"]["train"] + used["chair"]["volume"] + used["chair"]["test"]) \
        == list(range(12))
    assert [len(used["cup"][r]) for r in ("train", "volume", "test")] == [3, 1, 1]
    dropped = split_models(models, COUNTS, seed=4, extra="drop")
    assert [len(dropped["chair"][r]) for r in ("train", "volume", "test")] == [3, 1, 1]
    # the same draw: the volume and test models do not depend on the rule, training only grows
    for role in ("volume", "test"):
        assert dropped["chair"][role] == used["chair"][role]
    assert set(dropped["chair"]["train"]) < set(used["chair"]["train"])
    with pytest.raises(ValueError, match="unknown rule for extra models 'test'"):
        split_models(models, COUNTS, seed=4, extra="test")
