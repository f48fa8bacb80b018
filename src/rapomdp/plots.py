"""What every figure module shares: matplotlib figures through the object API (no pyplot, no
global backend), one text style sized for the report, a colour-blind-safe palette, and PNG and
self-contained HTML writing (atomic; plotly.js embedded so a page works offline).

Sizes: the report shows figures at most ~960 px wide (60 em). A figure ``w`` inches wide with
``f``-point text shows its text at ``f * 960 / (72 w)`` px, so figures here are at most 10 in
wide with text of at least 9 pt (>= 12 px on screen).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rapomdp.io import atomic_path

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Okabe & Ito's colour-blind-safe palette (orange, sky blue, bluish green, yellow, blue,
#: vermillion, reddish purple, black).
OKABE_ITO = ("#E69F00", "#56B4E9", "#009E73", "#F0E442", "#0072B2", "#D55E00", "#CC79A7",
             "#000000")
#: Outcome colours, always paired with a marker shape: right = bluish green disc,
#: wrong = vermillion cross.
RIGHT_COLOUR, WRONG_COLOUR = OKABE_ITO[2], OKABE_ITO[5]
PNG_DPI = 150
MAX_WIDTH_IN = 10.0
#: Azimuth labels of the hemisphere's top views: world axes, not angles (the rings are angles).
AZIMUTH_LABELS = ("+x", "+y", "−x", "−y")
#: Where the rings' labels sit: half-way between the +y and −x labels, so that no ring label
#: (the 90° one at the rim above all) stands beside an azimuth label.
RING_LABEL_AZIMUTH_DEG = 135.0
STYLE: dict[str, Any] = {
    "font.size": 10, "axes.titlesize": 10.5, "axes.labelsize": 10, "legend.fontsize": 9,
    "xtick.labelsize": 9, "ytick.labelsize": 9, "figure.titlesize": 11,
}


@contextmanager
def style() -> Iterator[None]:
    """The figures' text sizes and colour cycle (Okabe-Ito), for the block only."""
    import matplotlib
    from cycler import cycler

    with matplotlib.rc_context({**STYLE, "axes.prop_cycle": cycler(color=OKABE_ITO)}):
        yield


def new_figure(width_in: float, height_in: float) -> Figure:
    """A figure with an Agg canvas (object API; no pyplot state, no backend switch)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if width_in > MAX_WIDTH_IN:
        raise ValueError(f"figure {width_in} in wide: the report shows at most {MAX_WIDTH_IN} in "
                         f"legibly")
    figure = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_png(figure: Figure, path: str | Path, dpi: int = PNG_DPI) -> Path:
    """Write ``figure`` as PNG atomically (tight bounding box); returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        figure.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight")
    return path


def save_html(figure: Any, path: str | Path) -> Path:
    """Write a plotly figure as one self-contained HTML page: plotly.js is embedded (~4.7 MB),
    so the page works offline and nothing is fetched when it is opened."""
    path = Path(path)
    with atomic_path(path) as tmp:
        figure.write_html(str(tmp), include_plotlyjs=True, full_html=True)
    return path


def hemisphere_axes(ax: Any, ring_fontsize: float = 8.0) -> None:
    """Make a polar axes the top view of the upper hemisphere: radius the angle from the zenith
    in degrees (0 to 90; rings at 30° and 60° labelled at :data:`RING_LABEL_AZIMUTH_DEG` on a
    white ground, drawn under the data; the rim, 90°, labelled just outside it there), azimuth
    labelled by the world axes (:data:`AZIMUTH_LABELS`, nothing at the diagonals), so that no
    ring label stands beside an azimuth label or hides a viewpoint. Every hemisphere figure
    uses it."""
    from math import radians

    ax.set_ylim(0, 90)
    ax.set_yticks([30, 60], ["30°", "60°"], fontsize=ring_fontsize,
                  bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8})
    ax.set_rlabel_position(RING_LABEL_AZIMUTH_DEG)
    ax.yaxis.set_zorder(0.5)  # rings and their labels under the data
    ax.annotate("90°", (radians(RING_LABEL_AZIMUTH_DEG), 90.0), xytext=(-1.0, 1.0),
                textcoords="offset points", ha="right", va="bottom", fontsize=ring_fontsize,
                annotation_clip=False)
    ax.set_xticks([radians(a) for a in (0, 90, 180, 270)], AZIMUTH_LABELS)
