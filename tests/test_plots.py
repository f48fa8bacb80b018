"""The shared figure helpers: the report's width limit, PNG writing without pyplot, the
hemisphere's top view."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

from rapomdp.plots import (
    AZIMUTH_LABELS,
    MAX_WIDTH_IN,
    PNG_DPI,
    RING_LABEL_AZIMUTH_DEG,
    hemisphere_axes,
    new_figure,
    save_png,
    style,
)


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


def test_hemisphere_ring_labels_meet_no_azimuth_label_and_hide_no_point() -> None:
    import numpy as np

    with style():
        figure = new_figure(4.0, 4.0)
        ax = figure.add_subplot(projection="polar")
        # viewpoints on the rim and on the rings, at the ring labels' azimuth among others
        azimuth = np.radians(np.arange(0.0, 360.0, 22.5))
        points = ax.scatter(np.tile(azimuth, 3), np.repeat([30.0, 60.0, 90.0], azimuth.size))
        hemisphere_axes(ax)
        figure.canvas.draw()
        renderer = figure.canvas.get_renderer()
        azimuths = [t for t in ax.get_xticklabels() if t.get_text()]
        rings = [t for t in ax.get_yticklabels() if t.get_text()]
        rim = [t for t in ax.texts if t.get_text() == "90°"]
    assert [t.get_text() for t in azimuths] == list(AZIMUTH_LABELS)
    assert [t.get_text() for t in rings] == ["30°", "60°"] and len(rim) == 1
    assert ax.get_rlabel_position() == RING_LABEL_AZIMUTH_DEG and ax.get_ylim() == (0, 90)
    for ring in [*rings, *rim]:
        box = ring.get_window_extent(renderer)
        assert not any(box.overlaps(a.get_window_extent(renderer)) for a in azimuths), \
            ring.get_text()
    # the rim's label lies outside the disc: its box is beyond the rim's circle
    centre = ax.transData.transform((0.0, 0.0))
    radius = np.hypot(*(ax.transData.transform((0.0, 90.0)) - centre))
    box = rim[0].get_window_extent(renderer)
    corner = np.array([box.x1, box.y0])  # the corner nearest the centre (up and to the left)
    assert np.hypot(*(corner - centre)) > radius
    # the rings (and their labels) are drawn under the data
    assert ax.yaxis.get_zorder() < points.get_zorder()
