"""Supervised pretraining of the depth backbone on the corpus, resumable, and its export.

The network is the pipeline's own :class:`~rapomdp.recognition.network.DepthAlexNet` (the
default width and input), trained to tell the corpus's classes apart from single views, with
the train stage's optimiser (Adam, weight decay, batch 128). ``val_models_per_class`` models
of each class are held out whole, so the validation accuracy is on unseen objects of seen
classes. After every epoch ``checkpoint.pt`` (weights, optimiser, PyTorch's generator) and
``checkpoint.json`` (epoch, history, NumPy's generator, the settings) are written atomically:
a run stopped at any point resumes from its last finished epoch and ends with the same weights
as an uninterrupted run. :func:`export_backbone` writes the convolutions' weights and the model
card (:mod:`rapomdp.recognition.backbone`).

Example:
    >>> from rapomdp.pretrain.training import PretrainSettings
    >>> PretrainSettings().epochs, PretrainSettings().width
    (10, 0.25)
"""

from __future__ import annotations

import io
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from rapomdp.config import PreprocessConfig, TrainConfig
from rapomdp.io import ArtefactError, read_json, write_bytes_atomic, write_json_atomic
from rapomdp.pretrain.views import CorpusViews, ViewSettings
from rapomdp.progress import progress_bar
from rapomdp.recognition.backbone import write_backbone
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.training import evaluate_inputs, network_spec, optimisation_step

CHECKPOINT_WEIGHTS = "checkpoint.pt"
CHECKPOINT_STATE = "checkpoint.json"


@dataclass(frozen=True)
class PretrainSettings:
    """The recipe (recorded in the checkpoint and the model card).

    Attributes:
        width: the network's channel multiplier (the train stage's default).
        dropout: before the linear layer.
        epochs: passes over the training views.
        batch_size, weight_decay: Adam's (the train stage's defaults).
        learning_rate: Adam's: at the train stage's 1e-3 the network's output collapsed to
            the uniform distribution within the first epoch on the 172-class corpus (its loss
            ln 172 throughout); 3e-4 learns (the corpus's own validation, docs/recognition.md).
        val_models_per_class: models of each class held out whole for validation.
        seed: weights, batch order and the validation split.
    """

    width: float = 0.25
    dropout: float = 0.5
    epochs: int = 10
    batch_size: int = 128
    learning_rate: float = 3e-4
    weight_decay: float = 5e-4
    val_models_per_class: int = 2
    seed: int = 0


@dataclass
class PretrainState:
    """What ``checkpoint.json`` holds besides the settings."""

    epoch: int = 0
    seconds: float = 0.0
    history: list[dict[str, float]] = field(default_factory=list)
    rng: dict[str, Any] = field(default_factory=dict)


def network_for(views: CorpusViews, view_settings: ViewSettings,
                settings: PretrainSettings) -> NetworkSpec:
    """The pretrained network's spec: the train stage's (:func:`network_spec`) for the
    corpus's class count and the views' input."""
    cfg = TrainConfig(width=settings.width, dropout=settings.dropout,
                      preprocess=PreprocessConfig(**view_settings.preprocessing.to_dict()))
    spec = network_spec(len(views.classes), cfg)
    assert isinstance(spec, NetworkSpec)  # train.network alexnet
    return spec


def held_out_models(views: CorpusViews, per_class: int, seed: int) -> np.ndarray:
    """True for the views of the models held out for validation: ``per_class`` models of
    each class with more than ``per_class`` models, drawn from ``seed``."""
    rng = np.random.default_rng([seed, 17])
    model_class = np.zeros(int(views.models.max()) + 1, dtype=np.int64)
    model_class[views.models] = views.labels
    held = np.zeros(model_class.shape[0], dtype=bool)
    for label in range(len(views.classes)):
        members = np.flatnonzero(model_class == label)
        if len(members) > per_class:
            held[rng.choice(members, per_class, replace=False)] = True
    return held[views.models]


def _save(out: Path, network: nn.Module, optimiser: torch.optim.Optimizer,
          state: PretrainState, settings: PretrainSettings, digest: str) -> None:
    buffer = io.BytesIO()
    torch.save({"network": network.state_dict(), "optimiser": optimiser.state_dict(),
                "torch_rng": torch.get_rng_state()}, buffer)
    write_bytes_atomic(out / CHECKPOINT_WEIGHTS, buffer.getvalue())
    write_json_atomic(out / CHECKPOINT_STATE, {"settings": asdict(settings), "views": digest,
                                               **asdict(state)})


def _resume(out: Path, settings: PretrainSettings, digest: str) -> tuple[PretrainState,
                                                                          dict[str, Any] | None]:
    path = out / CHECKPOINT_STATE
    if not path.is_file():
        return PretrainState(), None
    stored = read_json(path)
    # the epochs may change: a run is extended (or ended) where it stands, the learning rate
    # being constant
    recipe = {k: v for k, v in asdict(settings).items() if k != "epochs"}
    if ({k: v for k, v in dict(stored.get("settings") or {}).items() if k != "epochs"}
            != recipe or stored.get("views") != digest):
        raise ArtefactError(
            f"{path}: a checkpoint of other settings or another corpus (stored "
            f"{stored.get('settings')}, views {stored.get('views')}); resume with the same "
            "settings, or start again with --restart")
    weights = torch.load(out / CHECKPOINT_WEIGHTS, map_location="cpu", weights_only=True)
    state = PretrainState(int(stored["epoch"]), float(stored["seconds"]),
                          list(stored["history"]), dict(stored["rng"]))
    return state, weights


