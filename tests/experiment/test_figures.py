"""Fig. 3's curves from a hand-made episodes table: the padding and the class filter."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from rapomdp.experiment.episode_table import EpisodeTable
from rapomdp.experiment.figures import belief_curves, fig3


def _table() -> EpisodeTable:
    """Three episodes: ra on class 0 with 1 and 3 images, static on class 1 with 2 images;
    the belief in the true class is written into the steps."""
    classes, methods = ["cup", "mug"], ["static", "ra", "random"]
    method = np.array(["ra", "ra", "static"])
    class_index = np.array([0, 0, 1])
    lengths = np.array([1, 3, 2])
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    true_belief = np.array([0.9, 0.5, 0.6, 0.7, 0.4, 0.8])
    beliefs = np.zeros((offsets[-1], 2))
    for episode, c in enumerate(class_index):
        rows = slice(offsets[episode], offsets[episode + 1])
        beliefs[rows, c] = true_belief[rows]
        beliefs[rows, 1 - c] = 1 - true_belief[rows]
    n, steps = method.size, int(offsets[-1])
    return EpisodeTable(
        classes=classes, methods=methods, method=method, class_index=class_index,
        model=np.array(["m0", "m1", "m2"]), start=np.zeros(n, np.int64),
        declared=class_index.copy(), exhausted=np.zeros(n, bool), correct=np.ones(n, bool),
        belief=true_belief[offsets[1:] - 1], moves=lengths - 1, distance_m=np.zeros(n),
        energy=np.zeros(n), offsets=offsets, step_viewpoints=np.arange(steps) % 4,
        step_outputs=beliefs.copy(), step_beliefs=beliefs, cpu_seconds=np.zeros(n))


def test_a_declared_episode_keeps_its_final_belief_in_the_mean_curve() -> None:
    curves = belief_curves(_table(), ["static", "ra", "random"], None)
    assert list(curves) == ["static", "ra"]  # random ran no episode: no curve
    # ra: (0.9, 0.9, 0.9) padded and (0.5, 0.6, 0.7) averaged step by step
    np.testing.assert_allclose(curves["ra"], [0.7, 0.75, 0.8])
    np.testing.assert_allclose(curves["static"], [0.4, 0.8])


def test_the_class_filter_keeps_that_class_only() -> None:
    curves = belief_curves(_table(), ["static", "ra"], 1)
    assert list(curves) == ["static"]
    np.testing.assert_allclose(curves["static"], [0.4, 0.8])


def test_fig3_draws_both_panels_from_the_table(tmp_path: Path) -> None:
    path = fig3(_table(), ["static", "ra"], "mug", tmp_path / "fig3.png")
    with Image.open(path) as image:  # two side-by-side panels: wider than tall
        assert image.format == "PNG" and image.width > 2 * image.height


def test_the_tradeoff_figure_draws_methods_always_or_never_right(tmp_path: Path) -> None:
    from rapomdp.experiment.figures import tradeoff
    from rapomdp.experiment.metrics import TradeoffPoint, summarise

    def point(method: str, value: float, correct: list[bool]) -> TradeoffPoint:
        n = len(correct)
        summary = summarise(np.array(correct), np.full(n, 0.5), np.ones(n), np.ones(n),
                            np.full(n, value), np.zeros(n, bool), method)
        return TradeoffPoint(method, "lambda", value, False, summary)

    points = [point("ra", 1.0, [True] * 10), point("ra", 2.0, [False] * 7),
              point("random", 1.0, [False] * 3), point("random", 2.0, [False] * 6)]
    assert tradeoff(points, tmp_path / "t.png").stat().st_size > 0


def test_every_method_has_its_own_colour_and_marker() -> None:
    from rapomdp.config import METHOD_NAMES
    from rapomdp.experiment.figures import METHOD_STYLES, method_style

    assert set(METHOD_STYLES) == set(METHOD_NAMES)
    colours = [c for c, _, _ in METHOD_STYLES.values()]
    markers = [m for _, _, m in METHOD_STYLES.values()]
    assert len(set(colours)) == len(colours) and len(set(markers)) == len(markers)
    unknown = method_style("a_method_of_ones_own", 0)
    assert unknown[0] not in colours and unknown[2] not in markers


def test_static_stays_visible_under_a_pomdp_point_at_the_same_place() -> None:
    """The trade-off draws Static (one point) above the curves as a large hollow marker of its
    own colour, so RA-POMDP's λ point at the same (energy, accuracy) shows through it."""
    from matplotlib.colors import to_rgba

    from rapomdp.experiment import figures
    from rapomdp.experiment.metrics import TradeoffPoint, summarise

    def point(method: str, parameter: str, value: float, energy: float) -> TradeoffPoint:
        correct = np.arange(10) < 6
        summary = summarise(correct, np.full(10, 0.5), np.ones(10), np.ones(10),
                            np.full(10, energy), np.zeros(10, bool), method)
        return TradeoffPoint(method, parameter, value, value == 8.0, summary)

    points = [point("ra", "lambda", 0.5, 0.0), point("ra", "lambda", 8.0, 1.2),
              point("static", "none", 0.0, 0.0)]
    ax = figures.tradeoff_plot(points).axes[0]
    lines = {c.get_label(): c.lines[0] for c in ax.containers}  # each errorbar's data line
    static, ra = lines["Static"], lines["RA-POMDP"]
    assert static.get_zorder() > ra.get_zorder()
    assert static.get_markerfacecolor() == "none" and static.get_markersize() > 2 * \
        ra.get_markersize()
    assert to_rgba(static.get_color()) != to_rgba(ra.get_color())
    assert static.get_marker() != ra.get_marker()
    assert (static.get_xdata()[0], static.get_ydata()[0]) == (ra.get_xdata()[0],
                                                              ra.get_ydata()[0])
