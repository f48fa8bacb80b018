"""Fig. 1 from a workspace's stages (``rapomdp figure fig1``; Fig. 2, which runs pipelines of
its own, is :func:`rapomdp.pipeline.write_fig2`), and the report's self-awareness figures
(predicted against observed P(correct) on the test models; one class's predicted and actual
per-viewpoint accuracy)."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.awareness.artefacts import (
    OBSERVATION_FILE,
    load_declared_confidence,
    volume_file,
)
from rapomdp.awareness.figures import (
    fig1,
    hemisphere_pair_figure,
    most_salient_view,
    reliability_figure,
)
from rapomdp.awareness.stage import load_saliency
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.belief import temper
from rapomdp.data.training_views import load_training_views
from rapomdp.io import atomic_path, load_npz
from rapomdp.recognition.belief import reliability
from rapomdp.workspace import StageError, Workspace

FIGURES_DIR = "figures"
AWARENESS_RELIABILITY = "awareness_reliability"
#: The columns of a reliability diagram's data (``<figure>.csv`` beside its PNG).
RELIABILITY_COLUMNS = ("curve", "bin", "bin_low", "bin_high", "mean_predicted", "observed",
                       "count")


def write_fig1(ws: Workspace, class_name: str | None = None, view: int | None = None,
               out_dir: Path | None = None) -> tuple[Path, Path]:
    """Fig. 1 of ``class_name`` (default: the first class) from workspace ``ws``, written as
    ``fig1_<class>.png|html`` into ``out_dir`` (default ``W/figures``).

    ``view`` is the volume model's training view shown in (a)-(c); by default the one nearest
    to the test viewpoint of highest score (:func:`~rapomdp.awareness.figures.most_salient_view`:
    the side of the object where the class's saliency is)."""
    views = load_training_views(ws.require("render"), ws.require("dataset"))
    dataset = views.dataset
    class_name = class_name or dataset.classes[0]
    if class_name not in dataset.classes:
        raise StageError(f"class '{class_name}' is not in the dataset; classes are: "
                         f"{', '.join(dataset.classes)}")
    model = next(m for m in dataset.with_role("volume") if m.class_name == class_name)
    depth, poses = views.load(model)
    maps = load_saliency(ws.require("saliency"), model)["saliency"].astype(np.float32)
    observe = load_npz(ws.require("observe") / OBSERVATION_FILE)
    c = dataset.classes.index(class_name)
    if view is None:
        view = most_salient_view(observe["directions"], observe["scores"][c], poses,
                                 object_pixels=(depth > 0).sum(axis=(1, 2)))
    if not 0 <= view < depth.shape[0]:
        raise StageError(f"view {view} is out of range: the model has {depth.shape[0]} views")
    volume = SaliencyVolume.load(ws.require("volume") / volume_file(class_name))
    out = Path(out_dir) if out_dir is not None else ws.root / FIGURES_DIR
    return fig1(depth[view], maps[view], volume, observe["directions"], observe["scores"][c],
                class_name, out / f"fig1_{class_name}.png", out / f"fig1_{class_name}.html",
                camera_pose=poses[view])


def reliability_rows(curves: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
                     ) -> list[dict[str, str | int | float]]:
    """A reliability diagram's data, one row per (curve, bin) of equal-width bins on [0, 1]:
    the mean predicted value, the observed accuracy (NaN when empty) and the count of outcomes
    the bin holds (``curves[name] = (mean predicted, observed, count)``, as
    :func:`rapomdp.recognition.belief.reliability` returns them)."""
    rows: list[dict[str, str | int | float]] = []
    for name, (predicted, observed, count) in curves.items():
        bins = len(count)
        rows += [{"curve": name, "bin": b, "bin_low": b / bins, "bin_high": (b + 1) / bins,
                  "mean_predicted": float(predicted[b]), "observed": float(observed[b]),
                  "count": int(count[b])} for b in range(bins)]
    return rows


def write_reliability_csv(curves: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                          path: Path) -> Path:
    """:func:`reliability_rows` as CSV (atomically); returns the path."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(RELIABILITY_COLUMNS))
        writer.writeheader()
        writer.writerows(reliability_rows(curves))
    return Path(path)


DECLARED_MODELS = ("ra", "classifier", "vptree")
"""The models whose declared confidence the report shows: the methods' (RA-POMDP, the
Classifier POMDP and Random, the VP-tree)."""


def declared_confidence_cells(observe_dir: Path, vptree_dir: Path | None = None
                              ) -> tuple[list[str], list[list[str]]]:
    """The declared confidence's held-out record (``calibration.json`` / ``vptree.json:
    declared_confidence``): per model, a and, at the stops of the held-out walks, the accuracy
    and the confidence and ECE of the belief and of the declared belief (each group by the
    others' a). No rows for a workspace from before it or without two held-out groups."""
    records = load_declared_confidence(observe_dir, vptree_dir)
    header = ["Model", "a", "Accuracy at the stops", "Belief: confidence", "ECE",
              "Declared (held out): confidence", "ECE", "ECE if calibrated (95 %)"]
    rows = []
    for name in DECLARED_MODELS:
        r = records.get(name)
        if not r or not r.get("groups"):
            continue
        rows.append([name, f"{r['temperature']:.3f}", f"{r['accuracy']:.3f}",
                     f"{r['confidence']:.3f}", f"{r['ece']:.3f}",
                     f"{r['declared_confidence']:.3f}", f"{r['declared_ece']:.3f}",
                     floor_cell(r)])
    return header, rows


def floor_cell(record: dict[str, Any]) -> str:
    """A declared-confidence record's ``declared_ece_if_calibrated`` as a cell ("—" for a
    record from before it)."""
    floor = record.get("declared_ece_if_calibrated")
    return "—" if floor is None or not np.isfinite(floor) else f"{floor:.3f}"


def single_view_models(observe: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The observe stage's models before the belief's temperature (the single-view models the
    quality table scores): tempering by t is undone by tempering by 1 / t."""
    names = [str(n) for n in observe["models"]]
    temperatures = observe["temperatures"] if "temperatures" in observe else np.ones(len(names))
    return {n: temper(observe[n], 1.0 / float(t))
            for n, t in zip(names, temperatures, strict=True)}


def identical_models(observe: dict[str, np.ndarray], atol: float = 1e-9) -> list[list[str]]:
    """The groups (two or more names, in the artefact's order) of the observe stage's models
    whose single-view P(o | c, x) (:func:`single_view_models`) are equal everywhere within
    ``atol``: ``ra`` and the variant it is, and any variants whose fits coincide. Their rows
    in the quality tables are then equal too."""
    single = single_view_models(observe)
    groups: list[list[str]] = []
    for name, model in single.items():
        for group in groups:
            first = single[group[0]]
            if first.shape == model.shape and np.allclose(first, model, rtol=0.0, atol=atol):
                group.append(name)
                break
        else:
            groups.append([name])
    return [g for g in groups if len(g) > 1]


def write_awareness_figures(observe_dir: Path, class_name: str, out_dir: Path,
                            models: Sequence[str] = ("ra", "classifier", "blackbox")
                            ) -> tuple[Path, Path]:
    """``awareness_reliability.png`` (predicted against observed P(correct) on the test
    models, per model; its bins and counts in ``awareness_reliability.csv``) and
    ``awareness_hemisphere_<class>.png`` (the RA and Classifier models' predicted
    per-viewpoint accuracy of ``class_name`` beside the test models' actual one)."""
    observe = load_npz(Path(observe_dir) / OBSERVATION_FILE)
    classes = [str(c) for c in observe["classes"]]
    if class_name not in classes:
        raise StageError(f"class '{class_name}' is not in the observe stage's classes")
    single = single_view_models(observe)
    labels, predicted = observe["test_labels"], observe["test_predictions"]
    correct = predicted == labels[:, None]
    curves = {}
    for name in (m for m in models if m in single):
        p_correct = np.diagonal(single[name], axis1=1, axis2=2)  # (V, C)
        curves[name] = reliability(p_correct.T[labels], correct, 10)
    out = Path(out_dir)
    rel = reliability_figure(curves, out / f"{AWARENESS_RELIABILITY}.png")
    write_reliability_csv(curves, out / f"{AWARENESS_RELIABILITY}.csv")
    c = classes.index(class_name)
    mine = labels == c
    actual = correct[mine].mean(axis=0) if mine.any() else np.full(correct.shape[1], np.nan)
    shown = [m for m in ("ra", "classifier") if m in single]
    values = [np.diagonal(single[m], axis1=1, axis2=2)[:, c] for m in shown] + [actual]
    titles = [f"{m}: predicted P(correct)" for m in shown] + [
        f"actual accuracy ({int(mine.sum())} test model(s))"]
    hemi = hemisphere_pair_figure(observe["directions"], values, titles,
                                  f"class {class_name}: predicted and actual accuracy per "
                                  f"viewpoint of X_rho (seen from above)",
                                  out / f"awareness_hemisphere_{class_name}.png")
    return rel, hemi
