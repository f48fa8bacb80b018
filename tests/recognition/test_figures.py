"""The classifier's figures stay within the report's width at any class count."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from rapomdp.plots import MAX_WIDTH_IN, PNG_DPI
from rapomdp.recognition.figures import confusion_figure


def test_a_35_class_confusion_fits_the_report(tmp_path: Path) -> None:
    classes = [f"class_{i}" for i in range(35)]
    confusion = np.eye(35) * 10 + np.roll(np.eye(35), 1, axis=1)
    path = confusion_figure(confusion, classes, "35 classes", tmp_path / "c.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(path) as image:  # tight bounding box: at most the figure's width
        assert image.width <= MAX_WIDTH_IN * PNG_DPI + 1
