"""The pretrained backbone: the shipped file loads and matches its hash, a tampered or foreign
one is refused by name, and fine-tuning from a backbone is reproducible."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from rapomdp.config import ConfigError, TrainConfig, config_from_dict
from rapomdp.recognition.backbone import (
    BACKBONE_FORMAT,
    SHIPPED_BACKBONE,
    BackboneError,
    check_fits,
    load_backbone,
    write_backbone,
)
from rapomdp.recognition.network import DepthAlexNet
from rapomdp.recognition.training import (
    network_spec,
    preprocess_params,
    train_classifier,
    training_backbone,
)
from tests.recognition.test_training import TOY_CLASSES, toy_views


def test_the_shipped_backbone_loads_and_matches_its_hash() -> None:
    backbone = load_backbone(SHIPPED_BACKBONE)
    card = json.loads(SHIPPED_BACKBONE.with_suffix(".json").read_text())
    assert card["format"] == BACKBONE_FORMAT
    assert backbone.sha256 == card["weights_sha256"]
    assert SHIPPED_BACKBONE.stat().st_size == card["weights_bytes"] <= 20 * 2**20
    # it fits the default configuration's network
    cfg = TrainConfig()
    check_fits(backbone, network_spec(35, cfg), preprocess_params(cfg.preprocess))
    network = DepthAlexNet(network_spec(35, cfg))
    assert set(backbone.state) == {f"features.{k}" for k in network.features.state_dict()}
    assert card["corpus"]["classes"] >= 100 and card["corpus"]["models"] >= 1000
    assert card["epochs"] == card["recipe"]["epochs"] and card["seconds"] > 0


def test_a_tampered_backbone_is_refused_by_name(tmp_path: Path) -> None:
    copy = tmp_path / "depth-backbone-v1.pt"
    shutil.copy(SHIPPED_BACKBONE, copy)
    shutil.copy(SHIPPED_BACKBONE.with_suffix(".json"), copy.with_suffix(".json"))
    load_backbone(copy)  # an exact copy loads
    data = bytearray(copy.read_bytes())
    data[len(data) // 2] ^= 0xFF
    copy.write_bytes(bytes(data))
    with pytest.raises(BackboneError, match=r"depth-backbone-v1\.pt: the weights do not "
                                            r"match the SHA-256 .*refused"):
        load_backbone(copy)


def test_a_missing_or_foreign_backbone_is_refused(tmp_path: Path) -> None:
    with pytest.raises(BackboneError, match="no backbone here"):
        load_backbone(tmp_path / "none.pt")
    (tmp_path / "x.pt").write_bytes(b"0")
    (tmp_path / "x.json").write_text('{"format": "something-else"}')
    with pytest.raises(BackboneError, match="not a rapomdp depth backbone card"):
        load_backbone(tmp_path / "x.pt")


def tiny_backbone(path: Path, cfg: TrainConfig, seed: int = 5) -> Path:
    torch.manual_seed(seed)
    network = DepthAlexNet(network_spec(9, cfg))
    state = {k: v for k, v in network.state_dict().items() if k.startswith("features.")}
    return write_backbone(path, state, network.spec, preprocess_params(cfg.preprocess),
                          {"corpus": {"classes": 9}})


def test_a_backbone_of_another_width_is_refused_with_the_key(tmp_path: Path) -> None:
    path = tiny_backbone(tmp_path / "b.pt", TrainConfig(width=0.125))
    with pytest.raises(BackboneError, match="pretrained with train.width 0.125, this "
                                            "configuration asks 0.25"):
        training_backbone(TrainConfig(backbone=str(path)))


def test_the_backbone_key_is_validated() -> None:
    with pytest.raises(ConfigError, match="neither scratch, pretrained nor a backbone file"):
        config_from_dict({"train": {"backbone": "imagenet"}})
    assert config_from_dict({"train": {"backbone": "x/y.pt"}}).train.backbone == "x/y.pt"


def test_fine_tuning_starts_from_the_backbone_and_is_identical_on_rerun(tmp_path: Path
                                                                        ) -> None:
    base = dict(width=0.125, epochs=2, batch_size=16, dropout=0.0,
                preprocess={"input_size_px": 32})
    path = tiny_backbone(tmp_path / "b.pt", TrainConfig(**base))
    cfg = TrainConfig(**base, backbone=str(path))
    data = toy_views(6, seed=1)
    runs = [train_classifier(data, data.subset(np.zeros(len(data), bool)), TOY_CLASSES, cfg,
                             144.3, 144.3, seed=2, device=torch.device("cpu"),
                             progress=False)[0] for _ in range(2)]
    first, second = (r.network.state_dict() for r in runs)
    assert all(torch.equal(first[k], second[k]) for k in first)
    scratch = train_classifier(data, data.subset(np.zeros(len(data), bool)), TOY_CLASSES,
                               TrainConfig(**base), 144.3, 144.3, seed=2,
                               device=torch.device("cpu"), progress=False)[0]
    start = load_backbone(path).state["features.0.weight"]
    tuned = first["features.0.weight"]
    # fine-tuned: two epochs at a tenth of the rate move the backbone's weights a little;
    # from scratch the first layer is another draw altogether
    assert 0 < float((tuned - start).abs().max()) < 0.05
    assert float((scratch.network.state_dict()["features.0.weight"] - start).abs().max()) > 0.05


def test_a_backbone_with_a_recogniser_of_ones_own_is_refused() -> None:
    cfg = TrainConfig(backbone="pretrained", network="rapomdp.recognition.examples:small_resnet")
    with pytest.raises(BackboneError, match="starts the alexnet network's convolutions; "
                                            "train.network is 'rapomdp.recognition"):
        training_backbone(cfg)
