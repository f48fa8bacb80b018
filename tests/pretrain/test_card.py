"""The model card page is generated from the shipped card, never typed in."""

from __future__ import annotations

from pathlib import Path

from rapomdp.io import read_json
from rapomdp.pretrain.card import card_markdown
from rapomdp.recognition.backbone import SHIPPED_BACKBONE, card_path

ROOT = Path(__file__).resolve().parents[2]


def test_docs_backbone_page_is_the_shipped_cards() -> None:
    card = read_json(card_path(SHIPPED_BACKBONE))
    page = (ROOT / "docs" / "backbone.md").read_text()
    assert page == card_markdown(card, SHIPPED_BACKBONE.name)
    assert f"SHA-256 `{card['weights_sha256']}`" in page
    assert f"{card['corpus']['classes']} classes" in page
