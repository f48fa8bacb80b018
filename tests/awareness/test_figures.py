"""Figs. 1 and 2 on small synthetic inputs: one camera for (a)-(c), the default view facing the
salient part, a colour bar with its unit on every image panel, self-contained HTML; the
calibration figure against its caption; the reliability diagrams' counts."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rapomdp.awareness import figures
from rapomdp.awareness.observation import (
    ClassScoreCalibration,
    ScoreCalibration,
    TransferCalibration,
)
from rapomdp.awareness.variants import FixedCorrectness
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.geometry.camera import look_at, look_at_many
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.geometry.voxels import VoxelGrid
from tests.conftest import remote_references


def _volume(salient_side: np.ndarray | None) -> SaliencyVolume:
    """A 6^3 ball of occupied voxels around the origin; score 0.9 on the voxels whose centre
    lies towards ``salient_side`` (beyond 0.05 m along it), 0.1 elsewhere."""
    grid = VoxelGrid((-0.15, -0.15, -0.15), 0.05, (6, 6, 6))
    index = np.stack(np.meshgrid(*[np.arange(6)] * 3, indexing="ij"), -1).reshape(-1, 3)
    centres = grid.indices_to_centres(index)
    scores = np.full(grid.count, np.nan)
    inside = np.linalg.norm(centres, axis=1) < 0.16
    scores[inside] = 0.1
    if salient_side is not None:
        scores[inside & (centres @ salient_side > 0.05)] = 0.9
    counts = np.where(np.isnan(scores), 0, 3)
    return SaliencyVolume(grid, scores.reshape(grid.shape), counts.reshape(grid.shape))


def test_view_angles_are_those_of_the_camera_position() -> None:
    eye = np.array([0.0, -0.5, 0.5])  # azimuth -90 deg, elevation 45 deg
    elevation, azimuth = figures.view_angles(look_at(eye, np.zeros(3)))
    assert (elevation, azimuth) == pytest.approx((45.0, -90.0))
    elevation, azimuth = figures.view_angles(look_at(np.array([0.3, 0.3, -0.1]), np.zeros(3)))
    assert azimuth == pytest.approx(45.0)
    assert elevation == pytest.approx(np.degrees(np.arctan2(-0.1, 0.3 * np.sqrt(2))))


def test_the_default_view_faces_the_highest_score() -> None:
    directions = fibonacci_directions(32, hemisphere=True)
    training = fibonacci_directions(20)
    poses = look_at_many(0.6 * training, np.zeros(3))
    scores = np.linspace(0.0, 0.5, 32)
    scores[11] = 1.0
    view = figures.most_salient_view(directions, scores, poses)
    assert view == int(np.argmax(training @ directions[11]))
    # views that do not see the object are never chosen
    pixels = np.full(20, 50)
    pixels[view] = 0
    other = figures.most_salient_view(directions, scores, poses, pixels)
    assert other != view and pixels[other] > 0
    # no viewpoint sees more saliency than another: the view with the most object pixels
    pixels[7] = 400
    assert figures.most_salient_view(directions, np.full(32, 0.5), poses, pixels) == 7


def test_salient_view_angles_point_at_the_salient_part() -> None:
    elevation, azimuth = figures.salient_view_angles(_volume(np.array([0.0, 1.0, 0.0])))
    assert azimuth == pytest.approx(90.0, abs=1.0)
    assert elevation == pytest.approx(10.0)  # the side, seen from the lowest allowed elevation
    side = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)
    elevation, azimuth = figures.salient_view_angles(_volume(side))
    assert azimuth == pytest.approx(0.0, abs=1.0) and elevation == pytest.approx(45.0, abs=3.0)
    # uniformly salient: no side to face, the documented default
    assert figures.salient_view_angles(_volume(None)) == figures.DEFAULT_VIEW_DEG


def _fig1_inputs() -> dict:
    depth = np.zeros((30, 40))
    depth[8:22, 10:30] = np.linspace(0.5, 0.6, 20)
    saliency = np.zeros((30, 40))
    saliency[8:22, 20:30] = 0.8
    directions = fibonacci_directions(16, hemisphere=True)
    return {"depth_m": depth, "saliency": saliency, "volume": _volume(np.array([0, 1.0, 0])),
            "directions": directions, "scores": directions[:, 2], "class_name": "mug",
            "camera_pose": look_at(np.array([0.0, 0.6, 0.2]), np.zeros(3))}


def test_fig1_panels_have_colour_bars_with_units_and_one_camera() -> None:
    fig = figures.fig1_figure(**_fig1_inputs())
    insets = [child for ax in fig.axes for child in ax.child_axes]  # the images' bars
    every = insets + [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    labels = [ax.get_ylabel() for ax in every]
    assert labels == [figures.DEPTH_LABEL, figures.SALIENCY_LABEL, figures.VOXEL_LABEL,
                      figures.SCORE_LABEL]
    assert "(m" in figures.DEPTH_LABEL and "0-1" in figures.SALIENCY_LABEL
    volume_axes = next(ax for ax in fig.axes if ax.name == "3d")
    elevation, azimuth = figures.view_angles(_fig1_inputs()["camera_pose"])
    assert (volume_axes.elev, volume_axes.azim) == pytest.approx((elevation, azimuth))
    assert azimuth == pytest.approx(90.0)
    # the depth colour bar spans the object's depths, not the background's 0
    depth_bar = next(ax for ax in every if ax.get_ylabel() == figures.DEPTH_LABEL)
    assert depth_bar.get_ylim() == pytest.approx((0.5, 0.6))


def test_fig1_and_fig2_write_pngs_and_self_contained_html(tmp_path: Path) -> None:
    png, html = figures.fig1(**_fig1_inputs(), png=tmp_path / "f1.png", html=tmp_path / "f1.html")
    volumes = [_volume(np.array([0, 1.0, 0])), _volume(np.array([1.0, 0, 0]))]
    png2, html2 = figures.fig2(volumes, ["mug vs cup", "all 2 classes"], "mug",
                               tmp_path / "f2.png", tmp_path / "f2.html")
    for path in (png, png2):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for path in (html, html2):
        page = path.read_text()
        assert remote_references(page) == []
        assert not re.search(r"<script[^>]*\bsrc=", page)  # every script is inline
        assert len(page) > 1_000_000  # plotly.js itself is inside
    assert "depth (m)" in html.read_text() and "voxel saliency (0-1)" in html2.read_text()


def test_remote_references_finds_what_a_browser_would_fetch() -> None:
    page = ('<script src="https://cdn.plot.ly/plotly.min.js"></script><a href="fig.html">x</a>'
            '<img src="//host/a.png"><script>var u = "<a href=\\"https://x\\">"</script>'
            '<link href="data:text/css,">')
    assert remote_references(page) == ["https://cdn.plot.ly/plotly.min.js", "//host/a.png"]


# --- calibration.png and its caption ----------------------------------------------------------

def _calibration_evidence() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scores (N, V) of 40 held-out pairs in two halves, right when the score is high, and a
    model's P(correct) for them: 0.2 in the low half, 0.9 in the high one."""
    scores = np.linspace(0.01, 0.99, 40).reshape(4, 10)
    correct = scores > 0.5
    predicted = np.where(correct, 0.9, 0.2)
    return scores, correct, predicted


