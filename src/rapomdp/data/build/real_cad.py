"""The real-CAD development sets: electronic components from Debian's ``kicad-packages3d``,
written as a mesh folder in the ``generic`` layout (``OUT/<class>/<model>.ply``) that
``dataset: {source: folder, layout: generic}`` reads.

    rapomdp dataset build real-cad --out runs/real-cad-dev/meshes
    rapomdp dataset build real-cad --set second --out runs/real-cad-dev-2/meshes
    rapomdp run -w runs/real-cad-dev-ws -c configs/real-cad-dev.yaml

Needs ``apt-get`` (a Debian or Ubuntu system; run ``apt-get update`` once) and ``dpkg-deb``, or
an already downloaded ``.deb`` (``deb=``), or the package already unpacked (``source=``). About
a minute a set, most of it the download.

Source: Debian bookworm package ``kicad-packages3d`` 6.0.10-1 (all; 379 MB download, 5.5 GB
installed: 6227 models, each as STEP and VRML), the KiCad 3D library. Fetched with
``apt-get download`` into ``cache`` (run ``apt-get update`` once first) and unpacked with
``dpkg-deb``; only the VRML files of the folders below are extracted (about 240 MB). The VRML is
KiCad StepUp's plain ``IndexedFaceSet`` export (absolute coordinates, no transforms), read by a
small parser here (trimesh reads no VRML, and the STEP twins would need OpenCASCADE).

Chosen over the other Debian packages with 3D models (surveyed on Debian bookworm):
flightgear-data-models (144 MB; 523 AC3D models, but its folders are uses, not object
categories: Residential 62, Maritime 55, Commercial 46 ...; of the 12 folders with 11 or more,
4 are weather, effects, sky and test geometry),
0ad-data (1.4 GB; 4010 models only as the engine's cached binary .pmd, mostly helmets, shields
and building parts), supertuxkart-data (628 MB; 1220 models in the game's own binary .spm) and
warzone2100-data (143 MB; 753 low-poly .pie game pieces). kicad-packages3d gives 61 folders of
11 or more models in a format read here, of real object categories.

Licence (the package's ``copyright`` file, DEP-5, read per file): CC-BY-SA-4.0 with KiCad's
exception (article 3 waived for electronic designs that use the models) for most files;
GPL-3+ for most of Capacitor_THT and part of Package_DIP (of the 192 models written by default:
CC-BY-SA-4.0-with-exception 172, GPL-3+ 20). Every model's licence is recorded in
``OUT/SOURCE.json``; ``OUT/SOURCE.md`` summarises. The meshes are derived work under the same
licences and stay out of the repository (``runs/`` is ignored).

Class mapping (KiCad folder -> class), through-hole parts as they stand on a board, z up;
measured on 6.0.10-1: files / candidates after the rules below / kept at the default cap 16:

    Resistor_THT        -> resistor        105 / 104 / 16  axial, power, shunt, box, SIP array
    Capacitor_THT       -> capacitor       375 / 353 / 16  electrolytic cans, discs, film boxes
    Inductor_THT        -> inductor        144 / 130 / 16  radial drums, axial, toroid chokes
    Crystal             -> crystal          99 /  63 / 16  HC-49/HC-52 cans, cylinders, resonators
    LED_THT             -> led              77 /  62 / 16  1.8-20 mm domes, angled, rectangular
    Package_TO_SOT_THT  -> transistor       97 /  94 / 16  TO-92, TO-18/-46 cans, TO-220, TO-3
    Package_DIP         -> dip_ic          202 / 186 / 16  DIP-4 ... DIP-64, SMDIP, sockets
    Relay_THT           -> relay            48 /  42 / 16  sealed box relays
    Potentiometer_THT   -> potentiometer    23 /  19 / 16  Bourns trimmers (boxes, round 3339)
    Connector_Dsub      -> dsub            112 /  99 / 16  D-sub 9 ... 62, male / female
    Transformer_THT     -> transformer      29 /  21 / 16  encapsulated and EI transformers
    Battery             -> battery          27 /  27 / 16  cell holders and a coin cell

Relay, transformer and potentiometer are all boxes with pins: hard classes (they differ in
proportions, pin rows, knobs and windows more than in outline).

A model is a candidate unless it is unreadable (one Relay_THT file is a Transform of line sets),
degenerate (fewer than ``MIN_FACES`` triangles: 5 LEDs, 1 TO-92; non-finite; or flat: smallest
extent under ``FLAT_RATIO`` of the largest) or a near-duplicate of a candidate before it in
name order (same face count and the same normalised extents and area within ``DUP_TOL``:
131 such, e.g. electrolytic cans whose lead pitch stays inside the can, colour variants of one
LED, D-sub housings under two names). At most ``max_per_class`` are kept (``select``): greedily
for shape variety (farthest in normalised extents) while spreading over the name families
(``family``: ``CP_Radial``, ``C_Disc``, ``C_Rect`` ...), so a class keeps its variety instead of
one family's parametric series.

Re-running is idempotent: the .deb and the extraction are cached; the folder is rebuilt under a
temporary name and swapped in whole.

Example (the rules are plain functions):
    >>> from rapomdp.data.build.real_cad import family
    >>> family("CP_Radial_D10.0mm_P5.00mm"), family("LED_D5.0mm_Clear")
    ('CP_Radial', 'LED')
"""

