"""Fig. 1 and Fig. 2 from a workspace's stages (the ``rapomdp figure`` commands)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from rapomdp.awareness.figures import fig1, fig2, most_salient_view
from rapomdp.awareness.stage import OBSERVATION_FILE, load_saliency
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.config import Config
from rapomdp.data.training_views import load_training_views
from rapomdp.io import load_npz
from rapomdp.workspace import StageError, StageResult, Workspace

FIGURES_DIR = "figures"


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
    volume = SaliencyVolume.load(ws.require("volume") / f"{class_name}.npz")
    out = Path(out_dir) if out_dir is not None else ws.root / FIGURES_DIR
    return fig1(depth[view], maps[view], volume, observe["directions"], observe["scores"][c],
                class_name, out / f"fig1_{class_name}.png", out / f"fig1_{class_name}.html",
                camera_pose=poses[view])


def write_fig2(config: Config, ws: Workspace, target: str, against: Sequence[str],
               epochs: int | None = None,
               on_result: Callable[[StageResult], None] | None = None) -> tuple[Path, Path]:
    """Fig. 2: ``target``'s volume in one two-class problem per opponent (each with its own
    classifier, in ``W/fig2/<target>-vs-<other>``) and in the all-class problem (``W``)."""
    from rapomdp.pipeline import run_pipeline

    volumes, titles = [], []
    for other in against:
        if other == target:
            raise StageError(f"fig2: the opponent '{other}' is the target class itself")
        pair = config.model_copy(deep=True)
        pair.dataset.classes = [target, other]
        if epochs is not None:
            pair.train.epochs = epochs
        sub = Workspace(ws.root / "fig2" / f"{target}-vs-{other}")
        run_pipeline(pair, sub, until="volume", on_result=on_result)
        volumes.append(SaliencyVolume.load(sub.require("volume") / f"{target}.npz"))
        titles.append(f"{target} vs {other}")
    run_pipeline(config, ws, until="volume", on_result=on_result)
    classes = load_training_views(ws.require("render"), ws.require("dataset")).dataset.classes
    if target not in classes:
        raise StageError(f"class '{target}' is not in the workspace's dataset")
    volumes.append(SaliencyVolume.load(ws.require("volume") / f"{target}.npz"))
    titles.append(f"all {len(classes)} classes")
    out = ws.root / FIGURES_DIR
    return fig2(volumes, titles, target, out / "fig2.png", out / "fig2.html")
