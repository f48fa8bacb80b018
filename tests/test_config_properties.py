"""Property-based tests of the configuration loader (hypothesis): whatever the document, the
loader returns a valid configuration or raises a bounded ConfigError, never anything else."""

from __future__ import annotations

import math

import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from rapomdp.config import Config, ConfigError, config_from_dict, parse_yaml

SECTIONS = list(Config.model_fields)
scalars = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=30))
values = st.recursive(scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(st.text(max_size=8), children, max_size=4)),
    max_leaves=12)
known_keys = st.sampled_from(SECTIONS + ["views", "epochs", "radius_m", "render", "x"])
documents = st.dictionaries(known_keys, st.one_of(values, st.dictionaries(
    st.sampled_from(["views", "radius_m", "epochs", "count", "width", "noise", "classes",
                     "zz"]), values, max_size=4)), max_size=5)


@settings(max_examples=150, deadline=None)
@given(documents)
def test_any_document_gives_a_config_or_a_bounded_config_error(document: dict) -> None:
    try:
        text = yaml.safe_dump(document)
    except yaml.YAMLError:
        return
    try:
        config = config_from_dict(parse_yaml(text, "doc.yaml") or {}, "doc.yaml")
    except ConfigError as exc:
        assert str(exc).startswith("doc.yaml: ")
        assert len(str(exc)) < 20 * 420
        return
    again = config_from_dict(parse_yaml(config.to_yaml(), "again") or {})
    assert again == config


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.integers(-(2**40), 2**40), st.booleans(),
                 st.floats(allow_nan=True, allow_infinity=True)))
def test_a_count_is_accepted_exactly_when_it_is_a_whole_number_of_at_least_one(value) -> None:
    valid = (not isinstance(value, bool) and math.isfinite(value) and value == int(value)
             and 1 <= value < 2**32)
    try:
        config = config_from_dict({"render": {"views": value}})
    except ConfigError as exc:
        assert not valid, (value, str(exc))
        assert "render.views" in str(exc)
        return
    assert valid and config.render.views == int(value)


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.booleans()))
def test_a_radius_is_accepted_exactly_when_finite_and_outside_the_object(value) -> None:
    valid = not isinstance(value, bool) and math.isfinite(value) and value > 0.2
    try:
        config = config_from_dict({"render": {"radius_m": value}})
    except ConfigError:
        assert not valid, value
        return
    assert valid and config.render.radius_m == value


@settings(max_examples=100, deadline=None)
@given(st.integers(-(2**70), 2**70))
def test_a_seed_is_accepted_exactly_within_32_bits(seed: int) -> None:
    try:
        assert config_from_dict({"seed": seed}).seed == seed
    except ConfigError:
        assert not 0 <= seed < 2**32
        return
    assert 0 <= seed < 2**32