def pretrain(views: CorpusViews, view_settings: ViewSettings, out: Path,
             settings: PretrainSettings, device: torch.device, digest: str,
             progress: bool = True, stop_after: int | None = None,
             log: Callable[[str], None] | None = None) -> tuple[DepthAlexNet, PretrainState]:
    """Train (or resume training) the backbone's network on the corpus views.

    Args:
        views: the corpus's inputs.
        view_settings: how they were made (the network's input).
        out: the pretraining folder (the checkpoint is read from and written to it).
        settings: the recipe; a checkpoint of another recipe is refused.
        device: where to train.
        digest: the views' :func:`~rapomdp.pretrain.views.settings_digest`.
        progress: a progress bar.
        stop_after: stop after this many epochs of this call (a partial run; resumable).
        log: called with one line per epoch.

    Returns:
        The network (in eval mode) and the state after the last epoch run.
    """
    spec = network_for(views, view_settings, settings)
    held = held_out_models(views, settings.val_models_per_class, settings.seed)
    train_index = np.flatnonzero(~held)
    val_inputs = views.inputs[held].astype(np.float32)
    val_labels = views.labels[held]
    torch.manual_seed(settings.seed)
    network = DepthAlexNet(spec).to(device)
    optimiser = torch.optim.Adam(network.parameters(), lr=settings.learning_rate,
                                 weight_decay=settings.weight_decay)
    state, weights = _resume(out, settings, digest)
    rng = np.random.default_rng(settings.seed)
    if weights is not None:
        network.load_state_dict(weights["network"])
        optimiser.load_state_dict(weights["optimiser"])
        torch.set_rng_state(weights["torch_rng"])
        rng.bit_generator.state = state.rng
    batches = -(-len(train_index) // settings.batch_size)
    remaining = max(0, settings.epochs - state.epoch)
    if stop_after is not None:
        remaining = min(remaining, stop_after)
    with progress_bar(progress, status=True) as bar:
        task = bar.add_task("pretrain", total=remaining * batches, status="", unit="batches")
        for _ in range(remaining):
            start = time.perf_counter()
            network.train()
            order = train_index[rng.permutation(len(train_index))]
            loss_sum, correct = 0.0, 0
            for b in range(batches):
                idx = np.sort(order[b * settings.batch_size:(b + 1) * settings.batch_size])
                batch_loss, batch_correct = optimisation_step(
                    network, optimiser,
                    torch.from_numpy(views.inputs[idx].astype(np.float32)).to(device),
                    torch.from_numpy(views.labels[idx]).to(device))
                loss_sum += batch_loss
                correct += batch_correct
                seen = min((b + 1) * settings.batch_size, len(train_index))
                bar.update(task, advance=1, description=f"pretrain {state.epoch + 1}/"
                           f"{settings.epochs}", status=f"loss {loss_sum / seen:.3f}")
            val_loss, val_accuracy = evaluate_inputs(network, val_inputs, val_labels, device)
            state.epoch += 1
            state.seconds += time.perf_counter() - start
            state.history.append({"epoch": state.epoch,
                                  "train_loss": loss_sum / len(train_index),
                                  "train_accuracy": correct / len(train_index),
                                  "val_loss": val_loss, "val_accuracy": val_accuracy,
                                  "seconds": state.seconds})
            state.rng = json.loads(json.dumps(rng.bit_generator.state))
            _save(out, network, optimiser, state, settings, digest)
            if log is not None:
                row = state.history[-1]
                log(f"epoch {state.epoch}/{settings.epochs}: train {row['train_accuracy']:.3f}"
                    f" val (unseen objects) {row['val_accuracy']:.3f} ({state.seconds:.0f} s)")
    network.eval()
    return network, state


def export_backbone(network: DepthAlexNet, state: PretrainState, settings: PretrainSettings,
                    view_settings: ViewSettings, corpus_source: dict[str, Any],
                    views: CorpusViews, device: torch.device, path: Path) -> Path:
    """Write the backbone (the convolutions' weights) and its model card.

    Args:
        network: the pretrained network.
        state: its training record.
        settings: the recipe.
        view_settings: how the corpus was seen.
        corpus_source: the corpus's ``SOURCE.json``.
        views: the corpus views (counts for the card).
        device: where it was trained.
        path: the weights file (``.pt``); the card is written beside it (``.json``).

    Returns:
        The weights file.
    """
    features = {k: v for k, v in network.state_dict().items() if k.startswith("features.")}
    card = {
        "corpus": {"classes": len(views.classes), "models": len(views.model_names),
                   "views": int(views.labels.shape[0]),
                   "sources": [{k: s[k] for k in ("name", "models", "licence", "origin")}
                               | {"classes": len(s["classes"])}
                               for s in corpus_source.get("sources", [])]},
        "recipe": {"objective": "supervised: the corpus classes from single views",
                   **asdict(settings), "epochs": state.epoch,
                   "view_settings": asdict(view_settings)},
        "epochs": state.epoch,
        "seconds": round(state.seconds, 1),
        "device": str(device),
        "threads": torch.get_num_threads(),
        "validation_accuracy_unseen_objects": state.history[-1]["val_accuracy"]
        if state.history else None,
        "history": state.history,
    }
    return write_backbone(path, features, network.spec, view_settings.preprocessing, card)

