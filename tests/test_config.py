import math
import re
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from rapomdp.config import (
    Config,
    ConfigError,
    SplitConfig,
    config_from_dict,
    load_config,
    parse_yaml,
    read_config_data,
)


def test_default_has_the_papers_values() -> None:
    cfg = Config()
    assert cfg.viewpoints.count == 128 and cfg.viewpoints.radius_m == 0.6
    assert cfg.dataset.radius_m == 0.2
    # split: auto (every model used; 4 / 3 / 4 at eleven models a class, the procedural
    # default); the paper's 3 / 1 / 1 is a config
    assert cfg.dataset.split == "auto" and cfg.dataset.models_per_class is None
    assert (SplitConfig().train, SplitConfig().volume, SplitConfig().test) == (4, 3, 4)
    # RA-POMDP's model: the RA variants averaged with weights fitted held out
    assert cfg.volume.models_per_class == 1 and cfg.observe.ra_model == "mixture"
    assert SplitConfig().extra == "train"
    paper = load_config(Path(__file__).parents[1] / "configs" / "paper.yaml")
    assert (paper.dataset.split.train, paper.dataset.split.volume, paper.dataset.split.test) \
        == (3, 1, 1)
    assert paper.evaluate.starts_per_model == 5 and paper.dataset.classes is None
    assert cfg.render.noise.enabled is False
    # retired keys stay in the evaluate and learn keys at their one behaviour
    assert {k: Config().section("evaluate")[k] for k in (
        "lookahead", "lookahead_depth", "lookahead_width", "declared_confidence",
        "declared_fit")} == {"lookahead": True, "lookahead_depth": 1, "lookahead_width": 4,
                             "declared_confidence": "calibrated", "declared_fit": "closed_loop"}
    assert "declared_form" not in Config().section("evaluate")
    assert Config().section("learn")["declare"] == "map"


def test_every_shipped_configuration_loads_and_the_folder_sets_name_their_mesh_folders() -> None:
    folder = Path(__file__).parents[1] / "configs"
    configs = {p.stem: load_config(p) for p in sorted(folder.glob("*.yaml"))}
    assert {"paper", "real-cad-dev", "real-cad-dev-2", "mesh-set"} <= configs.keys()
    assert str(configs["mesh-set"].dataset.path) == "runs/mesh-set/meshes"
    assert configs["mesh-set"].dataset.source == "folder"
    assert configs["real-cad-dev"].dataset.layout == "generic"
    assert str(configs["real-cad-dev-2"].dataset.path) == "runs/real-cad-dev-2/meshes"


def test_an_option_added_later_leaves_the_stage_keys_alone_at_its_default() -> None:
    """``train.ensemble`` 1 is what every workspace before the option trained: left out of the
    section (so of every stage key); any other value is in it, and in the YAML either way."""
    assert "ensemble" not in Config().section("train")
    assert {k: v for k, v in Config().section("train").items()
            if k not in ("augment", "input_features")} == {
        k: v for k, v in Config().train.model_dump(mode="json").items()
        if k not in ("ensemble", "network", "backbone", "augment")}
    assert config_from_dict({"train": {"ensemble": 3}}).section("train")["ensemble"] == 3
    assert yaml.safe_load(Config().to_yaml())["train"]["ensemble"] == 1
    # train.network likewise: alexnet is what every workspace before the option trained
    assert "network" not in Config().section("train")
    assert config_from_dict({"train": {"network": "pkg.nets:resnet"}}).section(
        "train")["network"] == "pkg.nets:resnet"
    assert yaml.safe_load(Config().to_yaml())["train"]["network"] == "alexnet"
    # and train.backbone: scratch is what every workspace before it trained
    assert "backbone" not in Config().section("train")
    assert config_from_dict({"train": {"backbone": "pretrained"}}).section(
        "train")["backbone"] == "pretrained"
    # a retired key in the key at its one behaviour: workspaces before the retirement keep
    # their train key and their checkpoint's recorded hash
    assert "input_features" not in Config().train.model_dump()
    assert Config().section("train")["input_features"] == "depth_normals"
    assert Config().section("train")["augment"] == {"shift": 0.05, "scale": 0.1, "noise": False}
    assert Config().section("dataset") == Config().dataset.model_dump(mode="json")


