"""A development dataset of real CAD models: electronic components from Debian's
``kicad-packages3d``, written as a mesh folder in the ``generic`` layout
(``OUT/<class>/<model>.ply``) that ``dataset: {source: folder, layout: generic}`` reads.

    python benchmarks/real_cad_devset.py                  # -> runs/real-cad-dev/meshes
    python benchmarks/real_cad_devset.py --out DIR --cache DIR --max-per-class 16
    python benchmarks/real_cad_devset.py --set second     # -> runs/real-cad-dev-2/meshes
    rapomdp dataset -w runs/real-cad-dev-ws -c configs/real-cad-dev.yaml

Source: Debian bookworm package ``kicad-packages3d`` 6.0.10-1 (all; 379 MB download, 5.5 GB
installed: 6227 models, each as STEP and VRML), the KiCad 3D library. Fetched with
``apt-get download`` into ``--cache`` (run ``apt-get update`` once first) and unpacked with
``dpkg-deb``; only the VRML files of the folders below are extracted (about 240 MB). The VRML is
KiCad StepUp's plain ``IndexedFaceSet`` export (absolute coordinates, no transforms), read by a
small parser here (trimesh reads no VRML, and the STEP twins would need OpenCASCADE).

Chosen over the other Debian packages with 3D models (measured 2026-12-02, bookworm):
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
LED, D-sub housings under two names). At most ``--max-per-class`` are kept (``select``): greedily
for shape variety (farthest in normalised extents) while spreading over the name families
(``family``: ``CP_Radial``, ``C_Disc``, ``C_Rect`` ...), so a class keeps its variety instead of
one family's parametric series.

Re-running is idempotent: the .deb and the extraction are cached; the folder is rebuilt under a
temporary name and swapped in whole.
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

PACKAGE = "kicad-packages3d"
MODELS_DIR = "usr/share/kicad/3dmodels"
COPYRIGHT = f"usr/share/doc/{PACKAGE}/copyright"

#: KiCad 3D folder (without ``.3dshapes``) -> class name.
CLASS_MAP: dict[str, str] = {
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

#: The second set (``--set second``; rule ``results/real_cad_second_set_rule.md``): the 12
#: largest folders not in the first, not mounting hardware, not a first-set category's SMD
#: variant, one folder per family of variants.
SECOND_CLASS_MAP: dict[str, str] = {
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
CLASS_MAPS = {"first": CLASS_MAP, "second": SECOND_CLASS_MAP}
#: Where each set is written unless ``--out`` says otherwise.
DEFAULT_OUT = {"first": Path("runs/real-cad-dev/meshes"),
               "second": Path("runs/real-cad-dev-2/meshes")}
MIN_FACES = 64          # fewer triangles: a placeholder, not a model
FLAT_RATIO = 0.01       # smallest / largest bounding-box extent below this: flat
DUP_TOL = 0.01          # relative tolerance on normalised extents and area for a near-duplicate
MIN_PER_CLASS = 11      # the default split's total (4 train / 3 volume / 4 test)

_INDEX_RE = re.compile(rb"coordIndex\s*\[([^\]]*)\]")
_POINT_RE = re.compile(rb"point\s*\[([^\]]*)\]")


# ---------------------------------------------------------------------------------------------
# reading

def parse_vrml(data: bytes) -> trimesh.Trimesh:
    """The triangles of every ``IndexedFaceSet`` in a VRML 2.0 file with absolute coordinates
    (KiCad StepUp's export: no Transform, Inline or PROTO); polygons are fan-triangulated."""
    if re.search(rb"\b(Transform|Inline|PROTO)\b", data):
        raise ValueError("not a plain IndexedFaceSet export (Transform, Inline or PROTO)")
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    offset = 0
    for chunk in data.split(b"IndexedFaceSet")[1:]:
        index_match, point_match = _INDEX_RE.search(chunk), _POINT_RE.search(chunk)
        if index_match is None or point_match is None:
            continue
        points = np.array(point_match.group(1).replace(b",", b" ").split(), dtype=np.float64)
        index = np.array(index_match.group(1).replace(b",", b" ").split(), dtype=np.int64)
        if points.size == 0 or index.size == 0:
            continue  # an empty set (StepUp writes some)
        if points.size % 3:
            raise ValueError("a point list whose length is not a multiple of 3")
        points = points.reshape(-1, 3)
        tris = _triangulate(index)
        if len(tris) == 0:
            continue
        if tris.max() >= len(points) or tris.min() < 0:
            raise ValueError("a face refers to a point that does not exist")
        vertices.append(points)
        faces.append(tris + offset)
        offset += len(points)
    if not faces:
        raise ValueError("no IndexedFaceSet with faces")
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)


