"""Every bad input and fault of issue 14, as a case: set it up, do what a user does, and report
what they saw (:class:`~tests.faults.harness.Outcome`). ``test_faults.py`` asserts each;
``benchmarks/fault_table.py`` prints them as a table."""

from __future__ import annotations

import errno
import json
import os
import signal
import time
from pathlib import Path

from rapomdp.workspace import SCRATCH
from tests.faults.harness import (
    TINY_YAML,
    Case,
    Outcome,
    alive,
    cached_workspace,
    cli,
    cli_process,
    disk_full,
    lost_files,
    python_process,
    read_only,
    snapshot,
    wait_for,
)

CASES: list[Case] = []


def case(name: str, fault: str, expect: str, succeeds: bool = False):
    def register(function):
        CASES.append(Case(name, fault, expect, function, succeeds))
        return function
    return register


def _kept(outcome: Outcome, before: dict[str, str], ws: Path,
          changed: tuple[str, ...] = ()) -> Outcome:
    """``outcome`` with the workspace files that were lost or changed (``changed``: files
    the command rightly rewrites)."""
    after = snapshot(ws)
    outcome.lost = [f for f in lost_files(before, after) if not f.startswith(changed)]
    return outcome


def _tetrahedron(comment: str = "") -> str:
    return (f"# {comment}\n" if comment else "") + (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")


def _folder_config(root: Path, path: Path, layout: str, extra: str = "") -> Path:
    config = root / "input" / "config.yaml"
    config.write_text(f"dataset: {{source: folder, path: {path}, layout: {layout}{extra}, "
                      "split: {train: 3, volume: 1, test: 1}}\n"
                      "camera: {width: 40, height: 30}\nrender: {views: 6}\n")
    return config


def _shapenet(root: Path, models: int = 5) -> Path:
    base = root / "input" / "shapenet"
    for i in range(models):
        folder = base / "02691156" / f"model{i}" / "models"
        folder.mkdir(parents=True)
        (folder / "model_normalized.obj").write_text(_tetrahedron())
    return base


# -- the workspace owns its configuration ---------------------------------------------------

@case("no -c", "`rapomdp render -w W` without -c on a configured workspace",
      "cached", succeeds=True)
def stage_without_config_file(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    outcome = cli(["render", "-w", str(ws)])
    outcome.message = outcome.detail.strip().splitlines()[-1]
    return _kept(outcome, before, ws)


@case("-c changes stages", "-c with another configuration on an existing workspace",
      "--reconfigure")
def config_file_that_invalidates(root: Path) -> Outcome:
    ws = cached_workspace(root)
    other = root / "input" / "other.yaml"
    other.parent.mkdir()
    other.write_text(TINY_YAML.replace("views: 6", "views: 7"))
    before = snapshot(ws)
    outcome = cli(["render", "-w", str(ws), "-c", str(other)])
    lines = outcome.detail.splitlines()
    assert any("render: render.views 6 -> 7" in line for line in lines), outcome.detail
    outcome.message = lines[0]
    return _kept(outcome, before, ws)


@case("--reconfigure", "-c with another configuration and --reconfigure",
      "render     done", succeeds=True)
def reconfigure_accepts(root: Path) -> Outcome:
    ws = cached_workspace(root)
    other = root / "input" / "other.yaml"
    other.parent.mkdir()
    other.write_text(TINY_YAML.replace("views: 6", "views: 7"))
    before = snapshot(ws)
    outcome = cli(["render", "-w", str(ws), "-c", str(other), "--reconfigure"])
    assert "views: 7" in (ws / "config.yaml").read_text()
    outcome.message = next(line for line in outcome.detail.splitlines() if "render " in line)
    return _kept(outcome, before, ws, changed=("render/", "manifest.json", "config.yaml"))


@case("failed run", "a run that fails (unknown class) keeps W/config.yaml",
      "unknown procedural class")
def failed_run_keeps_config(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    outcome = cli(["render", "-w", str(ws), "dataset.classes=[cup, mug, teapotx]"])
    return _kept(outcome, before, ws)


@case("status: stale", "`rapomdp status` after `run --until dataset seed=4`",
      "stale: seed 3 -> 4; input dataset was redone since", succeeds=True)
def status_marks_stale(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    first = cli(["run", "-w", str(ws), "--until", "dataset", "seed=4"])
    assert first.exit_code == 0, first.detail
    outcome = cli(["status", "-w", str(ws)])
    lines = outcome.detail.splitlines()
    row = next((line for line in lines if "│ render " in line), "")
    why = next((line for line in lines if line.startswith("  render: ")), "")
    outcome.message = (" ".join(row.replace("│", " ").split()[:2]) + ": "
                       + why.removeprefix("  render: "))
    return _kept(outcome, before, ws, changed=("config.yaml", "dataset/", "manifest.json"))


def _override(root: Path, override: str) -> Outcome:
    """A bad ``KEY=VALUE`` on a cached workspace: refused, nothing touched."""
    ws = cached_workspace(root)
    before = snapshot(ws)
    return _kept(cli(["render", "-w", str(ws), override]), before, ws)


for _name, _override_text, _expect in (
        ("override: boolean", "render.views=true", "render.views: a boolean is not a number"),
        ("override: unknown key", "train.epochz=3", "train.epochz: unknown key"),
        ("radius .inf", "render.radius_m=.inf", "render.radius_m: Input should be a finite"),
        ("seed: -1", "seed=-1", "seed: Input should be greater than or equal to 0"),
        ("seed: 2^32", "seed=4294967296", "seed: a whole number of magnitude below 2^32")):
    case(_name, f"`{_override_text}` on the command line", _expect)(
        lambda root, text=_override_text: _override(root, text))


# -- hostile input ---------------------------------------------------------------------------

@case("taxonomy.json ../", "ShapeNet taxonomy.json naming a class `../../../x`",
      "is not a plain name")
def taxonomy_traversal(root: Path) -> Outcome:
    base = _shapenet(root)
    (base / "taxonomy.json").write_text(json.dumps(
        [{"synsetId": "02691156", "name": "../../../x", "children": []}]))
    config = _folder_config(root, base, "shapenet")
    return cli(["render", "-w", str(root / "ws"), "-c", str(config)])


@case("synset_map ../", "dataset.synset_map naming a class `../../escape`",
      "is not a plain name")
def synset_map_traversal(root: Path) -> Outcome:
    base = _shapenet(root)
    mapping = root / "input" / "map.json"
    mapping.write_text(json.dumps({"02691156": "../../escape"}))
    config = _folder_config(root, base, "shapenet", f", synset_map: {mapping}")
    return cli(["render", "-w", str(root / "ws"), "-c", str(config)])


@case("fig2 --against ../", "`rapomdp figure fig2 --against ../../x` (names a folder)",
      "is not a plain name")
def fig2_traversal(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    outcome = cli(["figure", "fig2", "-w", str(ws), "--target", "cup", "--against", "../../x"])
    return _kept(outcome, before, ws)


@case("billion laughs", "a YAML document of 9 nested levels of 9 aliases (10^9 values)",
      "aliases")
def billion_laughs(root: Path) -> Outcome:
    lines = ['l0: &l0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for level in range(1, 9):
        lines.append(f"l{level}: &l{level} [" + ",".join([f"*l{level - 1}"] * 9) + "]")
    lines.append("seed: *l8")
    path = root / "input" / "lol.yaml"
    path.parent.mkdir()
    path.write_text("\n".join(lines) + "\n")
    outcome = cli(["run", "-w", str(root / "ws"), "-c", str(path)])
    assert outcome.seconds < 10, f"took {outcome.seconds:.1f} s"
    return outcome


@case("zero-area class", "a class whose meshes all have zero area (collinear vertices)",
      "every face of the mesh is degenerate")
def zero_area_meshes(root: Path) -> Outcome:
    base = root / "input" / "meshes"
    for name, text in (("flat", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
                       ("solid", _tetrahedron())):
        (base / name).mkdir(parents=True)
        for i in range(5):
            (base / name / f"m{i}.obj").write_text(text)
    config = _folder_config(root, base, "generic")
    return cli(["render", "-w", str(root / "ws"), "-c", str(config)])


@case("views: true", "`render: {views: true}` in a configuration file",
      "render.views: a boolean is not a number")
def views_true(root: Path) -> Outcome:
    path = root / "input" / "c.yaml"
    path.parent.mkdir()
    path.write_text("render: {views: true}\n")
    return cli(["render", "-w", str(root / "ws"), "-c", str(path)])


@case("seed: 1e23", "`seed: 1.0e+23` (a float YAML reads) in a file", "seed:")
def seed_huge(root: Path) -> Outcome:
    path = root / "input" / "c.yaml"
    path.parent.mkdir()
    path.write_text("seed: 1.0e+23\n")
    outcome = cli(["render", "-w", str(root / "ws"), "-c", str(path)])
    assert "seed" in outcome.detail and outcome.exit_code == 2, outcome.detail
    return outcome


@case("Latin-1 OBJ", "OBJ files with a Latin-1 comment (`# modèle créé`)",
      "dataset    done", succeeds=True)
def latin1_obj(root: Path) -> Outcome:
    base = root / "input" / "meshes"
    for name in ("cone", "wedge"):
        (base / name).mkdir(parents=True)
        for i in range(5):
            (base / name / f"m{i}.obj").write_bytes(
                _tetrahedron(f"modèle créé {name} {i}").encode("latin-1"))
    config = _folder_config(root, base, "generic")
    outcome = cli(["dataset", "-w", str(root / "ws"), "-c", str(config)])
    data = json.loads((root / "ws" / "dataset" / "dataset.json").read_text())
    assert data["classes"] == ["cone", "wedge"] and len(data["models"]) == 10
    outcome.message = next(line for line in outcome.detail.splitlines() if "dataset " in line)
    return outcome


@case("Latin-1 config", "a configuration with a Latin-1 comment", "seed: 3", succeeds=True)
def latin1_config(root: Path) -> Outcome:
    path = root / "input" / "c.yaml"
    path.parent.mkdir()
    path.write_bytes(("# réglages du modèle\n" + TINY_YAML).encode("latin-1"))
    outcome = cli(["config", "-c", str(path)])
    outcome.message = outcome.detail.splitlines()[0]
    return outcome


@case("binary config", "a configuration file holding binary data", "binary data")
def binary_config(root: Path) -> Outcome:
    path = root / "input" / "c.yaml"
    path.parent.mkdir()
    path.write_bytes(b"seed: 3\n\x00\x01\x02\xff")
    return cli(["render", "-w", str(root / "ws"), "-c", str(path)])


# -- every failure a named error -------------------------------------------------------------

def _damaged_mesh(root: Path, data: bytes) -> Outcome:
    ws = cached_workspace(root)
    mesh = ws / "dataset" / "meshes" / "cup" / "cup_000.npz"
    mesh.write_bytes(mesh.read_bytes()[:len(data)] if data else b"")
    before = snapshot(ws)
    outcome = cli(["dataset", "preview", "-w", str(ws), "--width", "32",
                   "--out", str(ws / "sheet.png")])
    assert "cup_000.npz" in outcome.message, outcome.message
    return _kept(outcome, before, ws)


@case("truncated .npz", "a mesh .npz cut to half its size, then `dataset preview`",
      "damaged .npz archive")
def truncated_npz(root: Path) -> Outcome:
    return _damaged_mesh(root, b"x" * 200)


@case("empty .npz", "a mesh .npz of 0 bytes, then `dataset preview`", "empty file")
def empty_npz(root: Path) -> Outcome:
    return _damaged_mesh(root, b"")


def _bad_manifest(root: Path, content: bytes, command: str) -> Outcome:
    ws = cached_workspace(root)
    (ws / "manifest.json").write_bytes(content)
    before = snapshot(ws)
    args = ["status", "-w", str(ws)] if command == "status" else ["render", "-w", str(ws)]
    outcome = cli(args)
    assert "manifest.json" in outcome.message, outcome.message
    return _kept(outcome, before, ws)


for _name, _fault, _expect, _content, _command in (
        ("manifest not UTF-8", "manifest.json with a Latin-1 byte, then `render`",
         "not valid JSON (byte", b'{"stages": {"caf\xe9": 1}}', "render"),
        ("manifest a list", "manifest.json holding a JSON list, then `render`",
         "not a rapomdp manifest", b"[]", "render"),
        ("manifest {} (status)", "manifest.json holding `{}`, then `status`",
         "not a rapomdp manifest", b"{}", "status"),
        ("manifest list (status)", "manifest.json holding `[1, 2]`, then `status`",
         "not a rapomdp manifest", b"[1, 2]", "status")):
    case(_name, _fault, _expect)(
        lambda root, content=_content, command=_command: _bad_manifest(root, content, command))


@case("read-only, cached", "a read-only workspace whose stages are all cached",
      "cached", succeeds=True)
def read_only_cached(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    with read_only(ws):
        outcome = cli(["run", "-w", str(ws), "--until", "render"])
    stages = [line for line in outcome.detail.splitlines() if line.startswith("✓")]
    outcome.message = stages[-1] if stages else outcome.detail.strip()[-300:]
    return _kept(outcome, before, ws)


@case("read-only, work to do", "a read-only workspace and a stage to redo",
      "the file system is read-only")
def read_only_work(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    with read_only(ws):
        outcome = cli(["run", "-w", str(ws), "--until", "render", "render.views=7"])
    return _kept(outcome, before, ws)


@case("disk full", "ENOSPC while the render stage writes its images",
      "no space left on the device")
def full_disk(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    with disk_full(ws):  # in this process, where the harness fills the disk
        outcome = cli(["render", "-w", str(ws), "--workers", "1", "render.views=7"])
    leftovers = [p.name for p in ws.iterdir() if ".tmp" in p.name or p.name == SCRATCH]
    assert not leftovers, leftovers
    return _kept(outcome, before, ws)


@case("failed folder swap", "the rename of the new render folder into place fails",
      "could not be moved into place")
def failed_swap(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    real_replace = os.replace

    def failing(src: object, dst: object) -> None:
        if Path(os.fsdecode(dst)).name == "render" and ".tmp-" in os.fsdecode(src):
            raise OSError(errno.EIO, os.strerror(errno.EIO), os.fsdecode(src))
        real_replace(src, dst)

    os.replace = failing
    try:
        outcome = cli(["render", "-w", str(ws), "render.views=7"])
    finally:
        os.replace = real_replace
    assert (ws / "render" / "render.json").exists()
    return _kept(outcome, before, ws)


@case("checkpoint class list", "a checkpoint whose class list differs (library load)",
      "Retrain with `rapomdp train -w")
def checkpoint_hint(root: Path) -> Outcome:
    from rapomdp.geometry.camera import xtion_intrinsics
    from rapomdp.recognition.classifier import CheckpointError, Classifier
    from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
    from rapomdp.recognition.preprocess import PreprocessParams

    folder = root / "ws" / "train"
    intrinsics = xtion_intrinsics(40, 30)
    network = DepthAlexNet(NetworkSpec(2, 32, width=0.125))
    Classifier(network, ["cup", "mug"], PreprocessParams(input_size_px=32), intrinsics.fx,
               intrinsics.fy).save(folder, config_hash="x")
    try:
        Classifier.load(folder, classes=["cup", "vase"])
    except CheckpointError as exc:
        assert f"rapomdp train -w {root / 'ws'} --force" in str(exc), str(exc)
        return Outcome(2, str(exc).rsplit(". ", 1)[-1])
    return Outcome(0, "loaded")


# -- faults: kill -9, two runs, dying workers ------------------------------------------------

@case("kill -9 mid-stage", f"SIGKILL while render writes W/{SCRATCH}/render.tmp-PID, then a "
      "rerun", "cached", succeeds=True)
def killed_mid_stage(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    child = cli_process(["render", "-w", str(ws), "render.views=3000"])
    scratch = ws / SCRATCH
    try:
        wait_for(lambda: scratch.is_dir() and any(
            "render.tmp-" in p.name and any(p.rglob("*.npz")) for p in scratch.iterdir()),
            120, "the render stage's temporary folder")
    finally:
        child.send_signal(signal.SIGKILL)
        child.communicate()
    assert any(".tmp-" in p.name for p in scratch.iterdir())
    outcome = cli(["render", "-w", str(ws)])
    leftovers = [p.name for p in ws.iterdir() if ".tmp" in p.name or ".old-" in p.name
                 or p.name == SCRATCH]
    assert not leftovers, leftovers
    outcome.message = "leftovers removed; " + outcome.detail.strip().splitlines()[-1]
    return _kept(outcome, before, ws)


@case("kill -9 mid-swap", "a run killed between the two renames of a folder swap",
      "cached", succeeds=True)
def killed_mid_swap(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    (ws / SCRATCH).mkdir()
    os.replace(ws / "render", ws / SCRATCH / "render.old-99999")
    (ws / SCRATCH / "render.tmp-99999").mkdir()
    outcome = cli(["render", "-w", str(ws)])
    outcome.message = "old folder moved back; " + outcome.detail.strip().splitlines()[-1]
    return _kept(outcome, before, ws)


@case("kill -9: workers", "SIGKILL of a parent whose 2 worker processes run tasks",
      "workers ended", succeeds=True)
def killed_parent_workers(root: Path) -> Outcome:
    pids = root / "pids"
    pids.mkdir()
    parent = python_process(
        "from rapomdp.parallel import run_tasks\n"
        "from tests.faults.tasks import sleep_and_report_pid\n"
        f"run_tasks(sleep_and_report_pid, [({str(pids)!r}, 120)] * 2, 2, 'sleep')\n")
    try:
        wait_for(lambda: len(list(pids.glob("*.pid"))) == 2, 120, "two workers")
    finally:
        start = time.monotonic()
        parent.send_signal(signal.SIGKILL)
        parent.communicate()
    workers = [int(p.stem) for p in pids.glob("*.pid")]
    assert len(workers) == 2
    wait_for(lambda: not any(alive(pid) for pid in workers), 10, "the workers to end")
    return Outcome(0, f"workers ended {time.monotonic() - start:.1f} s after the parent's "
                   "SIGKILL")


@case("two runs at once", "a second run while another holds the workspace",
      "in use by another rapomdp run")
def two_runs(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    holder = python_process(
        "import sys, time\nfrom rapomdp.workspace import Workspace\n"
        f"with Workspace({str(ws)!r}).locked():\n"
        "    print('locked', flush=True)\n    time.sleep(120)\n")
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        outcome = cli(["render", "-w", str(ws), "render.views=7"])
        assert f"pid {holder.pid}" in outcome.message, outcome.message
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.communicate()
    after_kill = cli(["render", "-w", str(ws)])
    assert after_kill.exit_code == 0, after_kill.detail
    return _kept(outcome, before, ws)


@case("worker dies", "a worker process killed (SIGKILL) while running a task",
      "a worker process died")
def worker_dies(root: Path) -> Outcome:
    from rapomdp.parallel import WorkerError, run_tasks
    from tests.faults.tasks import die

    try:
        run_tasks(die, [(0,), (1,)], 2, "dying tasks")
    except WorkerError as exc:
        return Outcome(2, str(exc))
    return Outcome(0, "no error")


import tests.faults.cases_workspace  # noqa: E402, F401  (issue 28's data-loss cases register here)
from tests.faults import cases_inputs  # noqa: E402, F401  (issue 28's cases, registered here)
