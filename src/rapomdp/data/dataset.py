"""The dataset stage: normalised meshes of every class and their train / volume / test roles.

Output (``W/dataset/``): ``dataset.json`` (classes, models, roles, sources; the split's rule,
its role counts per class, the classes left out, and ``held_out_groups``: the fewest volume
models of any class, i.e. how many complete groups of held-out evidence the observe stage's
leave-one-group-out choices have) and ``meshes/<class>/<model>.npz`` (vertices in metres,
faces), normalised by :func:`rapomdp.data.meshes.normalise_mesh`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.layouts import LAYOUT_UP_AXIS, DatasetLayoutError, folder_models
from rapomdp.data.meshes import MeshLoadError, centroid, load_mesh, normalise_mesh
from rapomdp.data.procedural import PROCEDURAL_CLASSES, generate_model
from rapomdp.data.splits import AUTO_FULL_MODELS, ROLES, split_models
from rapomdp.io import (
    ArtefactError,
    check_plain_name,
    load_npz,
    plain_name,
    read_json,
    save_npz,
    stable_hash,
    write_json_atomic,
)
from rapomdp.progress import track
from rapomdp.workspace import StageInputs

DATASET_FILE = "dataset.json"


@dataclass(frozen=True)
class ModelEntry:
    """One normalised model of the dataset."""

    id: str
    class_name: str
    role: str
    source: str
    file: str
    height_m: float
    faces: int

    @property
    def centroid(self) -> np.ndarray:
        """The bounding-box centre: on the z axis at half the model's height."""
        return np.array([0.0, 0.0, self.height_m / 2.0])


def class_ranks(models: Sequence[ModelEntry]) -> np.ndarray:
    """Each model's rank among the models of its class before it in ``models`` (M,): a volume
    model's held-out group (the k-th volume model of every class is group k, so a group holds
    one model of each class)."""
    seen: dict[str, int] = {}
    ranks = np.empty(len(models), dtype=np.int64)
    for i, model in enumerate(models):
        ranks[i] = seen.get(model.class_name, 0)
        seen[model.class_name] = int(ranks[i]) + 1
    return ranks


@dataclass
class Dataset:
    """The dataset stage's output, read back."""

    root: Path
    classes: list[str]
    models: list[ModelEntry]

    def with_role(self, role: str) -> list[ModelEntry]:
        if role not in ROLES:
            raise ValueError(f"unknown role '{role}'; roles are: {', '.join(ROLES)}")
        return [m for m in self.models if m.role == role]

    def role_counts(self) -> dict[str, dict[str, int]]:
        """Each class's number of models per role."""
        counts = {c: dict.fromkeys(ROLES, 0) for c in self.classes}
        for model in self.models:
            counts[model.class_name][model.role] += 1
        return counts

    @property
    def held_out_groups(self) -> int:
        """The fewest volume models of any class: how many groups of held-out evidence (the
        k-th volume model of every class is group k, :func:`class_ranks`) hold every class.
        Below 2, a leave-one-group-out choice has no held-out group to score on."""
        return min((c["volume"] for c in self.role_counts().values()), default=0)

    def label(self, model: ModelEntry) -> int:
        return self.classes.index(model.class_name)

    def mesh(self, model: ModelEntry) -> trimesh.Trimesh:
        arrays = load_npz(self.root / model.file)
        return trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)


def _file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes (read in blocks)."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def duplicate_line(stage_dir: str | Path) -> str | None:
    """One warning line when models of different roles are the same file content (a test model
    that is a training model is not unseen), else None."""
    duplicates = read_json(Path(stage_dir) / DATASET_FILE).get("duplicates") or []
    if not duplicates:
        return None
    shown = "; ".join(duplicates[:3]) + (f"; and {len(duplicates) - 3} more"
                                         if len(duplicates) > 3 else "")
    return (f"{len(duplicates)} model file(s) have the same bytes as a model of another role "
            f"(the split is not held out): {shown}")


def warning_lines(stage_dir: str | Path) -> list[str]:
    """The dataset's warnings, one line each: classes left out for too few models, model files
    shared between roles."""
    dropped = read_json(Path(stage_dir) / DATASET_FILE).get("dropped_message")
    duplicated = duplicate_line(stage_dir)
    return [line for line in (dropped, duplicated) if line]


def split_line(stage_dir: str | Path) -> str:
    """One line: the split's rule and the held-out evidence it leaves the observe stage."""
    data = read_json(Path(stage_dir) / DATASET_FILE)
    rule = ("auto (every model used)" if data.get("split_rule") == "auto"
            else "fixed counts" + (", extra models trained on"
                                   if data.get("extra_models") == "train" else ""))
    groups = data.get("held_out_groups")
    held = ("" if groups is None else f"; held-out groups (volume models of the smallest "
            f"class): {groups}" + (" (too few for a leave-one-group-out choice)"
                                  if groups < 2 else ""))
    return f"split: {rule}{held}"


def role_count_lines(stage_dir: str | Path) -> list[str]:
    """How many models each role got per class, one line per distinct count (classes named)."""
    data = read_json(Path(stage_dir) / DATASET_FILE)
    groups: dict[tuple[int, ...], list[str]] = {}
    for name in data["classes"]:
        counts = data.get("role_counts", {}).get(name)
        if counts is None:  # a dataset written before the counts were recorded
            counts = {r: sum(1 for m in data["models"]
                             if m["class_name"] == name and m["role"] == r) for r in ROLES}
        groups.setdefault(tuple(counts[r] for r in ROLES), []).append(name)
    lines = []
    for key, names in groups.items():
        roles = ", ".join(f"{n} {r}" for n, r in zip(key, ROLES, strict=True))
        lines.append(f"{roles} model(s) per class ({len(names)} classes: {', '.join(names)})")
    return lines