def _triangulate(index: np.ndarray) -> np.ndarray:
    """Faces from a ``-1``-separated coordIndex list (fast path when every face is a triangle)."""
    if index[-1] != -1:
        index = np.append(index, -1)
    if index.size % 4 == 0 and np.all(index[3::4] == -1):
        quads = index.reshape(-1, 4)[:, :3]
        if not np.any(quads < 0):
            return quads
    out = []
    for polygon in np.split(index, np.flatnonzero(index == -1) + 1):
        polygon = polygon[polygon >= 0]
        for k in range(1, len(polygon) - 1):
            out.append((polygon[0], polygon[k], polygon[k + 1]))
    return np.array(out, dtype=np.int64).reshape(-1, 3)


# ---------------------------------------------------------------------------------------------
# the rules (plain functions)

_DIMENSION_RE = re.compile(r"[A-Za-z]{1,2}\d")


def family(stem: str) -> str:
    """A model's family: its first two ``_`` tokens, the second left out when it is a dimension
    (``CP_Radial_D10.0mm_P5.00mm`` -> ``CP_Radial``; ``DIP-8_W7.62mm`` -> ``DIP-8``;
    ``LED_D5.0mm_Clear`` -> ``LED``; ``Relay_SPDT_Finder_36.11`` -> ``Relay_SPDT``)."""
    tokens = stem.split("_")
    if len(tokens) > 1 and _DIMENSION_RE.match(tokens[1]):
        return tokens[0]
    return "_".join(tokens[:2])


def degenerate_reason(mesh: trimesh.Trimesh) -> str | None:
    """Why ``mesh`` is unusable (too few faces, non-finite, flat, no area), or None."""
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


def signature(mesh: trimesh.Trimesh) -> tuple[int, np.ndarray]:
    """(face count, [x/y extents sorted, z extent, area] normalised by the largest extent):
    invariant to scale and to a quarter turn about the up axis."""
    extents = np.ptp(np.asarray(mesh.vertices), axis=0)
    scale = float(extents.max())
    xy = np.sort(extents[:2]) / scale
    return len(mesh.faces), np.array([xy[0], xy[1], extents[2] / scale, mesh.area / scale**2])


def near_duplicate(a: tuple[int, np.ndarray], b: tuple[int, np.ndarray],
                   tol: float = DUP_TOL) -> bool:
    """Same face count and every normalised measure within ``tol`` (relative)."""
    return a[0] == b[0] and bool(np.all(np.abs(a[1] - b[1]) <= tol * np.maximum(a[1], b[1])))


def shape_vector(sig: tuple[int, np.ndarray]) -> np.ndarray:
    """A signature as a point for shape distances: the logs of its normalised extents and
    area (so a ratio counts the same at every size)."""
    return np.log(np.maximum(sig[1], 1e-6))


def select(signatures: dict[str, tuple[int, np.ndarray]], cap: int) -> list[str]:
    """At most ``cap`` models (0: all) chosen greedily for variety: first the one nearest the
    class's median shape, then each time, among the families with the smallest share of their
    models picked so far (every family once before any twice, then in proportion to size), the
    model farthest in shape (``shape_vector``) from every model picked; ties by name."""
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


def licence_for(path: str, stanzas: list[tuple[list[str], str]]) -> str:
    """The licence of ``path`` (relative to the models folder) under DEP-5: the last matching
    ``Files:`` stanza wins."""
    found = "unknown"
    for patterns, licence in stanzas:
        if any(fnmatch.fnmatchcase(path, pattern) for pattern in patterns):
            found = licence
    return found


def parse_copyright(text: str) -> list[tuple[list[str], str]]:
    """The (Files patterns, License) stanzas of a DEP-5 copyright file."""
    stanzas = []
    for block in re.split(r"\n\s*\n", text):
        files = re.search(r"^Files:(.*?)(?=^\S)", block + "\nEnd:", re.S | re.M)
        licence = re.search(r"^License:\s*(\S+)", block, re.M)
        if files and licence:
            stanzas.append((files.group(1).split(), licence.group(1)))
    return stanzas