def test_yaml_round_trip(tmp_path: Path) -> None:
    cfg = config_from_dict({"seed": 5, "camera": {"width": 80, "height": 60}})
    path = tmp_path / "c.yaml"
    path.write_text(cfg.to_yaml())
    assert load_config(path) == cfg
    assert load_config(None) == Config()


def test_wrong_keys_and_values_are_named(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"dataset": {"radiuss": 0.3, "split": {"train": 0}},
                                    "renderr": {}}))
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert str(path) in message
    assert "dataset.radiuss: unknown key" in message
    assert "renderr: unknown key" in message
    assert "dataset.split.train: Input should be greater than or equal to 1 (got 0)" in message
    # the split's two forms: the word auto or fixed counts; the union's tags are no keys
    assert config_from_dict({"dataset": {"split": "auto"}}) == Config()
    assert config_from_dict({"dataset": {"split": {"test": 2}}}).dataset.split.test == 2
    with pytest.raises(ConfigError) as wrong:
        config_from_dict({"dataset": {"split": "automatic"}})
    assert "dataset.split: Input should be 'auto' (got 'automatic')" in str(wrong.value)
    with pytest.raises(ConfigError, match="dataset.split.tset: unknown key"):
        config_from_dict({"dataset": {"split": {"tset": 2}}})


