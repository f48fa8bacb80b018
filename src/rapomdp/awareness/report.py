"""Fig. 1 from a workspace's stages (``rapomdp figure fig1``); Fig. 2, which runs pipelines of
its own, is :func:`rapomdp.pipeline.write_fig2`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import OBSERVATION_FILE, volume_file
from rapomdp.awareness.figures import fig1
from rapomdp.awareness.stage import load_saliency
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.data.training_views import load_training_views
from rapomdp.io import load_npz
from rapomdp.workspace import StageError, Workspace

FIGURES_DIR = "figures"


def write_fig1(ws: Workspace, class_name: str | None = None, view: int | None = None,
               out_dir: Path | None = None) -> tuple[Path, Path]:
    """Fig. 1 of ``class_name`` (default: the first class) from workspace ``ws``, written as
    ``fig1_<class>.png|html`` into ``out_dir`` (default ``W/figures``)."""
    views = load_training_views(ws.require("render"), ws.require("dataset"))
    dataset = views.dataset
    class_name = class_name or dataset.classes[0]
    if class_name not in dataset.classes:
        raise StageError(f"class '{class_name}' is not in the dataset; classes are: "
                         f"{', '.join(dataset.classes)}")
    model = next(m for m in dataset.with_role("volume") if m.class_name == class_name)
    depth, _ = views.load(model)
    maps = load_saliency(ws.require("saliency"), model)["saliency"].astype(np.float32)
    if view is None:
        view = int(np.argmax((depth > 0).sum(axis=(1, 2))))
    if not 0 <= view < depth.shape[0]:
        raise StageError(f"view {view} is out of range: the model has {depth.shape[0]} views")
    volume = SaliencyVolume.load(ws.require("volume") / volume_file(class_name))
    observe = load_npz(ws.require("observe") / OBSERVATION_FILE)
    c = dataset.classes.index(class_name)
    out = Path(out_dir) if out_dir is not None else ws.root / FIGURES_DIR
    return fig1(depth[view], maps[view], volume, observe["directions"], observe["scores"][c],
                class_name, out / f"fig1_{class_name}.png", out / f"fig1_{class_name}.html")
