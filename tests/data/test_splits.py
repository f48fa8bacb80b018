import pytest

from rapomdp.config import SplitConfig
from rapomdp.data.splits import (
    AUTO_FULL_MODELS,
    AUTO_MIN_MODELS,
    TooFewModelsError,
    auto_counts,
    split_models,
)

COUNTS = {"train": 3, "volume": 1, "test": 1}


def test_split_is_deterministic_disjoint_and_per_class_independent() -> None:
    models = {"a": list(range(8)), "b": list(range(5))}
    first = split_models(models, COUNTS, seed=7, extra="drop").roles
    assert first == split_models(models, COUNTS, seed=7, extra="drop").roles
    for roles in first.values():
        picked = roles["train"] + roles["volume"] + roles["test"]
        assert len(roles["train"]) == 3 and len(roles["volume"]) == 1
        assert len(set(picked)) == 5
    # adding a class leaves the others' split unchanged
    more = split_models({**models, "c": list(range(6))}, COUNTS, seed=7, extra="drop").roles
    assert more["a"] == first["a"] and more["b"] == first["b"]
    # another seed gives another split
    assert any(split_models(models, COUNTS, seed=s, extra="drop").roles["a"] != first["a"]
               for s in range(8, 12))


def test_too_few_models_is_one_error_naming_each_class_or_the_classes_are_dropped() -> None:
    models = {"cup": [1, 2, 3, 4, 5], "vase": [1, 2], "jar": [1, 2, 3]}
    with pytest.raises(TooFewModelsError) as error:
        split_models(models, COUNTS, seed=0)
    assert str(error.value).startswith(
        "class 'vase' has 2 model(s), class 'jar' has 3 model(s); the split needs 5 "
        "(3 train, 1 volume, 1 test): add models")
    split = split_models(models, COUNTS, seed=0, too_few="drop")  # no Python warning
    assert list(split.roles) == ["cup"] and split.dropped == {"vase": 2, "jar": 3}
    assert split.dropped_message is not None
    assert split.dropped_message.endswith("class(es) left out")
    assert "class 'vase' has 2 model(s)" in split.dropped_message
    assert split_models({"cup": [1, 2, 3, 4, 5]}, COUNTS, seed=0).dropped_message is None
    with pytest.raises(TooFewModelsError, match="no class has enough.*'vase' has 1"):
        split_models({"vase": [1]}, COUNTS, seed=0, too_few="drop")


def test_extra_models_go_to_training_or_are_dropped_and_the_other_roles_keep_their_counts() -> None:
    models = {"chair": list(range(12)), "cup": list(range(5))}
    used = split_models(models, COUNTS, seed=4).roles
    assert [len(used["chair"][r]) for r in ("train", "volume", "test")] == [10, 1, 1]
    assert sorted(used["chair"]["train"] + used["chair"]["volume"] + used["chair"]["test"]) \
        == list(range(12))
    assert [len(used["cup"][r]) for r in ("train", "volume", "test")] == [3, 1, 1]
    dropped = split_models(models, COUNTS, seed=4, extra="drop").roles
    assert [len(dropped["chair"][r]) for r in ("train", "volume", "test")] == [3, 1, 1]
    # the same draw: the volume and test models do not depend on the rule, training only grows
    for role in ("volume", "test"):
        assert dropped["chair"][role] == used["chair"][role]
    assert set(dropped["chair"]["train"]) < set(used["chair"]["train"])
    with pytest.raises(ValueError, match="unknown rule for extra models 'test'"):
        split_models(models, COUNTS, seed=4, extra="test")


def test_auto_counts_grow_from_the_papers_split_to_the_default() -> None:
    table = {n: tuple(auto_counts(n)[r] for r in ("train", "volume", "test"))
             for n in range(AUTO_MIN_MODELS, AUTO_FULL_MODELS + 1)}
    assert table == {5: (3, 1, 1), 6: (3, 1, 2), 7: (3, 2, 2), 8: (3, 2, 3), 9: (4, 2, 3),
                     10: (4, 3, 3), 11: (4, 3, 4)}
    assert all(sum(counts) == n for n, counts in table.items())
    full = SplitConfig()  # the fixed split's default is the rule's full size
    assert table[AUTO_FULL_MODELS] == (full.train, full.volume, full.test)
    with pytest.raises(ValueError, match="at least 5 models, got 4"):
        auto_counts(4)


def test_auto_split_uses_every_model_and_matches_the_fixed_default_from_eleven() -> None:
    models = {"a": list(range(5)), "b": list(range(7)), "c": list(range(11)),
              "d": list(range(16))}
    auto = split_models(models, None, seed=2).roles
    for name, items in models.items():
        picked = auto[name]["train"] + auto[name]["volume"] + auto[name]["test"]
        assert sorted(picked) == items  # every model used, once
        assert len(auto[name]["test"]) >= 1 and len(auto[name]["volume"]) >= 1
    assert [len(auto["b"][r]) for r in ("train", "volume", "test")] == [3, 2, 2]
    assert [len(auto["d"][r]) for r in ("train", "volume", "test")] == [9, 3, 4]
    fixed = split_models(models, {"train": 4, "volume": 3, "test": 4}, seed=2,
                         too_few="drop").roles
    assert fixed["c"] == auto["c"] and fixed["d"] == auto["d"]  # the same draw
    with pytest.raises(TooFewModelsError, match="class 'e' has 4 model\\(s\\); split: auto "
                       "needs at least 5 a class \\(3 train, 1 volume, 1 test\\)"):
        split_models({**models, "e": list(range(4))}, None, seed=2)