def test_cross_field_rules_and_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="'gradcam' attributes to one network's last "
                       "convolution, and train.ensemble 3 trains 3 networks"):
        config_from_dict({"train": {"ensemble": 3}, "saliency": {"method": "gradcam"}})
    with pytest.raises(ConfigError, match="source 'folder' needs dataset.path"):
        config_from_dict({"dataset": {"source": "folder"}})
    with pytest.raises(ConfigError, match="missing_full_deg must not be below"):
        config_from_dict({"render": {"noise": {"missing_start_deg": 80, "missing_full_deg": 70}}})
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "absent.yaml")
    (tmp_path / "broken.yaml").write_text("dataset: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(tmp_path / "broken.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_config(tmp_path / "list.yaml")


def test_aliases_and_expansions_are_bounded(tmp_path: Path) -> None:
    import time

    from rapomdp.config import MAX_ALIASES

    many = "a: &a 1\nb: [" + ", ".join(["*a"] * (MAX_ALIASES + 1)) + "]\n"
    with pytest.raises(ConfigError, match=f"more than {MAX_ALIASES} aliases"):
        parse_yaml(many, "many.yaml")
    assert parse_yaml("a: &a [1, 2]\nb: *a\n", "ok.yaml") == {"a": [1, 2], "b": [1, 2]}
    # 3 levels of 10 aliases of 1000 values: 21 aliases, 200 000 values once expanded
    wide = "l0: &l0 [" + ", ".join(["x"] * 1000) + "]\n"
    wide += "l1: &l1 [" + ", ".join(["*l0"] * 10) + "]\n"
    wide += "l2: &l2 [" + ", ".join(["*l1"] * 10) + "]\nseed: *l2\n"
    start = time.perf_counter()
    with pytest.raises(ConfigError, match="values once aliases are expanded"):
        parse_yaml(wide, "wide.yaml")
    assert time.perf_counter() - start < 2.0


def test_numbers_are_finite_in_range_and_never_booleans() -> None:
    cases = {
        "seed: Input should be greater than or equal to 0": {"seed": -1},
        "seed: a whole number of magnitude below 2^32 is expected": {"seed": 2**32},
        "render.radius_m: Input should be a finite number (got inf)":
            {"render": {"radius_m": float("inf")}},
        "solve.discount: Input should be a finite number": {"solve": {"discount": float("nan")}},
        "render.views: a boolean is not a number (got True)": {"render": {"views": True}},
        "robot.base_xyz_m: a boolean is not a number": {"robot": {"base_xyz_m": [True, 0, 0]}},
        "render.radius_m (0.1) must exceed dataset.radius_m (0.2)":
            {"render": {"radius_m": 0.1}},
        "viewpoints.radius_m (0.2) must exceed": {"viewpoints": {"radius_m": 0.2}},
        "dataset.classes: class '../x' is not a plain name": {"dataset": {"classes": ["../x"]}},
    }
    for message, data in cases.items():
        with pytest.raises(ConfigError) as info:
            config_from_dict(data)
        assert message in str(info.value), (message, str(info.value))
    assert config_from_dict({"seed": 2**32 - 1}).seed == 2**32 - 1
    assert config_from_dict({"render": {"noise": {"enabled": True}}}).render.noise.enabled


def test_an_error_never_shows_an_unbounded_value() -> None:
    with pytest.raises(ConfigError) as info:
        config_from_dict({"seed": "9" * 1_000_000, "render": {"views": list(range(10**5))}})
    message = str(info.value)
    assert len(message) < 600
    assert "render.views: Input should be a valid integer (got a list of 100000 items)" in message


def test_text_in_any_common_encoding(tmp_path: Path) -> None:
    text = "# réglages\nseed: 4\n"
    for encoding in ("utf-8", "utf-8-sig", "utf-16", "latin-1", "cp1252"):
        path = tmp_path / f"{encoding}.yaml"
        path.write_bytes(text.encode(encoding))
        assert load_config(path).seed == 4, encoding
    (tmp_path / "bin.yaml").write_bytes(b"seed: 4\x00\x00")
    with pytest.raises(ConfigError, match="bin.yaml: binary data"):
        load_config(tmp_path / "bin.yaml")


def test_overrides_are_typed_and_validated_like_the_file() -> None:
    from rapomdp.config import apply_overrides

    base = {"train": {"epochs": 3}, "seed": 1}
    data = apply_overrides(base, ["train.epochs=5", "dataset.classes=[cup, mug]",
                                  "solve.iterations=null", "train.augment.noise=true"])
    config = config_from_dict(data)
    assert config.train.epochs == 5 and config.dataset.classes == ["cup", "mug"]
    assert config.solve.iterations is None and config.train.augment.noise is True
    assert base == {"train": {"epochs": 3}, "seed": 1}, "the base mapping is not changed"
    with pytest.raises(ConfigError, match="expected section.key=value"):
        apply_overrides({}, ["train.epochs"])
    with pytest.raises(ConfigError, match="seed is a value, not a section"):
        apply_overrides({"seed": 1}, ["seed.x=2"])
    with pytest.raises(ConfigError, match="train.epochz: unknown key"):
        config_from_dict(apply_overrides({}, ["train.epochz=5"]))
    with pytest.raises(ConfigError, match="train.epochs: a boolean is not a number"):
        config_from_dict(apply_overrides({}, ["train.epochs=yes"]))


# -- property-based: whatever the document, a valid configuration or a bounded ConfigError --

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


@pytest.mark.parametrize(("text", "fragment"), [
    ("seed: 1\ntrain: {epochs: 5}\nseed: 2\n", "line 3, column 1: the key 'seed' is given twice "
                                                "(lines 1 and 3)"),
    ("train:\n  epochs: 5\nrender: {views: 6}\ntrain:\n  epochs: 25\n",
     "the key 'train' is given twice (lines 1 and 4)"),
    ("train: {epochs: 5, epochs: 6}\n", "the key 'epochs' is given twice"),
    ("dataset:\n  classes: !!set {cup, mug, bicycle}\n", "a !!set has no order")])
def test_duplicate_keys_and_sets_are_refused_by_line(text: str, fragment: str,
                                                    tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        read_config_data(path)


def test_a_merged_key_may_still_be_overridden() -> None:
    data = parse_yaml("base: &b {epochs: 5, batch: 2}\ntrain:\n  <<: *b\n  epochs: 7\n", "c")
    assert data["train"] == {"epochs": 7, "batch": 2}
