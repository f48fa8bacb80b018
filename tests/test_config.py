from pathlib import Path

import pytest
import yaml

from rapomdp.config import Config, ConfigError, config_from_dict, load_config


def test_default_has_the_papers_values() -> None:
    cfg = Config()
    assert cfg.viewpoints.count == 128 and cfg.viewpoints.radius_m == 0.6
    assert cfg.dataset.radius_m == 0.2
    # 4 test models a class for statistics over test models; the paper's 3 / 1 / 1 is a config
    assert (cfg.dataset.split.train, cfg.dataset.split.volume, cfg.dataset.split.test) == (4, 1, 4)
    assert cfg.dataset.split.extra == "train"
    paper = load_config(Path(__file__).parents[1] / "configs" / "paper.yaml")
    assert (paper.dataset.split.train, paper.dataset.split.volume, paper.dataset.split.test) \
        == (3, 1, 1)
    assert paper.evaluate.starts_per_model == 5 and paper.dataset.classes is None
    assert cfg.render.noise.enabled is False


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


def test_cross_field_rules_and_unreadable_files(tmp_path: Path) -> None:
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
