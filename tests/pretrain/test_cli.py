"""``rapomdp pretrain`` from the command line: a tiny run writes a backbone, a bad source is
one error line."""

from __future__ import annotations

from pathlib import Path

import trimesh
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.recognition.backbone import load_backbone

runner = CliRunner()
TINY = ["--families", "3", "--models", "2", "--no-kicad", "--views", "4", "--epochs", "1",
        "--threads", "1", "--workers", "1", "--no-progress"]


def test_a_tiny_pretraining_writes_a_backbone_and_its_card(tmp_path: Path) -> None:
    out = tmp_path / "b.pt"
    result = runner.invoke(app, ["pretrain", "-d", str(tmp_path / "w"), "-o", str(out), *TINY])
    assert result.exit_code == 0, result.output
    assert "abstract families: 3 classes, 6 models" in result.output
    assert "epoch 1/1" in result.output and f"backbone: {out}" in result.output
    assert load_backbone(out).card["corpus"]["classes"] == 3


def test_an_evaluation_class_in_an_extra_folder_is_one_error_line(tmp_path: Path) -> None:
    (tmp_path / "mine" / "bicycle").mkdir(parents=True)
    trimesh.creation.box().export(tmp_path / "mine" / "bicycle" / "b.stl")
    result = runner.invoke(app, ["pretrain", "-d", str(tmp_path / "w"), "--extra",
                                 str(tmp_path / "mine"), *TINY])
    assert result.exit_code == 2
    assert "error: --extra folder class 'bicycle' is an evaluation class" in result.output
    assert not (tmp_path / "w" / "corpus").exists()


def test_bad_options_are_named(tmp_path: Path) -> None:
    result = runner.invoke(app, ["pretrain", "-o", str(tmp_path / "b.bin"), *TINY])
    assert result.exit_code == 2 and "a backbone's weights file ends in .pt" in result.output
    result = runner.invoke(app, ["pretrain", "--device", "tpu", *TINY])
    assert result.exit_code == 2 and "--device must be auto, cpu or cuda" in result.output