@pytest.mark.parametrize(("variant", "calibration", "curves"), [
    ("paper", ScoreCalibration("logistic", -2.0, 4.0), 1),
    ("class_area", ClassScoreCalibration(np.array([-1.0, 0.0, 1.0]), 2.0), 4),
    ("transfer", TransferCalibration(), 0),
    ("viewpoint", FixedCorrectness(np.full((3, 10), 0.5), np.zeros(3), np.ones(2)), 0),
])
def test_calibration_figure_and_caption_say_the_same(variant: str, calibration: object,
                                                     curves: int) -> None:
    scores, correct, predicted = _calibration_evidence()
    fig = figures.calibration_plot(scores, correct, calibration, predicted, variant)
    ax = fig.axes[0]
    assert len(ax.lines) == curves  # the map (per class: each class's and their mean) or none
    caption = figures.calibration_caption(variant, calibration.method)
    assert f"RA-POMDP's model (ra_{variant})" in caption and f"ra_{variant}" in ax.get_title()
    if curves:
        assert "fitted score-to-correctness map" in caption and "no curve" not in caption
    else:
        assert "has no map from the score alone" in caption and "no curve is drawn" in caption
        assert "score-to-correctness map" not in caption
    # the model's P(correct) per bin is drawn at the bins' means: 0.2 below 0.5, 0.9 above
    crosses = next(c for c in ax.collections if c.get_label().startswith(f"ra_{variant}:"))
    x, y = np.asarray(crosses.get_offsets()).T
    np.testing.assert_allclose(y, np.where(x < 0.5, 0.2, 0.9))
    accuracy = next(c for c in ax.collections if c.get_label().startswith("held-out"))
    np.testing.assert_allclose(np.asarray(accuracy.get_offsets())[:, 1], (x > 0.5) * 1.0)
    assert ax.get_xlabel() == figures.SCORE_AXES[figures.calibration_score(variant)]


def test_the_transfer_model_is_binned_by_the_salient_area() -> None:
    assert figures.calibration_score("transfer") == "area"
    assert figures.calibration_score("paper") == "mean"
    assert figures.calibration_score("class_area") == "area"


# --- reliability diagrams: the counts shown -------------------------------------------------

def test_reliability_diagram_shows_every_bins_count_and_hollows_small_bins() -> None:
    from rapomdp.recognition.belief import reliability

    confidence = np.concatenate([np.full(341, 0.95), [0.55], [0.35, 0.36]])
    correct = np.concatenate([np.arange(341) < 300, [True], [False, True]])
    curves = {"RA-POMDP": reliability(confidence, correct, 10),
              "Static": reliability(np.full(6, 0.75), np.ones(6, bool), 10)}
    fig = figures.reliability_plot(curves, "confidence", "Final beliefs",
                                   styles={"RA-POMDP": ("#0072B2", "v")})
    top, bottom = fig.axes
    counts = sorted(int(t.get_text()) for t in bottom.texts)
    assert counts == [1, 2, 6, 341]  # every non-empty bin's count written under the diagram
    # the line joins the bins of at least RELIABILITY_MIN_COUNT only: 341 (and Static's 6)
    ra_line, static_line = top.lines[1:]
    np.testing.assert_allclose(ra_line.get_xdata(), [0.95])
    np.testing.assert_allclose(static_line.get_xdata(), [0.75])
    hollow = [c for c in top.collections if len(c.get_offsets())
              and len(c.get_facecolors()) == 0]
    assert sorted(len(c.get_offsets()) for c in hollow) == [2]  # the 1- and 2-outcome bins
    legend = [t.get_text() for t in top.get_legend().get_texts()]
    assert "RA-POMDP (344)" in legend and "Static (6)" in legend
    assert f"hollow: < {figures.RELIABILITY_MIN_COUNT} in the bin" in legend
    # marker area grows with the count
    filled = next(c for c in top.collections if len(c.get_offsets()) == 1
                  and np.allclose(c.get_offsets(), [[0.95, 300 / 341]]))
    small = next(c for c in hollow)
    assert filled.get_sizes()[0] > 5 * small.get_sizes().max()
