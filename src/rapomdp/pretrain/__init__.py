"""Pretraining the depth backbone: the corpus, its views, the supervised run, the export.

``rapomdp pretrain`` runs :func:`run_pretrain`: it builds the corpus (:mod:`.corpus`) unless
``WORKDIR/corpus`` holds one, renders and preprocesses it (:mod:`.views`), trains the network
on it with a checkpoint after every epoch (:mod:`.training`; a stopped run resumes) and writes
the backbone and its card (:mod:`rapomdp.recognition.backbone`). This package comes after the
recognition stage: it imports the data and recognition packages, and no stage imports it.

Example:
    >>> from rapomdp.pretrain import DEFAULT_WORKDIR
    >>> str(DEFAULT_WORKDIR)
    'runs/pretrain'
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rapomdp.io import read_json
from rapomdp.pretrain.corpus import build_corpus
from rapomdp.pretrain.training import (
    CHECKPOINT_STATE,
    CHECKPOINT_WEIGHTS,
    PretrainSettings,
    PretrainState,
    export_backbone,
    pretrain,
)
from rapomdp.pretrain.views import ViewSettings, render_corpus, settings_digest
from rapomdp.recognition.classifier import configure_torch

DEFAULT_WORKDIR = Path("runs/pretrain")


@dataclass(frozen=True)
class CorpusSettings:
    """What :func:`~rapomdp.pretrain.corpus.build_corpus` is asked for (its defaults)."""

    families: int = 160
    models_per_family: int = 20
    kicad: bool = True
    max_per_class: int = 24
    deb: Path | None = None
    extra: tuple[Path, ...] = ()


def run_pretrain(workdir: Path = DEFAULT_WORKDIR, export: Path | None = None,
                 corpus: CorpusSettings = CorpusSettings(),
                 views: ViewSettings = ViewSettings(),
                 settings: PretrainSettings = PretrainSettings(), workers: int = 1,
                 threads: int | None = None, device: str = "auto", restart: bool = False,
                 stop_after: int | None = None, progress: bool = True,
                 log: Callable[[str], None] = print) -> tuple[Path | None, PretrainState]:
    """Build, render, train (or resume) and export, each step kept when already done.

    Args:
        workdir: the pretraining folder (``corpus/``, ``views.npz``, the checkpoint).
        export: the backbone's weights file (default ``WORKDIR/depth-backbone.pt``); written
            once every epoch has run.
        corpus: the corpus to build when ``WORKDIR/corpus`` has none.
        views: how the corpus is seen.
        settings: the recipe.
        workers: processes rendering the corpus.
        threads: PyTorch's CPU threads (None: half the cores).
        device: ``auto`` (CUDA when available), ``cpu`` or ``cuda``.
        restart: forget the checkpoint and train from the first epoch.
        stop_after: stop after this many epochs (resumable); nothing is exported unless
            every epoch has run.
        progress: progress bars.
        log: called with a line as each step is done.

    Returns:
        The backbone's weights file (None when stopped early) and the training record.
    """
    corpus_dir = workdir / "corpus"
    if not (corpus_dir / "SOURCE.json").is_file():
        build = build_corpus(corpus_dir, families=corpus.families,
                             models_per_family=corpus.models_per_family, kicad=corpus.kicad,
                             max_per_class=corpus.max_per_class, deb=corpus.deb,
                             extra=corpus.extra, progress=log)
        log(build.summary())
    if restart:
        for name in (CHECKPOINT_STATE, CHECKPOINT_WEIGHTS):
            (workdir / name).unlink(missing_ok=True)
    corpus_views = render_corpus(corpus_dir, workdir, views, workers, progress)
    log(f"corpus views: {corpus_views.labels.shape[0]} of {len(corpus_views.model_names)} "
        f"models, {len(corpus_views.classes)} classes")
    torch_device = configure_torch(device, threads)
    network, state = pretrain(corpus_views, views, workdir, settings, torch_device,
                              settings_digest(corpus_dir, views), progress, stop_after, log)
    if state.epoch < settings.epochs:
        log(f"stopped after epoch {state.epoch} of {settings.epochs}: run the same command "
            "again to resume")
        return None, state
    target = export if export is not None else workdir / "depth-backbone.pt"
    export_backbone(network, state, settings, views, read_json(corpus_dir / "SOURCE.json"),
                    corpus_views, torch_device, target)
    log(f"backbone: {target} (and its card {target.with_suffix('.json').name})")
    return target, state


__all__ = ["DEFAULT_WORKDIR", "CorpusSettings", "PretrainSettings", "ViewSettings",
           "run_pretrain"]
