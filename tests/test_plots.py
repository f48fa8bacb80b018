"""The shared figure helpers: the report's width limit, PNG writing without pyplot."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

from rapomdp.plots import MAX_WIDTH_IN, PNG_DPI, new_figure, save_png, style


def test_a_figure_wider_than_the_report_is_refused() -> None:
    with pytest.raises(ValueError, match=r"figure 10.5 in wide: the report shows at most 10.0"):
        new_figure(MAX_WIDTH_IN + 0.5, 3.0)


def test_a_figure_is_written_as_png_at_the_report_resolution(tmp_path: Path) -> None:
    with style():
        figure = new_figure(4.0, 2.0)
        figure.subplots().plot([0, 1], [1, 0])
        path = save_png(figure, tmp_path / "sub" / "line.png")
    assert [p.name for p in path.parent.iterdir()] == ["line.png"]  # atomic: no leftovers
    with Image.open(path) as image:  # the tight box: the figure's width and 0.1 in pads
        assert image.format == "PNG" and image.width <= (4.0 + 2 * 0.1) * PNG_DPI + 1