from __future__ import annotations

import hashlib
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from rapomdp.data.build.common import (
    DatasetBuildError,
    building_folder,
    check_replaceable,
    refuse_held_back,
    swap_in,
)
from rapomdp.data.build.debian import (
    COPYRIGHT,
    MODELS_DIR,
    PACKAGE,
    check_deb,
    deb_field,
    extract,
    fetch_deb,
    licence_for,
    parse_copyright,
)
from rapomdp.data.build.vrml import parse_vrml
from rapomdp.io import write_json_atomic, write_text_atomic

#: KiCad 3D folder (without ``.3dshapes``) -> class name: the first set.
FIRST_SET: dict[str, str] = {
    "Resistor_THT": "resistor",
    "Capacitor_THT": "capacitor",
    "Inductor_THT": "inductor",
    "Crystal": "crystal",
    "LED_THT": "led",
    "Package_TO_SOT_THT": "transistor",
    "Package_DIP": "dip_ic",
    "Relay_THT": "relay",
    "Potentiometer_THT": "potentiometer",
    "Connector_Dsub": "dsub",
    "Transformer_THT": "transformer",
    "Battery": "battery",
}
#: The second set (docs/decisions/0025-second-real-cad-set.md): the 12 largest folders not in
#: the first, not mounting hardware, not a first-set category's SMD variant, one folder per
#: family of variants.
SECOND_SET: dict[str, str] = {
    "Connector_PinSocket_2.54mm": "pin_socket",
    "Connector_PinHeader_2.54mm": "pin_header",
    "Package_DFN_QFN": "qfn",
    "Package_SO": "soic",
    "Connector_Phoenix_MSTB": "phoenix",
    "Connector_JST": "jst",
    "Button_Switch_SMD": "button",
    "Varistor": "varistor",
    "Diode_THT": "diode",
    "Connector_Molex": "molex",
    "TerminalBlock_Phoenix": "terminal_block",
    "Package_BGA": "bga",
}
SETS: dict[str, dict[str, str]] = {"first": FIRST_SET, "second": SECOND_SET}
#: Where each set is written by default (the paths ``configs/real-cad-dev*.yaml`` read).
DEFAULT_OUT = {"first": Path("runs/real-cad-dev/meshes"),
               "second": Path("runs/real-cad-dev-2/meshes")}
DEFAULT_CACHE = Path("runs/real-cad-dev/cache")
MIN_FACES = 64          # fewer triangles: a placeholder, not a model
FLAT_RATIO = 0.01       # smallest / largest bounding-box extent below this: flat
DUP_TOL = 0.01          # relative tolerance on normalised extents and area for a near-duplicate
MIN_PER_CLASS = 11      # the default split's total (4 train / 3 volume / 4 test)