def load_dataset(stage_dir: str | Path) -> Dataset:
    """Read a dataset stage folder (its record checked: names plain, files inside it)."""
    stage_dir = Path(stage_dir)
    path = stage_dir / DATASET_FILE
    data = read_json(path)
    try:
        models = [ModelEntry(**entry) for entry in data["models"]]
        classes = [check_plain_name(c, "class name", path) for c in data["classes"]]
        for model in models:
            check_plain_name(model.class_name, "class name", path)
            check_plain_name(model.id, "model id", path)
            if model.file != _mesh_file(model.class_name, model.id):
                raise ArtefactError(f"{path}: model {model.id!r} has the file {model.file[:80]!r}"
                                    ", not one of the stage's own")
    except (TypeError, KeyError) as exc:
        raise ArtefactError(f"{path}: not a rapomdp dataset record ({str(exc)[:120]})") from None
    return Dataset(stage_dir, classes, models)


def _mesh_file(class_name: str, model_id: str) -> str:
    """Where the stage writes a model, relative to its folder."""
    return f"meshes/{class_name}/{model_id}.npz"


def _model_id(path: Path, layout: str) -> str:
    """A model's id: its file name (ShapeNet: its folder's), made a plain name."""
    return plain_name(path.parent.parent.name if layout == "shapenet" else path.stem)


def _write_mesh(out: Path, rel: str, mesh: trimesh.Trimesh) -> None:
    save_npz(out / rel, vertices=np.asarray(mesh.vertices, dtype=np.float64),
             faces=np.asarray(mesh.faces, dtype=np.int32))


def run_dataset_stage(config: Config, inputs: StageInputs, out: Path,
                      context: RunContext) -> None:
    """Build the dataset: pick, split, load, normalise and store every model.

    Args:
        config: the run's configuration; the stage reads ``seed`` and ``dataset`` (its
            key) and ``limits``.
        inputs: the folders of the stages it reads (none).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``dataset.json`` (the models, classes, split and roles, with
            each mesh file's content hash) and ``meshes/`` (every model normalised, as a mesh file).
    """
    cfg = config.dataset
    auto = cfg.split == "auto"
    counts = None if auto else {role: getattr(cfg.split, role) for role in ROLES}
    if cfg.source == "procedural":
        classes = list(cfg.classes) if cfg.classes is not None else list(PROCEDURAL_CLASSES)
        unknown = [c for c in classes if c not in PROCEDURAL_CLASSES]
        if unknown:
            raise DatasetLayoutError(
                f"unknown procedural class(es) {', '.join(unknown)}; "
                f"classes are: {', '.join(PROCEDURAL_CLASSES)}"
            )
        per_class = cfg.models_per_class or (AUTO_FULL_MODELS if auto else cfg.split.total)
        candidates = {c: list(range(per_class)) for c in classes}
        layout, up_axis = "procedural", "z"
    else:
        layout, candidates = folder_models(cfg)
        up_axis = LAYOUT_UP_AXIS[layout] if cfg.up_axis == "auto" else cfg.up_axis

    drawn = split_models(candidates, counts, config.seed, cfg.too_few_models,
                         "train" if auto else cfg.split.extra)
    split = drawn.roles

    jobs = [(c, role, item) for c, roles in split.items() for role in ROLES for item in roles[role]]
    models: list[ModelEntry] = []
    used_ids: set[tuple[str, str]] = set()
    same_bytes: dict[str, tuple[str, Path]] = {}  # file digest -> the first (role, file)
    duplicates: list[str] = []  # a file of one role with the same bytes as one of another
    for class_name, role, item in track(jobs, "dataset: normalising meshes", context.progress,
                                          unit="meshes"):
        if isinstance(item, int):
            mesh, source = generate_model(class_name, config.seed, item), f"procedural:{item}"
            model_id = f"{class_name}_{item:03d}"
        else:
            mesh, source = load_mesh(item, int(config.limits.mesh_file_mb * 1e6)), str(item)
            model_id = _model_id(item, layout)
            seen = same_bytes.setdefault(_file_digest(item), (role, item))
            if seen[0] != role:
                duplicates.append(f"{role} {item} = {seen[0]} {seen[1]}")
        base, n = model_id, 1
        while (class_name, model_id) in used_ids:
            n += 1
            model_id = f"{base}_{n}"
        used_ids.add((class_name, model_id))
        try:
            normalised = normalise_mesh(mesh, cfg.radius_m, up_axis)
        except MeshLoadError as exc:
            raise MeshLoadError(f"{source}: {exc}") from exc
        rel = _mesh_file(check_plain_name(class_name, "class name", source),
                         check_plain_name(model_id, "model id", source))
        _write_mesh(out, rel, normalised)
        height = float(np.ptp(normalised.vertices[:, 2]))
        models.append(ModelEntry(model_id, class_name, role, source, rel, height,
                                 int(len(normalised.faces))))
        assert np.allclose(centroid(normalised.vertices)[:2], 0.0, atol=1e-9)

    write_json_atomic(
        out / DATASET_FILE,
        {
            "classes": list(split),
            "layout": layout,
            "up_axis": up_axis,
            "radius_m": cfg.radius_m,
            "dropped": drawn.dropped,
            "dropped_message": drawn.dropped_message,
            "duplicates": duplicates,
            "split_rule": "auto" if auto else "fixed",
            "split_counts": counts,
            "extra_models": "train" if auto else cfg.split.extra,
            "role_counts": {c: {r: len(roles[r]) for r in ROLES} for c, roles in split.items()},
            "held_out_groups": min(len(roles["volume"]) for roles in split.values()),
            "models": [asdict(m) for m in models],
            "content_hash": stable_hash([asdict(m) for m in models]),
        },
    )
