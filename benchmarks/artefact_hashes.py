"""Hash every artefact of the tiny end-to-end pipeline (the evaluate tests' configuration).

Run on two trees (before and after a refactoring) with the same seed and compare the printed
digests: a structural change must leave every artefact's content unchanged. ``.npz`` archives are
hashed array by array (a zip member's timestamp is not content); JSON records drop the fields
that measure wall time; PNG files are hashed as decoded pixels.

    PYTHONPATH=src python benchmarks/artefact_hashes.py [--out hashes.json]
    PYTHONPATH=src python benchmarks/artefact_hashes.py \
        --compare benchmarks/results/artefact_hashes_main.json
    PYTHONPATH=src python benchmarks/artefact_hashes.py --noise \
        --compare benchmarks/results/artefact_hashes_main_noise.json

``benchmarks/results/artefact_hashes_main{,_noise}.json`` were recorded on main at 9b0d8b4 (the
tree before issue 16's restructuring), with the sensor noise off and on.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

#: tests/experiment/test_evaluation.py's TINY (TINY_PIPELINE plus its overrides).
TINY: dict = {
    "seed": 5,
    "camera": {"width": 64, "height": 48},
    "render": {"views": 12},
    "train": {"width": 0.125, "epochs": 2, "batch_size": 16, "preprocess": {"input_size_px": 32}},
    "saliency": {"iterations": 5},
    "volume": {"resolution": 12},
    "vptree": {"branching": 4, "levels": 2},
    "dataset": {"classes": ["cup", "bicycle", "teapot"]},
    "viewpoints": {"count": 16},
    # a budget the tiny solves never reach (they converge in under a second), so that the
    # upper bound's grid, sized to what the budget allows, reaches its full resolution on a
    # loaded machine too
    "solve": {"timeout_s": 30.0},
    "evaluate": {"methods": ["static", "random", "vptree", "classifier", "ra"],
                 "starts_per_model": 3, "max_moves": 6},
}
#: Record fields that measure time or name the machine, not the result.
TIMING_KEYS = {"seconds", "finished", "wall_s", "elapsed_s", "time_s", "seconds_per_episode",
               "train_seconds", "images_per_second", "timed_out", "iterations"}
#: How far a time-limited solve got (its iterations, the upper bound's grid resolution and the
#: bound's last bits) depends on the machine's speed, not on the code: scrubbed like time.
GRID_REACHED = re.compile(r"grid reached resolution \d+")
SIGNIFICANT_DIGITS = 12
#: Files that are not results: the manifest holds wall time; ``.lock`` is the workspace's lock
#: file, there whether or not a run holds it.
SKIP = {"manifest.json", ".lock"}


def _scrub(value: object) -> object:
    if isinstance(value, dict):
        return {k: _scrub(v) for k, v in value.items()
                if k not in TIMING_KEYS and "second" not in k and not k.endswith("_s")}
    if isinstance(value, list):
        return [_scrub(v) for v in value]
    if isinstance(value, float):
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}")
    if isinstance(value, str):
        return GRID_REACHED.sub("grid reached resolution N", value)
    return value


#: Text that measures time, names the folder or is a random element id (plotly's div).
VOLATILE = [
    (re.compile(r"^.*\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d.*$", re.M), "TIME-ROW"),
    (re.compile(r"[\d.]+ (s|images/s|images per CPU second)\b"), "N s"),
    # one-decimal table cells are the report's seconds columns (stage records, solver table)
    (re.compile(r"(\| |<td>)\d+\.\d( \||</td>)"), r"\1N\2"),
    (re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}"), "UUID"),
]


def _text(path: Path, workspace: Path) -> str:
    text = path.read_text().replace(str(workspace), "WS")
    if path.suffix == ".csv":
        rows = [line.split(",") for line in text.splitlines()]
        keep = [i for i, name in enumerate(rows[0]) if "second" not in name] if rows else []
        return "\n".join(",".join(row[i] for i in keep if i < len(row)) for row in rows)
    for pattern, replacement in VOLATILE:
        text = pattern.sub(replacement, text)
    return text


def digest(path: Path, workspace: Path) -> str:
    h = hashlib.sha256()
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            for name in sorted(n for n in data.files if "second" not in n):
                array = data[name]
                h.update(f"{name}{array.dtype}{array.shape}".encode())
                h.update(np.ascontiguousarray(array).tobytes())
    elif path.suffix == ".json":
        h.update(json.dumps(_scrub(json.loads(path.read_text())), sort_keys=True).encode())
    elif path.suffix == ".png":
        import matplotlib.image

        h.update(np.ascontiguousarray(matplotlib.image.imread(path)).tobytes())
    elif path.suffix in {".md", ".html", ".csv", ".txt", ".yaml"}:
        h.update(_text(path, workspace).encode())
    else:
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write {file: digest} here as JSON")
    parser.add_argument("--workspace", type=Path, help="keep the workspace here")
    parser.add_argument("--noise", action="store_true",
                        help="with the Xtion sensor noise on (render.noise.enabled)")
    parser.add_argument("--compare", type=Path,
                        help="a --out file of another tree: print every difference, exit 1 if any")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes of the run (default 1; 2 exercises the pool)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ws = args.workspace or Path(tmp) / "ws"
        config = Path(tmp) / "tiny.yaml"
        data = {**TINY, "render": {**TINY["render"], "noise": {"enabled": True}}} \
            if args.noise else TINY
        config.write_text(yaml.safe_dump(data))
        subprocess.run([sys.executable, "-m", "rapomdp.cli", "run", "-w", str(ws), "-c",
                        str(config), "--workers", str(args.workers)], check=True,
                       stdout=subprocess.DEVNULL)
        hashes = {str(p.relative_to(ws)): digest(p, ws) for p in sorted(ws.rglob("*"))
                  if p.is_file() and p.name not in SKIP}
    for name, value in hashes.items():
        print(f"{value}  {name}")
    if args.out:
        args.out.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
    if args.compare:
        before = json.loads(args.compare.read_text())
        differ = sorted(n for n in before.keys() | hashes.keys()
                        if before.get(n) != hashes.get(n))
        for name in differ:
            print(f"DIFFERS  {name}: {before.get(name, 'absent')} -> {hashes.get(name, 'absent')}")
        print(f"{len(hashes)} artefacts, {len(differ)} differ from {args.compare}")
        sys.exit(1 if differ else 0)


if __name__ == "__main__":
    main()