# ---------------------------------------------------------------------------------------------
# fetching

def fetch_deb(cache: Path) -> Path:
    """The cached ``.deb`` of PACKAGE, downloaded with ``apt-get download`` when missing."""
    cache.mkdir(parents=True, exist_ok=True)
    debs = sorted(cache.glob(f"{PACKAGE}_*.deb"))
    if not debs:
        print(f"downloading {PACKAGE} with apt-get download into {cache} ...", flush=True)
        result = subprocess.run(["apt-get", "download", PACKAGE], cwd=cache,
                                capture_output=True, text=True)
        debs = sorted(cache.glob(f"{PACKAGE}_*.deb"))
        if result.returncode != 0 or not debs:
            sys.exit(f"apt-get download {PACKAGE} failed (run 'apt-get update' first?):\n"
                     f"{result.stderr.strip()}")
    return debs[-1]


def deb_field(deb: Path, name: str) -> str:
    return subprocess.run(["dpkg-deb", "-f", str(deb), name], check=True, capture_output=True,
                          text=True).stdout.strip()


def extract(deb: Path, cache: Path, class_map: dict[str, str] = CLASS_MAP) -> Path:
    """The unpacked VRML files of the mapped folders and the copyright file (cached; a marker
    written last says the extraction is complete)."""
    digest = hashlib.sha256(json.dumps(sorted(class_map)).encode()).hexdigest()[:10]
    root = cache / f"{deb.stem}-{digest}"
    if (root / ".complete").is_file():
        return root
    partial = root.with_name(root.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    patterns = [f"./{MODELS_DIR}/{folder}.3dshapes/*.wrl" for folder in class_map]
    print(f"extracting {len(patterns)} folders from {deb.name} ...", flush=True)
    tar = subprocess.Popen(["tar", "-x", "-C", str(partial), "--wildcards", f"./{COPYRIGHT}",
                            *patterns], stdin=subprocess.PIPE)
    dpkg = subprocess.run(["dpkg-deb", "--fsys-tarfile", str(deb)], stdout=tar.stdin)
    tar.stdin.close()
    if tar.wait() != 0 or dpkg.returncode != 0:
        sys.exit(f"extracting {deb} failed")
    (partial / ".complete").write_text("ok\n")
    shutil.rmtree(root, ignore_errors=True)
    partial.rename(root)
    return root


# ---------------------------------------------------------------------------------------------
# building

@dataclass
class ClassReport:
    folder: str
    name: str
    files: int = 0
    unreadable: list[str] = field(default_factory=list)
    degenerate: list[str] = field(default_factory=list)
    duplicates: list[str] = field(default_factory=list)
    candidates: int = 0
    kept: list[dict] = field(default_factory=list)


def build_class(folder: Path, name: str, out: Path, cap: int,
                stanzas: list[tuple[list[str], str]]) -> ClassReport:
    report = ClassReport(folder.name.removesuffix(".3dshapes"), name)
    files = sorted(folder.glob("*.wrl"))
    report.files = len(files)
    meshes: dict[str, trimesh.Trimesh] = {}
    signatures: dict[str, tuple[int, np.ndarray]] = {}
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


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        while block := stream.read(1 << 20):
            digest.update(block)
    return digest.hexdigest()


def write_source(out: Path, deb: Path, reports: list[ClassReport], cap: int) -> dict:
    info = {
        "package": PACKAGE,
        "version": deb_field(deb, "Version"),
        "deb": deb.name,
        "deb_sha256": _sha256(deb),
        "homepage": deb_field(deb, "Homepage"),
        "format": "VRML 2.0 (KiCad StepUp IndexedFaceSet) -> binary PLY, z up, units as shipped",
        "max_per_class": cap,
        "rules": {"min_faces": MIN_FACES, "flat_ratio": FLAT_RATIO, "dup_tol": DUP_TOL},
        "classes": {r.name: {"folder": r.folder, "files": r.files,
                             "unreadable": r.unreadable, "degenerate": r.degenerate,
                             "duplicates": r.duplicates, "candidates": r.candidates,
                             "kept": r.kept} for r in reports},
    }
    (out / "SOURCE.json").write_text(json.dumps(info, indent=1) + "\n")
    licences: dict[str, int] = {}
    for r in reports:
        for model in r.kept:
            licences[model["licence"]] = licences.get(model["licence"], 0) + 1
    lines = [f"# Real-CAD development set: {PACKAGE} {info['version']}", "",
             f"Debian package `{PACKAGE}` {info['version']} ({deb.name}, sha256 "
             f"{info['deb_sha256'][:16]}...), upstream {info['homepage']}.",
             "Built by `benchmarks/real_cad_devset.py`; per-model sources and licences in "
             "SOURCE.json.", "",
             "Licences of the models here (from the package's DEP-5 copyright file): "
             + ", ".join(f"{k} ({v})" for k, v in sorted(licences.items())) + ".",
             "CC-BY-SA-4.0-with-exception: CC-BY-SA 4.0, article 3 waived for electronic "
             "designs using the models.", "", table(reports, markdown=True), ""]
    (out / "SOURCE.md").write_text("\n".join(lines))
    return info


def table(reports: list[ClassReport], markdown: bool = False) -> str:
    head = ["class", "kicad folder", "files", "unreadable", "degenerate", "duplicates",
            "candidates", "kept", "families", "median faces"]
    rows = []
    for r in reports:
        faces = [m["faces"] for m in r.kept]
        rows.append([r.name, r.folder, r.files, len(r.unreadable), len(r.degenerate),
                     len(r.duplicates), r.candidates, len(r.kept),
                     len({family(m["model"]) for m in r.kept}),
                     int(np.median(faces)) if faces else 0])
    rows.append(["total", "", *[sum(row[k] for row in rows) for k in range(2, 8)], "", ""])
    if markdown:
        return "\n".join(["| " + " | ".join(map(str, row)) + " |" for row in
                          [head, ["---"] * len(head), *rows]])
    widths = [max(len(str(row[k])) for row in [head, *rows]) for k in range(len(head))]
    return "\n".join("  ".join(str(v).rjust(w) if k > 1 else str(v).ljust(w)
                               for k, (v, w) in enumerate(zip(row, widths, strict=True)))
                     for row in [head, *rows])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None,
                        help="mesh folder to (re)build (default: runs/real-cad-dev/meshes, "
                             "the second set runs/real-cad-dev-2/meshes)")
    parser.add_argument("--set", choices=sorted(CLASS_MAPS), default="first",
                        help="which class map: the first set, or the second, disjoint one "
                             "(default: %(default)s)")
    parser.add_argument("--cache", type=Path, default=Path("runs/real-cad-dev/cache"),
                        help="where the .deb and its extraction are kept (default: %(default)s)")
    parser.add_argument("--max-per-class", type=int, default=16,
                        help="models kept per class, 0 for all (default: %(default)s)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    class_map = CLASS_MAPS[args.set]
    args.out = args.out or DEFAULT_OUT[args.set]
    deb = fetch_deb(args.cache)
    root = extract(deb, args.cache, class_map)
    stanzas = parse_copyright((root / COPYRIGHT).read_text())
    out = args.out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.*-*"):  # left by an interrupted run
        shutil.rmtree(stale, ignore_errors=True)
    building = out.with_name(f".{out.name}.building-{os.getpid()}")
    building.mkdir()
    reports = []
    for folder, name in class_map.items():
        reports.append(build_class(root / MODELS_DIR / f"{folder}.3dshapes", name, building,
                                   args.max_per_class, stanzas))
        print(f"  {name}: {len(reports[-1].kept)} of {reports[-1].files}", flush=True)
    info = write_source(building, deb, reports, args.max_per_class)
    old = out.with_name(f".{out.name}.old-{os.getpid()}")
    if out.exists():
        out.rename(old)
    building.rename(out)
    shutil.rmtree(old, ignore_errors=True)
    print(f"\n{PACKAGE} {info['version']} -> {args.out} (max {args.max_per_class} a class)\n")
    print(table(reports))
    short = [r.name for r in reports if len(r.kept) < MIN_PER_CLASS]
    if short:
        print(f"\nclasses under {MIN_PER_CLASS} models (the default split's total): {short}")
    print(f"\n{time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
