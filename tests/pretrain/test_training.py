"""Pretraining: a stopped run resumes to the same weights, another recipe is refused, and the
exported backbone loads and fits the network it was trained in."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from rapomdp.io import ArtefactError
from rapomdp.pretrain import CorpusSettings, PretrainSettings, ViewSettings, run_pretrain
from rapomdp.pretrain.card import card_markdown
from rapomdp.pretrain.training import CHECKPOINT_WEIGHTS
from rapomdp.recognition.backbone import load_backbone

CORPUS = CorpusSettings(families=4, models_per_family=3, kicad=False)
VIEWS = ViewSettings(views=4, width_px=64, height_px=48, input_size_px=32)
RECIPE = PretrainSettings(width=0.125, epochs=2, batch_size=8, val_models_per_class=1)


def _run(workdir: Path, **options: object) -> tuple[Path | None, object]:
    return run_pretrain(workdir, corpus=CORPUS, views=VIEWS, settings=options.pop(
        "settings", RECIPE), threads=1, progress=False, log=lambda _: None,
        **options)  # type: ignore[arg-type]


def test_a_stopped_run_resumes_to_the_weights_of_an_uninterrupted_one(tmp_path: Path) -> None:
    whole, state = _run(tmp_path / "whole")
    assert whole is not None and state.epoch == 2  # type: ignore[attr-defined]
    stopped, partial_state = _run(tmp_path / "stopped", stop_after=1)
    assert stopped is None and partial_state.epoch == 1  # type: ignore[attr-defined]
    assert (tmp_path / "stopped" / CHECKPOINT_WEIGHTS).is_file()
    resumed, _ = _run(tmp_path / "stopped")
    assert resumed is not None
    a, b = load_backbone(whole).state, load_backbone(resumed).state
    assert set(a) == set(b) and all(torch.equal(a[k], b[k]) for k in a)
    card = load_backbone(resumed).card
    assert card["corpus"] == {"classes": 4, "models": 12, "views": 48, "sources": [
        {"name": "abstract families", "models": 12, "licence": card["corpus"]["sources"][0][
            "licence"], "origin": "rapomdp.data.procedural.abstract, seed 0", "classes": 4}]}
    assert [row["epoch"] for row in card["history"]] == [1, 2]
    page = card_markdown(card, resumed.name)
    assert "4 classes, 12 models, 48 views" in page and "2 epochs in" in page


def test_a_checkpoint_of_another_recipe_is_refused(tmp_path: Path) -> None:
    _run(tmp_path / "w", stop_after=1)
    other = PretrainSettings(width=0.125, epochs=2, batch_size=8, val_models_per_class=1,
                             learning_rate=5e-4)
    with pytest.raises(ArtefactError, match="a checkpoint of other settings"):
        _run(tmp_path / "w", settings=other)
    path, state = _run(tmp_path / "w", settings=other, restart=True)
    assert path is not None and state.epoch == 2  # type: ignore[attr-defined]