Signature = tuple[int, np.ndarray]


# ---------------------------------------------------------------------------------------------
# the rules

_DIMENSION_RE = re.compile(r"[A-Za-z]{1,2}\d")


def family(stem: str) -> str:
    """A model's family: its first two ``_`` tokens, the second left out when it is a dimension.

    Args:
        stem: the model's file name without suffix.

    Returns:
        ``CP_Radial_D10.0mm_P5.00mm`` -> ``CP_Radial``; ``DIP-8_W7.62mm`` -> ``DIP-8``;
        ``LED_D5.0mm_Clear`` -> ``LED``; ``Relay_SPDT_Finder_36.11`` -> ``Relay_SPDT``.
    """
    tokens = stem.split("_")
    if len(tokens) > 1 and _DIMENSION_RE.match(tokens[1]):
        return tokens[0]
    return "_".join(tokens[:2])


def degenerate_reason(mesh: trimesh.Trimesh) -> str | None:
    """Why ``mesh`` is unusable as a model, or None.

    Args:
        mesh: a model as read.

    Returns:
        ``"<n> faces"`` under :data:`MIN_FACES`, ``"non-finite vertices"``, ``"flat"`` (smallest
        extent under :data:`FLAT_RATIO` of the largest), ``"no surface area"``; None if usable.
    """
    if len(mesh.faces) < MIN_FACES:
        return f"{len(mesh.faces)} faces"
    if not np.all(np.isfinite(mesh.vertices)):
        return "non-finite vertices"
    extents = np.ptp(np.asarray(mesh.vertices), axis=0)
    if extents.max() <= 0 or extents.min() < FLAT_RATIO * extents.max():
        return "flat"
    if not mesh.area > 0:
        return "no surface area"
    return None


def signature(mesh: trimesh.Trimesh) -> Signature:
    """A shape's signature, invariant to scale and to a quarter turn about the up axis.

    Args:
        mesh: a usable model (:func:`degenerate_reason` is None).

    Returns:
        (face count, (4,) float64: the two x/y extents sorted, the z extent and the area, each
        divided by the largest extent, the area by its square).
    """
    extents = np.ptp(np.asarray(mesh.vertices), axis=0)
    scale = float(extents.max())
    xy = np.sort(extents[:2]) / scale
    return len(mesh.faces), np.array([xy[0], xy[1], extents[2] / scale, mesh.area / scale**2])


def near_duplicate(a: Signature, b: Signature, tol: float = DUP_TOL) -> bool:
    """Whether two signatures are one model under two names.

    Args:
        a: a :func:`signature`.
        b: another.
        tol: relative tolerance on each normalised measure.

    Returns:
        True when the face counts are equal and every measure is within ``tol``.
    """
    return a[0] == b[0] and bool(np.all(np.abs(a[1] - b[1]) <= tol * np.maximum(a[1], b[1])))


def shape_vector(sig: Signature) -> np.ndarray:
    """A signature as a point for shape distances.

    Args:
        sig: a :func:`signature`.

    Returns:
        (4,) the logs of its normalised measures (a ratio counts the same at every size).
    """
    return np.log(np.maximum(sig[1], 1e-6))


