"""The pretraining corpus: a mesh folder of many classes, none of them an evaluation class.

Two sources, both built here from nothing (the meshes stay out of the repository, under
``runs/``):

* **Abstract families** (:mod:`rapomdp.data.procedural.abstract`): ``families`` classes of
  primitive assemblies, ``models_per_family`` models each, with part-level deformations. Made
  by this project, under its licence.
* **Electronic components** from Debian's ``kicad-packages3d`` (the real-CAD builder's package
  and reader): the KiCad folders in :data:`KICAD_CORPUS`, which are none of the two real-CAD
  development sets' folders nor a variant of one of their classes (an SMD twin of a
  through-hole class, another pitch of a pin header, another Phoenix or terminal-block series,
  another IC package of the QFN/SOIC/BGA/DIP kind are all left out). CC-BY-SA-4.0 with KiCad's
  exception, or GPL-3+, per file, recorded in ``SOURCE.json``.

Any other mesh folder (``extra``, the ``generic`` layout ``<class>/<model>.<ext>``) may be
added. Every source is refused if its name or path holds a held-back name (``sweethome3d``),
and every class whose name is a class of an evaluation set (:data:`EVALUATION_CLASSES`: the
default's 35, the mesh set's 11, both real-CAD sets' 24 and their KiCad folders) is refused by
name: the backbone is judged on classes it never saw.

Example:
    >>> from rapomdp.pretrain.corpus import check_corpus_class
    >>> check_corpus_class("abstract_000", "abstract families")
    >>> try:
    ...     check_corpus_class("Mug", "--extra folder")
    ... except Exception as exc:
    ...     print(str(exc).split(":")[0])
    --extra folder class 'Mug' is an evaluation class
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rapomdp.data.build.common import (
    DatasetBuildError,
    building_folder,
    refuse_held_back,
    swap_in,
)
from rapomdp.data.build.debian import (
    COPYRIGHT,
    MODELS_DIR,
    check_deb,
    deb_field,
    extract,
    fetch_deb,
    parse_copyright,
)
from rapomdp.data.build.mesh_set import SHAPES
from rapomdp.data.build.real_cad import FIRST_SET, SECOND_SET, build_class
from rapomdp.data.layouts import MESH_EXTENSIONS
from rapomdp.data.meshes import MeshLoadError, load_mesh
from rapomdp.data.procedural.abstract import abstract_family, generate_abstract
from rapomdp.data.procedural.classes import PROCEDURAL_CLASSES
from rapomdp.io import write_json_atomic, write_text_atomic

#: KiCad folder -> corpus class: folders with 11 or more models in kicad-packages3d 6.0.10-1
#: that are neither a development set's folder nor a variant of one of its classes.
KICAD_CORPUS: dict[str, str] = {
    "Mounting_Wuerth": "standoff",
    "Connector_FFC-FPC": "ffc_connector",
    "Converter_DCDC": "dcdc_converter",
    "Display_7Segment": "seven_segment",
    "OptoDevice": "opto_device",
    "Display": "display_module",
    "Fuse": "fuse",
    "Connector_IDC": "idc_connector",
    "TestPoint": "test_point",
    "Connector_Stocko": "stocko_connector",
    "Buzzer_Beeper": "buzzer",
    "Converter_ACDC": "acdc_converter",
}


def _normal(name: str) -> str:
    return name.strip().lower().replace("-", "_").replace(" ", "_")


#: Every class of an evaluation set, and the KiCad folders behind the real-CAD sets, normalised
#: (lower case, ``_`` for ``-`` and spaces): a corpus never holds one.
EVALUATION_CLASSES: frozenset[str] = frozenset(
    _normal(name) for name in (*PROCEDURAL_CLASSES, *SHAPES, *FIRST_SET.values(),
                               *SECOND_SET.values(), *FIRST_SET, *SECOND_SET))
DEFAULT_OUT = Path("runs/pretrain/corpus")
DEFAULT_CACHE = Path("runs/real-cad-dev/cache")


def check_corpus_class(name: str, source: str) -> None:
    """Refuse a corpus class that is an evaluation class or names a held-back source.

    Args:
        name: the class (a folder name).
        source: where it comes from, for the message.

    Raises:
        DatasetBuildError: naming the class and why.
    """
    refuse_held_back([name], f"{source} class")
    if _normal(name) in EVALUATION_CLASSES:
        raise DatasetBuildError(
            f"{source} class {name!r} is an evaluation class: a pretraining corpus holds no "
            "class of the default, the mesh set or the real-CAD development sets (rename or "
            "leave it out)")


@dataclass
class CorpusBuild:
    """A finished corpus.

    Attributes:
        out: the mesh folder (``<class>/<model>.ply``).
        classes: models per class, in the corpus's class order.
        sources: per source: its classes, models, licence and origin.
    """

    out: Path
    classes: dict[str, int]
    sources: list[dict[str, Any]]

    def summary(self) -> str:
        """One line per source and the total."""
        lines = [f"{s['name']}: {len(s['classes'])} classes, {s['models']} models "
                 f"({s['licence']})" for s in self.sources]
        return "\n".join([*lines, f"total: {len(self.classes)} classes, "
                          f"{sum(self.classes.values())} models -> {self.out}"])


def _abstract_source(out: Path, families: int, models: int, seed: int,
                     progress: Callable[[str], None] | None) -> dict[str, Any]:
    classes: dict[str, int] = {}
    for index in range(families):
        family = abstract_family(index, seed)
        check_corpus_class(family.name, "abstract families")
        target = out / family.name
        target.mkdir(parents=True)
        for model in range(models):
            generate_abstract(family, seed, model).export(
                target / f"m{model:03d}.ply", file_type="ply", encoding="binary")
        classes[family.name] = models
        if progress is not None and (index + 1) % 20 == 0:
            progress(f"abstract families: {index + 1}/{families}")
    return {"name": "abstract families", "classes": classes, "models": sum(classes.values()),
            "licence": "made by rapomdp (the project's licence)",
            "origin": f"rapomdp.data.procedural.abstract, seed {seed}"}


def _kicad_source(out: Path, cache: Path, deb: Path | None, cap: int,
                  progress: Callable[[str], None] | None) -> dict[str, Any]:
    for folder, name in KICAD_CORPUS.items():
        check_corpus_class(folder, "kicad-packages3d")
        check_corpus_class(name, "kicad-packages3d")
    if deb is None:
        deb = fetch_deb(cache)
    check_deb(deb)
    root = extract(deb, cache, KICAD_CORPUS)
    stanzas = parse_copyright((root / COPYRIGHT).read_text())
    classes: dict[str, int] = {}
    licences: dict[str, int] = {}
    for folder, name in KICAD_CORPUS.items():
        report = build_class(root / MODELS_DIR / f"{folder}.3dshapes", name, out, cap, stanzas)
        classes[name] = len(report.kept)
        for model in report.kept:
            licences[model["licence"]] = licences.get(model["licence"], 0) + 1
        if progress is not None:
            progress(f"kicad-packages3d: {name} {len(report.kept)} of {report.files}")
    return {"name": "kicad-packages3d", "classes": classes, "models": sum(classes.values()),
            "licence": ", ".join(f"{k} ({v})" for k, v in sorted(licences.items())),
            "origin": f"Debian package kicad-packages3d {deb_field(deb, 'Version')} "
                      f"({deb.name}), folders {', '.join(KICAD_CORPUS)}"}


def _extra_source(out: Path, folder: Path) -> dict[str, Any]:
    if not folder.is_dir():
        raise DatasetBuildError(f"--extra {folder}: no such folder")
    classes: dict[str, int] = {}
    for class_dir in sorted(p for p in folder.iterdir() if p.is_dir()):
        check_corpus_class(class_dir.name, "--extra folder")
        files = sorted(p for p in class_dir.iterdir() if p.suffix.lower() in MESH_EXTENSIONS)
        if not files:
            continue
        target = out / class_dir.name
        if target.exists():
            raise DatasetBuildError(f"--extra {folder}: class {class_dir.name!r} is already "
                                    "in the corpus")
        target.mkdir(parents=True)
        for path in files:
            refuse_held_back([path.name], "--extra file")
            try:
                load_mesh(path).export(target / f"{path.stem}.ply", file_type="ply",
                                       encoding="binary")
            except MeshLoadError as exc:
                raise DatasetBuildError(f"--extra {path}: {exc}") from None
        classes[class_dir.name] = len(files)
    return {"name": f"extra {folder}", "classes": classes, "models": sum(classes.values()),
            "licence": "as the folder's owner states", "origin": str(folder)}


def build_corpus(out: Path | None = None, *, families: int = 160, models_per_family: int = 20,
                 kicad: bool = True, max_per_class: int = 24, cache: Path = DEFAULT_CACHE,
                 deb: Path | None = None, extra: Sequence[Path] = (), seed: int = 0,
                 progress: Callable[[str], None] | None = None) -> CorpusBuild:
    """Build the pretraining corpus (built beside ``out`` and swapped in whole).

    Args:
        out: the mesh folder (default :data:`DEFAULT_OUT`); replaced only if a build made it.
        families: abstract families (classes).
        models_per_family: models of each abstract family.
        kicad: add :data:`KICAD_CORPUS`'s classes from ``kicad-packages3d``.
        max_per_class: models kept per KiCad class (the real-CAD builder's selection).
        cache: where the ``.deb`` and its extraction are kept (shared with the real-CAD sets).
        deb: an already downloaded ``kicad-packages3d`` ``.deb``.
        extra: more mesh folders in the ``generic`` layout.
        seed: the abstract families' seed.
        progress: called with a line as each part is done.

    Returns:
        The build, with ``SOURCE.json`` and ``SOURCE.md`` written into the folder.

    Raises:
        DatasetBuildError: a held-back source, an evaluation class, a folder that may not be
            replaced, or a failed download.
    """
    if families < 0 or models_per_family < 1:
        raise DatasetBuildError("--families must be 0 or more and --models 1 or more")
    for folder in extra:
        refuse_held_back(Path(folder).resolve().parts, "--extra folder")
    if deb is not None:
        refuse_held_back([deb.name], "--deb file")
    building = building_folder(out if out is not None else DEFAULT_OUT)
    target = out if out is not None else DEFAULT_OUT
    try:
        sources = []
        if families:
            sources.append(_abstract_source(building, families, models_per_family, seed,
                                            progress))
        if kicad:
            sources.append(_kicad_source(building, cache, deb, max_per_class, progress))
        sources += [_extra_source(building, Path(folder)) for folder in extra]
        classes = {name: count for s in sources for name, count in s["classes"].items()}
        if len(classes) < 2:
            raise DatasetBuildError("a corpus needs at least 2 classes")
        write_json_atomic(building / "SOURCE.json", {"classes": classes, "sources": sources})
        lines = ["# Pretraining corpus", "",
                 "Built by `rapomdp pretrain`. No class of an evaluation set; no "
                 "held-back source.", "", "| source | classes | models | licence | origin |",
                 "|---|---|---|---|---|"]
        lines += [f"| {s['name']} | {len(s['classes'])} | {s['models']} | {s['licence']} | "
                  f"{s['origin']} |" for s in sources]
        write_text_atomic(building / "SOURCE.md", "\n".join([*lines, ""]))
    except BaseException:
        shutil.rmtree(building, ignore_errors=True)
        raise
    return CorpusBuild(swap_in(building, target), classes, sources)
