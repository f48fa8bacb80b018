"""Dataset layouts on disk: which mesh files belong to which class.

* ``generic``: ``root/<class>/*.<ext>`` for any supported extension;
* ``objectnet3d``: ``root/CAD/off/<class>/<NN>.off`` (``root`` may also be the ``CAD/off`` folder);
* ``modelnet``: ``root/<class>/{train,test}/*.off`` (both folders are pooled: the project makes
  its own split);
* ``shapenet``: ``root/<synset>/<model>/models/model_normalized.obj``; classes are named by a
  synset-to-name map (``synset_map`` JSON, or ShapeNet's ``taxonomy.json`` in ``root``), or by the
  synset id when neither exists.

Each layout implies the meshes' up axis (ModelNet: z; ObjectNet3D and ShapeNet: y; generic: z),
which the configuration can override. Class names become folder names in the workspace, so a
name that is not a plain file name (``../x``, ``a/b``, ``.x``) is refused, naming its source.
"""

from __future__ import annotations

import json
from pathlib import Path

from rapomdp.config import Config, DatasetConfig
from rapomdp.io import ArtefactError, check_plain_name, fingerprint_files, read_text

LAYOUT_UP_AXIS = {"generic": "z", "objectnet3d": "y", "modelnet": "z", "shapenet": "y"}
#: The mesh files a layout reads (and :func:`rapomdp.data.meshes.load_mesh` loads).
MESH_EXTENSIONS = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
#: The procedural generator's version: the dataset stage's external input when the source is
#: the generator (a new version redoes the stage).
PROCEDURAL_VERSION = "2"


class DatasetLayoutError(ValueError):
    """A dataset folder does not match its layout (the folder and the problem are named)."""


def _class_dirs(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))


def _generic(root: Path) -> dict[str, list[Path]]:
    found = {}
    for folder in _class_dirs(root):
        files = sorted(
            p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in MESH_EXTENSIONS
        )
        if files:
            found[folder.name] = files
    return found


def _objectnet3d(root: Path) -> dict[str, list[Path]]:
    base = root / "CAD" / "off" if (root / "CAD" / "off").is_dir() else root
    return {
        folder.name: sorted(folder.glob("*.off"))
        for folder in _class_dirs(base)
        if any(folder.glob("*.off"))
    }


def _modelnet(root: Path) -> dict[str, list[Path]]:
    found = {}
    for folder in _class_dirs(root):
        files = sorted(
            (p for part in ("train", "test") if (folder / part).is_dir()
             for p in (folder / part).glob("*.off")),
            key=lambda p: (p.name, str(p)),
        )
        if files:
            found[folder.name] = files
    return found


def _synset_names(root: Path, synset_map: Path | None) -> dict[str, str]:
    path = synset_map if synset_map is not None else root / "taxonomy.json"
    if synset_map is not None and not synset_map.is_file():
        raise DatasetLayoutError(f"{synset_map}: synset map not found")
    if not path.is_file():
        return {}
    try:
        data = json.loads(read_text(path))
    except ArtefactError as exc:
        raise DatasetLayoutError(str(exc)) from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise DatasetLayoutError(f"{path}: not valid JSON ({str(exc)[:200]})") from None
    if isinstance(data, dict):
        return {str(k): str(v) for k, v in data.items()}
    if isinstance(data, list):  # ShapeNet's taxonomy.json
        return {
            str(e["synsetId"]): str(e["name"]).split(",")[0].strip()
            for e in data
            if isinstance(e, dict) and "synsetId" in e and "name" in e
        }
    raise DatasetLayoutError(f"{path}: expected a mapping or ShapeNet's taxonomy list")


def _checked_name(name: str, source: Path) -> str:
    try:
        return check_plain_name(name, "class name", source)
    except ArtefactError as exc:
        raise DatasetLayoutError(str(exc)) from None