def select(signatures: dict[str, Signature], cap: int) -> list[str]:
    """The models a class keeps, chosen greedily for variety.

    First the model nearest the class's median shape; then, each time, among the families with
    the smallest share of their models picked so far (every family once before any twice, then
    in proportion to size), the model farthest in shape (:func:`shape_vector`) from every model
    picked; ties by name.

    Args:
        signatures: model name -> :func:`signature`, the class's candidates.
        cap: at most this many (0: all).

    Returns:
        The names kept, sorted.
    """
    stems = sorted(signatures)
    limit = len(stems) if cap <= 0 else min(cap, len(stems))
    if limit == 0:
        return []
    points = np.array([shape_vector(signatures[s]) for s in stems])
    families = [family(s) for s in stems]
    sizes = {f: families.count(f) for f in families}
    median = np.median(points, axis=0)
    picked = [int(np.argmin(np.linalg.norm(points - median, axis=1)))]
    uses: dict[str, int] = {families[picked[0]]: 1}
    nearest = np.linalg.norm(points - points[picked[0]], axis=1)
    while len(picked) < limit:
        free = [i for i in range(len(stems)) if i not in picked]
        share = {i: uses.get(families[i], 0) / sizes[families[i]] for i in free}
        fewest = min(share.values())
        pool = [i for i in free if share[i] == fewest]
        choice = max(pool, key=lambda i: (nearest[i], -i))
        picked.append(choice)
        uses[families[choice]] = uses.get(families[choice], 0) + 1
        nearest = np.minimum(nearest, np.linalg.norm(points - points[choice], axis=1))
    return sorted(stems[i] for i in picked)


# ---------------------------------------------------------------------------------------------
# building

@dataclass
class ClassReport:
    """What one class's folder gave.

    Attributes:
        folder: the KiCad folder (without ``.3dshapes``).
        name: the class.
        files: ``.wrl`` files in it.
        unreadable: ``"<model> (<why>)"`` per file the reader refused.
        degenerate: ``"<model> (<why>)"`` per unusable model.
        duplicates: models that repeat an earlier candidate.
        candidates: models left after those rules.
        kept: per model written: its name, file, source, licence, faces and vertices.
    """

    folder: str
    name: str
    files: int = 0
    unreadable: list[str] = field(default_factory=list)
    degenerate: list[str] = field(default_factory=list)
    duplicates: list[str] = field(default_factory=list)
    candidates: int = 0
    kept: list[dict[str, Any]] = field(default_factory=list)


def build_class(folder: Path, name: str, out: Path, cap: int,
                stanzas: list[tuple[list[str], str]]) -> ClassReport:
    """One class: read every model of a KiCad folder, apply the rules, write those kept.

    Args:
        folder: ``<root>/usr/share/kicad/3dmodels/<Folder>.3dshapes``.
        name: the class; its models go to ``out/<name>/<model>.ply`` (binary PLY).
        out: the mesh folder being built.
        cap: models kept at most (0: all), chosen by :func:`select`.
        stanzas: :func:`parse_copyright`'s, for each model's licence.

    Returns:
        The class's report.

    Raises:
        DatasetBuildError: the folder is not in the package.
    """
    if not folder.is_dir():
        raise DatasetBuildError(f"{folder.name} is not in the package ({folder.parent})")
    report = ClassReport(folder.name.removesuffix(".3dshapes"), name)
    files = sorted(folder.glob("*.wrl"))
    report.files = len(files)
    meshes: dict[str, trimesh.Trimesh] = {}
    signatures: dict[str, Signature] = {}
    for path in files:
        try:
            mesh = parse_vrml(path.read_bytes())
        except (ValueError, OverflowError) as exc:
            report.unreadable.append(f"{path.stem} ({exc})")
            continue
        mesh.merge_vertices()
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.remove_unreferenced_vertices()
        reason = degenerate_reason(mesh)
        if reason:
            report.degenerate.append(f"{path.stem} ({reason})")
            continue
        sig = signature(mesh)
        if any(near_duplicate(sig, other) for other in signatures.values()):
            report.duplicates.append(path.stem)
            continue
        signatures[path.stem] = sig
        meshes[path.stem] = mesh
    report.candidates = len(meshes)
    target = out / name
    target.mkdir(parents=True)
    for stem in select(signatures, cap):
        mesh = meshes[stem]
        mesh.export(target / f"{stem}.ply", file_type="ply", encoding="binary")
        relative = f"{folder.name}/{stem}.wrl"
        report.kept.append({"model": stem, "file": f"{name}/{stem}.ply",
                            "source": f"{MODELS_DIR}/{relative}",
                            "licence": licence_for(relative, stanzas),
                            "faces": int(len(mesh.faces)),
                            "vertices": int(len(mesh.vertices))})
    return report


