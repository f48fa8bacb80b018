"""The trained depth classifier as a library object, and its checkpoint.

A checkpoint is two files side by side: ``classifier.pt``, the network's state dict written with
``torch.save`` and read with ``torch.load(..., weights_only=True)``, and ``classifier.json``, the
metadata: class list, preprocessing parameters, network spec (a user's recogniser's: its
import path, ``kind: custom``, whose factory is imported again on load), camera focal
lengths, the configuration hash and the SHA-256 of the weights file.
:meth:`Classifier.load` checks the metadata against what the caller expects and refuses a
mismatch with :class:`CheckpointMismatchError`, naming the file and the field.
"""

from __future__ import annotations

import hashlib
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rapomdp.io import ArtefactError, read_json, write_bytes_atomic, write_json_atomic
from rapomdp.recognition.custom import RecogniserError
from rapomdp.recognition.network import Network, build_network, spec_from_record
from rapomdp.recognition.preprocess import Preprocessed, PreprocessParams, preprocess

WEIGHTS_FILE = "classifier.pt"
META_FILE = "classifier.json"
FORMAT = "rapomdp-depth-classifier/1"
THREADS_ENV = "RAPOMDP_THREADS"


class CheckpointError(ArtefactError):
    """A classifier checkpoint is missing, unreadable or corrupt (the file is named)."""


class CheckpointMismatchError(CheckpointError):
    """A checkpoint was made for other classes, preprocessing or configuration."""


def default_threads() -> int:
    """Threads for PyTorch on the CPU: ``RAPOMDP_THREADS``, else half the usable cores.

    Half, not all: on a small shared machine a busy core makes PyTorch's worker threads wait on
    each other (on 2 busy cores, 2 threads trained 2.7x and predicted 12x slower than 1; see
    docs/recognition.md), and these small convolutions gain little from more threads.
    """
    value = os.environ.get(THREADS_ENV)
    if value:
        try:
            threads = int(value)
        except ValueError:
            raise ValueError(f"{THREADS_ENV}={value!r} is not an integer") from None
        if threads < 1:
            raise ValueError(f"{THREADS_ENV}={value!r} must be at least 1")
        return threads
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, (cores or 1) // 2)


def select_device(device: str = "auto") -> torch.device:
    """``auto``: CUDA when available, else the CPU; ``cuda`` fails clearly without CUDA."""
    if device == "cuda" and not torch.cuda.is_available():
        raise RuntimeError("device 'cuda' was asked for, but CUDA is not available here")
    use_cuda = device == "cuda" or (device == "auto" and torch.cuda.is_available())
    return torch.device("cuda" if use_cuda else "cpu")


def configure_torch(device: str = "auto", threads: int | None = None) -> torch.device:
    """Set PyTorch's CPU thread count (``threads`` or :func:`default_threads`); the device."""
    torch.set_num_threads(threads or default_threads())
    return select_device(device)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _resolve(path: str | Path) -> tuple[Path, Path]:
    """The weights and metadata files of a checkpoint given as a folder or either file."""
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    stem = path.stem if not path.is_dir() else Path(WEIGHTS_FILE).stem
    return folder / f"{stem}.pt", folder / f"{stem}.json"


