"""Retired options: dropped at their former default, refused by name at any other value."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rapomdp.config import Config, ConfigError, config_from_dict
from rapomdp.retired import RETIRED_KEYS, RETIRED_VALUES, drop_retired

ROOT = Path(__file__).resolve().parents[1]


def _nested(dotted: str, value: object) -> dict:
    *parents, leaf = dotted.split(".")
    data: dict = {leaf: value}
    for part in reversed(parents):
        data = {part: data}
    return data


@pytest.mark.parametrize("dotted", sorted(RETIRED_KEYS))
def test_a_retired_key_at_its_former_default_is_dropped(dotted: str) -> None:
    data = _nested(dotted, RETIRED_KEYS[dotted].default)
    assert config_from_dict(data, "old.yaml") == Config()


@pytest.mark.parametrize("dotted", sorted(RETIRED_KEYS))
def test_a_retired_key_at_another_value_is_refused_with_its_page(dotted: str) -> None:
    default = RETIRED_KEYS[dotted].default
    other = (not default) if isinstance(default, bool) else ["something", "else"]
    with pytest.raises(ConfigError) as caught:
        config_from_dict(_nested(dotted, other), "old.yaml")
    message = str(caught.value)
    assert message.startswith(f"old.yaml: {dotted} was retired")
    assert f"docs/decisions/{RETIRED_KEYS[dotted].page}" in message


@pytest.mark.parametrize(("dotted", "value"),
                         [(key, value) for key, values in RETIRED_VALUES.items()
                          for value in values])
def test_a_retired_value_is_refused_with_its_page(dotted: str, value: str) -> None:
    with pytest.raises(ConfigError) as caught:
        config_from_dict(_nested(dotted, value), "old.yaml")
    assert f"{dotted}: {value!r} was retired" in str(caught.value)
    assert f"docs/decisions/{RETIRED_VALUES[dotted][value]}" in str(caught.value)


def test_every_retired_key_is_gone_from_the_configuration() -> None:
    dumped = yaml.safe_load(Config().to_yaml())
    for dotted in RETIRED_KEYS:
        node = dumped
        *parents, leaf = dotted.split(".")
        for part in parents:
            node = node[part]
        assert leaf not in node, dotted


def test_every_page_named_exists() -> None:
    pages = {r.page for r in RETIRED_KEYS.values()}
    pages |= {page for values in RETIRED_VALUES.values() for page in values.values()}
    missing = sorted(p for p in pages if not (ROOT / "docs" / "decisions" / p).is_file())
    assert missing == []


def test_drop_retired_leaves_its_input_alone_and_keeps_other_keys() -> None:
    data = {"train": {"norm": "none", "epochs": 5}, "seed": 3}
    assert drop_retired(data, "x") == {"train": {"epochs": 5}, "seed": 3}
    assert data == {"train": {"norm": "none", "epochs": 5}, "seed": 3}


def test_a_boolean_is_not_taken_for_a_numeric_former_default() -> None:
    with pytest.raises(ConfigError, match="evaluate.lookahead_depth was retired"):
        config_from_dict({"evaluate": {"lookahead_depth": True}}, "x")