def table(reports: list[ClassReport], markdown: bool = False) -> str:
    """The per-class counts as a table.

    Args:
        reports: :func:`build_class`'s, one a class.
        markdown: a Markdown table instead of aligned text.

    Returns:
        One row a class and a total: files, unreadable, degenerate, duplicates, candidates,
        kept, families and the median face count of the models kept.
    """
    head = ["class", "kicad folder", "files", "unreadable", "degenerate", "duplicates",
            "candidates", "kept", "families", "median faces"]
    rows: list[list[Any]] = []
    for r in reports:
        faces = [m["faces"] for m in r.kept]
        rows.append([r.name, r.folder, r.files, len(r.unreadable), len(r.degenerate),
                     len(r.duplicates), r.candidates, len(r.kept),
                     len({family(m["model"]) for m in r.kept}),
                     int(np.median(faces)) if faces else 0])
    rows.append(["total", "", *[sum(row[k] for row in rows) for k in range(2, 8)], "", ""])
    if markdown:
        return "\n".join("| " + " | ".join(map(str, row)) + " |"
                         for row in [head, ["---"] * len(head), *rows])
    widths = [max(len(str(row[k])) for row in [head, *rows]) for k in range(len(head))]
    return "\n".join("  ".join(str(v).rjust(w) if k > 1 else str(v).ljust(w)
                               for k, (v, w) in enumerate(zip(row, widths, strict=True)))
                     for row in [head, *rows])


def write_source(out: Path, package: dict[str, Any], reports: list[ClassReport],
                 cap: int) -> dict[str, Any]:
    """``SOURCE.json`` (every model's source file and licence) and ``SOURCE.md`` (a summary).

    Args:
        out: the mesh folder being built.
        package: what was read: ``package``, ``version``, ``deb``, ``deb_sha256``, ``homepage``
            (None where unknown, as for an unpacked folder).
        reports: one a class.
        cap: the models-a-class cap the build used.

    Returns:
        The record written to ``SOURCE.json``.
    """
    info = {**package,
            "format": "VRML 2.0 (KiCad StepUp IndexedFaceSet) -> binary PLY, z up, units as "
                      "shipped",
            "max_per_class": cap,
            "rules": {"min_faces": MIN_FACES, "flat_ratio": FLAT_RATIO, "dup_tol": DUP_TOL},
            "classes": {r.name: {"folder": r.folder, "files": r.files,
                                 "unreadable": r.unreadable, "degenerate": r.degenerate,
                                 "duplicates": r.duplicates, "candidates": r.candidates,
                                 "kept": r.kept} for r in reports}}
    write_json_atomic(out / "SOURCE.json", info)
    licences: dict[str, int] = {}
    for r in reports:
        for model in r.kept:
            licences[model["licence"]] = licences.get(model["licence"], 0) + 1
    origin = (f"Debian package `{info['package']}` {info['version']} ({info['deb']}, sha256 "
              f"{str(info['deb_sha256'])[:16]}...), upstream {info['homepage']}."
              if info.get("deb") else f"`{info['package']}` unpacked at {info.get('unpacked')}.")
    lines = [f"# Real-CAD development set: {info['package']} {info['version'] or ''}".rstrip(),
             "", origin,
             "Built by `rapomdp dataset build real-cad`; per-model sources and licences in "
             "SOURCE.json.", "",
             "Licences of the models here (from the package's DEP-5 copyright file): "
             + ", ".join(f"{k} ({v})" for k, v in sorted(licences.items())) + ".",
             "CC-BY-SA-4.0-with-exception: CC-BY-SA 4.0, article 3 waived for electronic "
             "designs using the models.", "", table(reports, markdown=True), ""]
    write_text_atomic(out / "SOURCE.md", "\n".join(lines))
    return info