class Classifier:
    """A depth classifier: raw depth images in, class probabilities out.

    ``fx_px``, ``fy_px`` are the focal lengths of the camera the images come from (preprocessing
    sizes the crop in metres); the training camera's are stored and used by default.
    """

    def __init__(
        self,
        network: Network,
        classes: Sequence[str],
        preprocessing: PreprocessParams,
        fx_px: float,
        fy_px: float,
        device: torch.device | str = "cpu",
        meta: dict[str, Any] | None = None,
    ) -> None:
        if network.spec.classes != len(classes):
            raise ValueError(
                f"network has {network.spec.classes} outputs but {len(classes)} classes were given"
            )
        if network.spec.input_size_px != preprocessing.input_size_px:
            raise ValueError("network and preprocessing disagree on the input size")
        self.device = torch.device(device)
        self.network = network.to(self.device).eval()
        self.classes = list(classes)
        self.preprocessing = preprocessing
        self.fx_px, self.fy_px = float(fx_px), float(fy_px)
        self.meta = dict(meta or {})

    # -- inference -------------------------------------------------------------------------

    def preprocess(
        self, depth_images: np.ndarray, fx_px: float | None = None, fy_px: float | None = None
    ) -> Preprocessed:
        """The network inputs for depth images, exactly as in training (no augmentation)."""
        return preprocess(
            depth_images, fx_px or self.fx_px, fy_px or self.fy_px, self.preprocessing
        )

    def logits_of_inputs(self, inputs: torch.Tensor | np.ndarray) -> torch.Tensor:
        """Logits (n, C) of preprocessed inputs (n, 1, S, S), with gradients if they need them."""
        x = torch.as_tensor(inputs, dtype=torch.float32, device=self.device)
        return self.network(x)

    def predict_inputs(self, inputs: np.ndarray, batch_size: int = 512) -> np.ndarray:
        """Class probabilities (n, C) of preprocessed inputs (n, 1, S, S)."""
        inputs = np.asarray(inputs, dtype=np.float32)
        out = np.empty((inputs.shape[0], len(self.classes)), dtype=np.float32)
        with torch.inference_mode():
            for start in range(0, inputs.shape[0], batch_size):
                batch = torch.from_numpy(inputs[start : start + batch_size]).to(self.device)
                out[start : start + batch_size] = (
                    torch.softmax(self.network(batch), dim=1).cpu().numpy()
                )
        return out

    def predict(
        self,
        depth_images: np.ndarray,
        batch_size: int = 512,
        fx_px: float | None = None,
        fy_px: float | None = None,
    ) -> np.ndarray:
        """Class probabilities (n, C) for depth images (n, H, W) in metres (0 = background).

        One image (H, W) gives (1, C). Columns follow :attr:`classes`.
        """
        depth = np.asarray(depth_images, dtype=np.float32)
        if depth.ndim == 2:
            depth = depth[None]
        out = np.empty((depth.shape[0], len(self.classes)), dtype=np.float32)
        # preprocess in chunks so a big batch never holds every full-size image's copies
        for start in range(0, depth.shape[0], batch_size):
            inputs = self.preprocess(depth[start : start + batch_size], fx_px, fy_px).images
            out[start : start + batch_size] = self.predict_inputs(inputs, batch_size)
        return out

    # -- checkpoint ------------------------------------------------------------------------

    def save(self, path: str | Path, config_hash: str, extra: dict[str, Any] | None = None) -> Path:
        """Write ``classifier.pt`` and ``classifier.json`` into folder ``path``, atomically."""
        weights_path, meta_path = _resolve(Path(path) / WEIGHTS_FILE)
        buffer = io.BytesIO()
        state = {k: v.detach().cpu() for k, v in self.network.state_dict().items()}
        torch.save(state, buffer)
        data = buffer.getvalue()
        write_bytes_atomic(weights_path, data)
        meta = {
            "format": FORMAT,
            "classes": self.classes,
            "preprocessing": self.preprocessing.to_dict(),
            "network": self.network.spec.to_dict(),
            "camera": {"fx_px": self.fx_px, "fy_px": self.fy_px},
            "config_hash": config_hash,
            "weights_sha256": _sha256(data),
            **(extra or {}),
        }
        write_json_atomic(meta_path, meta)
        self.meta = meta
        return weights_path

    @classmethod
    def load(
        cls,
        path: str | Path,
        classes: Sequence[str] | None = None,
        preprocessing: PreprocessParams | None = None,
        config_hash: str | None = None,
        device: str = "auto",
        threads: int | None = None,
    ) -> Classifier:
        """Load a checkpoint (its folder, or its ``.pt`` or ``.json`` file).

        ``classes``, ``preprocessing`` and ``config_hash``, when given, must match the
        checkpoint's, or :class:`CheckpointMismatchError` names the file and the difference.
        PyTorch's thread count is left alone unless ``threads`` is given.
        """
        weights_path, meta_path = _resolve(path)
        meta = read_json(meta_path) if meta_path.exists() else None
        if meta is None:
            raise CheckpointError(f"{meta_path}: checkpoint metadata not found")
        if meta.get("format") != FORMAT:
            raise CheckpointError(
                f"{meta_path}: not a rapomdp classifier checkpoint (format {meta.get('format')!r})"
            )
        _check(meta_path, "class list", meta["classes"], None if classes is None else list(classes))
        _check(
            meta_path, "preprocessing parameters", meta["preprocessing"],
            None if preprocessing is None else preprocessing.to_dict(),
        )
        _check(meta_path, "configuration hash", meta["config_hash"], config_hash)
        try:
            data = weights_path.read_bytes()
        except OSError as exc:
            raise CheckpointError(f"{weights_path}: cannot read weights ({exc.strerror})") from None
        if _sha256(data) != meta["weights_sha256"]:
            raise CheckpointError(
                f"{weights_path}: weights do not match the SHA-256 recorded in {meta_path.name} "
                "(a partial copy, or weights from another run)"
            )
        torch_device = configure_torch(device, threads) if threads else select_device(device)
        try:
            state = torch.load(io.BytesIO(data), map_location=torch_device, weights_only=True)
            spec = spec_from_record(meta["network"])
            network = build_network(spec)
            network.load_state_dict(state)
        except RecogniserError as exc:  # the user's recogniser, named by the record
            raise CheckpointError(f"{meta_path}: cannot rebuild the recogniser the checkpoint "
                                  f"names: {exc}") from exc
        except Exception as exc:  # any unpickling or shape error is a bad checkpoint
            raise CheckpointError(f"{weights_path}: cannot load weights ({exc})") from exc
        return cls(
            network,
            meta["classes"],
            PreprocessParams(**meta["preprocessing"]),
            meta["camera"]["fx_px"],
            meta["camera"]["fy_px"],
            torch_device,
            meta,
        )


def _retrain_hint(path: Path) -> str:
    """A command that really redoes the training (plain ``rapomdp train`` keeps a cached one)."""
    where = path.parent.parent if path.parent.name == "train" else "WORKSPACE"
    return f"Retrain with `rapomdp train -w {where} --force`."


def _check(path: Path, what: str, stored: Any, expected: Any) -> None:
    if expected is None or stored == expected:
        return
    if isinstance(stored, list) and isinstance(expected, list):
        missing = [c for c in expected if c not in stored]
        extra = [c for c in stored if c not in expected]
        detail = (f"missing {missing}, unexpected {extra}" if missing or extra
                  else "same classes in another order")
        raise CheckpointMismatchError(
            f"{path}: the checkpoint's {what} does not match ({detail}); "
            f"checkpoint has {stored}, expected {expected}. {_retrain_hint(path)}"
        )
    raise CheckpointMismatchError(
        f"{path}: the checkpoint's {what} does not match: checkpoint has {stored}, "
        f"expected {expected}. {_retrain_hint(path)}"
    )