def _shapenet(root: Path, synset_map: Path | None) -> dict[str, list[Path]]:
    names = _synset_names(root, synset_map)
    source = synset_map if synset_map is not None else root / "taxonomy.json"
    found: dict[str, list[Path]] = {}
    for folder in _class_dirs(root):
        files = sorted(folder.glob("*/models/model_normalized.obj"))
        if files:
            name = names.get(folder.name)
            name = folder.name if name is None else _checked_name(name, source)
            found.setdefault(name, []).extend(files)
    return found


def detect_layout(root: Path) -> str:
    """Guess a folder's layout from its structure."""
    if (root / "CAD" / "off").is_dir():
        return "objectnet3d"
    for folder in _class_dirs(root)[:5]:
        if (folder / "train").is_dir() or (folder / "test").is_dir():
            return "modelnet"
        if any(folder.glob("*/models/model_normalized.obj")):
            return "shapenet"
    return "generic"


def discover_models(
    root: str | Path, layout: str = "auto", synset_map: Path | None = None
) -> tuple[str, dict[str, list[Path]]]:
    """The layout used and, per class (sorted by name), the sorted mesh files."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetLayoutError(f"{root}: dataset folder not found")
    if layout == "auto":
        layout = detect_layout(root)
    readers = {
        "generic": _generic,
        "objectnet3d": _objectnet3d,
        "modelnet": _modelnet,
        "shapenet": lambda r: _shapenet(r, synset_map),
    }
    if layout not in readers:
        raise DatasetLayoutError(f"unknown layout '{layout}'; use one of {', '.join(readers)}")
    found = readers[layout](root)
    if not found:
        raise DatasetLayoutError(f"{root}: no mesh files found in the '{layout}' layout")
    for name in found:
        _checked_name(name, root)
    return layout, dict(sorted(found.items()))


def folder_models(cfg: DatasetConfig) -> tuple[str, dict[str, list[Path]]]:
    """The layout and, per class, the mesh files of a mesh folder (``dataset.source: folder``).

    Args:
        cfg: The ``dataset`` section: its ``path``, ``layout`` (``auto``: detected),
            ``synset_map`` and ``classes`` (only those, in that order, when given).

    Returns:
        The layout used and, per class, the sorted mesh files.

    Raises:
        DatasetLayoutError: No ``path``, a folder that does not match its layout, or a class
            named in ``classes`` but not found.

    Example:
        >>> import tempfile
        >>> from rapomdp.config import DatasetConfig
        >>> tmp = tempfile.TemporaryDirectory()
        >>> for name in ("bowl", "cup", "mug"):
        ...     (Path(tmp.name) / name).mkdir()
        ...     _ = (Path(tmp.name) / name / "a.obj").write_text("v 0 0 0\\n")
        >>> cfg = DatasetConfig(source="folder", path=tmp.name, classes=["mug", "cup"])
        >>> layout, found = folder_models(cfg)
        >>> layout, {name: [p.name for p in files] for name, files in found.items()}
        ('generic', {'mug': ['a.obj'], 'cup': ['a.obj']})
        >>> tmp.cleanup()
    """
    if cfg.path is None:
        raise DatasetLayoutError("dataset.path is not set: the mesh folder to read")
    layout, found = discover_models(cfg.path, cfg.layout, cfg.synset_map)
    if cfg.classes is not None:
        missing = [c for c in cfg.classes if c not in found]
        if missing:
            raise DatasetLayoutError(
                f"{cfg.path}: class folder(s) not found: {', '.join(missing)} "
                f"(found: {', '.join(found) or 'none'})"
            )
        found = {c: found[c] for c in cfg.classes}
    return layout, found


def dataset_fingerprint(config: Config) -> str:
    """What the stage reads from outside the config: the mesh files, or the generator's version."""
    if config.dataset.source == "procedural":
        return f"procedural-{PROCEDURAL_VERSION}"
    _, found = folder_models(config.dataset)
    return fingerprint_files([p for paths in found.values() for p in paths])