@dataclass
class RealCadBuild:
    """A finished build.

    Attributes:
        out: the mesh folder written.
        reports: one a class, in the set's order.
        info: the ``SOURCE.json`` record.
    """

    out: Path
    reports: list[ClassReport]
    info: dict[str, Any]

    def summary(self) -> str:
        """What was built, the per-class table, and the classes the default split cannot take."""
        lines = [f"{self.info['package']} {self.info['version'] or '(unpacked)'} -> {self.out} "
                 f"(max {self.info['max_per_class']} a class)", "", table(self.reports)]
        short = [r.name for r in self.reports if len(r.kept) < MIN_PER_CLASS]
        if short:
            lines += ["", f"classes under {MIN_PER_CLASS} models (the default split's total; "
                      f"dataset.too_few_models: drop leaves them out): {', '.join(short)}"]
        return "\n".join(lines)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        while block := stream.read(1 << 20):
            digest.update(block)
    return digest.hexdigest()


def build_real_cad(out: Path | None = None, *, which: str = "first",
                   cache: Path = DEFAULT_CACHE, deb: Path | None = None,
                   source: Path | None = None, max_per_class: int = 16,
                   progress: Callable[[str], None] | None = None) -> RealCadBuild:
    """Build a real-CAD mesh folder from ``kicad-packages3d``.

    The package comes from ``source`` (already unpacked), else ``deb``, else ``apt-get
    download`` into ``cache``. The folder is built beside ``out`` and swapped in whole, so a
    rebuild is idempotent and an interrupted one leaves the old folder intact.

    Args:
        out: the mesh folder (default :data:`DEFAULT_OUT` of the set).
        which: ``"first"`` or ``"second"`` (:data:`SETS`).
        cache: where the ``.deb`` and its extraction are kept.
        deb: a downloaded ``kicad-packages3d`` ``.deb``.
        source: an unpacked package tree (holding ``usr/share/kicad/3dmodels`` and the
            copyright file).
        max_per_class: models kept a class (0: all).
        progress: called with one line per class as it is done.

    Returns:
        The build: the folder, the per-class reports and the ``SOURCE.json`` record.

    Raises:
        DatasetBuildError: an unknown set, a held-back or wrong package, a missing tool or
            folder.
    """
    if which not in SETS:
        raise DatasetBuildError(f"--set must be one of {', '.join(SETS)}, got {which!r}")
    if max_per_class < 0:
        raise DatasetBuildError(f"--max-per-class must be 0 (all) or more, got {max_per_class}")
    class_map = SETS[which]
    target = check_replaceable(out if out is not None else DEFAULT_OUT[which])
    if source is not None:
        refuse_held_back(source.resolve().parts, "--source folder")
        root = source
        if not (root / COPYRIGHT).is_file():
            raise DatasetBuildError(f"{source} is not an unpacked {PACKAGE}: no {COPYRIGHT}")
        package: dict[str, Any] = {"package": PACKAGE, "version": None, "deb": None,
                                   "deb_sha256": None, "homepage": None,
                                   "unpacked": str(source)}
    else:
        if deb is not None:
            check_deb(deb)
        else:
            deb = fetch_deb(cache)
            check_deb(deb)
        root = extract(deb, cache, class_map)
        package = {"package": PACKAGE, "version": deb_field(deb, "Version"), "deb": deb.name,
                   "deb_sha256": _sha256(deb), "homepage": deb_field(deb, "Homepage")}
    stanzas = parse_copyright((root / COPYRIGHT).read_text())
    building = building_folder(target)
    try:
        reports = []
        for folder, name in class_map.items():
            reports.append(build_class(root / MODELS_DIR / f"{folder}.3dshapes", name, building,
                                       max_per_class, stanzas))
            if progress is not None:
                progress(f"{name}: {len(reports[-1].kept)} of {reports[-1].files}")
        info = write_source(building, package, reports, max_per_class)
    except BaseException:
        shutil.rmtree(building, ignore_errors=True)
        raise
    return RealCadBuild(swap_in(building, target), reports, info)
