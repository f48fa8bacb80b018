"""The bad inputs of issue 28 (crashes, hangs, silent wrong results, the environment and the
weaker faults), as cases of the fault suite: registered through :func:`tests.faults.cases.case`
(``cases.py`` imports this module last), so ``test_faults.py`` and
``benchmarks/fault_table.py`` run them with the others."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.faults.cases import _kept, _tetrahedron, case
from tests.faults.harness import (
    Outcome,
    cached_workspace,
    cli,
    cli_process,
    disk_full,
    foreign_service,
    snapshot,
    wait_for,
)


def _input(root: Path) -> Path:
    folder = root / "input"
    folder.mkdir(exist_ok=True)
    return folder


def _on_workspace(root: Path, args: list[str], words: int = 1) -> Outcome:
    """``rapomdp COMMAND -w W ARGS`` (the command: the first ``words`` of ``args``) on a
    cached workspace; its files must all stay."""
    ws = cached_workspace(root)
    before = snapshot(ws)
    outcome = cli([*args[:words], "-w", str(ws), *args[words:]])
    return _kept(outcome, before, ws)


# -- crashes ---------------------------------------------------------------------------------

@case("Wilson at 0 % and 100 %", "Table 1 rows and the tradeoff figure of methods right 0 of "
      "3, 6, 7, 12 and 10 of 10 times", "every error bar >= 0", succeeds=True)
def wilson_edges(root: Path) -> Outcome:
    from rapomdp.experiment.figures import tradeoff
    from rapomdp.experiment.metrics import TradeoffPoint, summarise

    points = []
    for i, (right, n) in enumerate(((0, 3), (0, 6), (0, 7), (0, 12), (10, 10))):
        summary = summarise(np.arange(n) < right, np.full(n, 0.5), np.ones(n), np.ones(n),
                            np.full(n, float(i)), np.zeros(n, bool), "ra")
        assert summary.accuracy_low <= summary.accuracy <= summary.accuracy_high, summary
        points.append(TradeoffPoint("ra", "lambda", float(i), i == 0, summary))
    path = tradeoff(points, _input(root) / "tradeoff.png")
    assert path.stat().st_size > 0
    return Outcome(0, f"every error bar >= 0; {path.name} written")


for _name, _address, _expect in (
        ("--scheduler garbage", "garbage", "not a dask.distributed scheduler address"),
        ("--scheduler ''", "", "not a dask.distributed scheduler address"),
        ("--scheduler inproc://x", "inproc://x", "no scheduler of this process has that address")):
    @case(_name, f"`rapomdp evaluate -w W --scheduler {_address!r}`", _expect)
    def _scheduler_address(root: Path, address: str = _address) -> Outcome:
        outcome = _on_workspace(root, ["evaluate", "--scheduler", address])
        assert outcome.seconds < 10, f"took {outcome.seconds:.1f} s: checked after running"
        assert not (root / "ws" / "train").exists(), "a stage ran before the check"
        return outcome


for _name, _reply, _expect in (
        ("--scheduler at an HTTP server", None, "no Dask handshake within 10 s"),
        ("--scheduler at another service", b"SSH-2.0-OpenSSH_9.6\r\n" + b"\xff" * 64,
         "the service there is not a Dask scheduler")):
    @case(_name, f"`--scheduler tcp://127.0.0.1:PORT` where {_name.split(' at ')[1]} "
          "answers (a test server)", _expect)
    def _foreign_service(root: Path, reply: bytes | None = _reply) -> Outcome:
        with foreign_service(reply) as address:
            outcome = _on_workspace(root, ["solve", "--scheduler", address])
        assert outcome.seconds < 20, f"took {outcome.seconds:.1f} s"
        return outcome


@case("pomdp export --out DIR", "`rapomdp pomdp export --benchmark 8x3 --out D.pomdp`, D.pomdp "
      "a folder holding a file", "a folder, not a regular file")
def export_to_folder(root: Path) -> Outcome:
    folder = _input(root) / "out.pomdp"
    folder.mkdir()
    (folder / "mine.txt").write_text("the user's")
    before = snapshot(root / "input")
    outcome = cli(["pomdp", "export", "--benchmark", "8x3", "--out", str(folder)])
    assert str(folder) in outcome.message, outcome.message
    return _kept(outcome, before, root / "input")


@case("pomdp export: disk full", "ENOSPC while `pomdp export` writes the .pomdp file",
      "no space left on the device")
def export_disk_full(root: Path) -> Outcome:
    folder = _input(root)
    (folder / "a.pomdp").write_text("the user's earlier file\n")
    before = snapshot(folder)
    with disk_full(folder):
        outcome = cli(["pomdp", "export", "--benchmark", "32x6", "--out",
                       str(folder / "a.pomdp")])
    assert "a.pomdp" in outcome.message, outcome.message
    assert sorted(p.name for p in folder.iterdir()) == ["a.pomdp"]
    return _kept(outcome, before, folder)


@case("--benchmark 100000x3", "`rapomdp pomdp export --benchmark 100000x3` (320 GB of arrays)",
      "the benchmark problem 100000x3 needs about 320 GB, over the memory cap of 4 GB")
def benchmark_too_big(root: Path) -> Outcome:
    outcome = cli(["pomdp", "export", "--benchmark", "100000x3", "--out",
                   str(_input(root) / "big.pomdp")])
    assert outcome.seconds < 5, f"took {outcome.seconds:.1f} s"
    return outcome


@case("pomdp solve /dev/zero", "`rapomdp pomdp solve /dev/zero` (endless, not a regular file)",
      "/dev/zero: not a regular file")
def solve_dev_zero(root: Path) -> Outcome:
    outcome = cli(["pomdp", "solve", "/dev/zero"])
    assert outcome.seconds < 10, f"took {outcome.seconds:.1f} s"
    return outcome


@case("run --workers 0", "`rapomdp run -w W --workers 0`", "--workers must be at least 1, got 0")
def workers_zero(root: Path) -> Outcome:
    return _on_workspace(root, ["run", "--workers", "0"])


@case("preview --width 0", "`rapomdp dataset preview -w W --width 0`",
      "--width must be 8 to 2048 pixels, got 0")
def preview_width_zero(root: Path) -> Outcome:
    return _on_workspace(root, ["dataset", "preview", "--width", "0"], words=2)


@case("preview --elevation-deg nan", "`rapomdp dataset preview -w W --elevation-deg nan` "
      "(drew a blank sheet)", "--elevation-deg must be a finite angle in [-90, 90], got nan")
def preview_elevation_nan(root: Path) -> Outcome:
    outcome = _on_workspace(root, ["dataset", "preview", "--elevation-deg", "nan"], words=2)
    assert not (root / "ws" / "contact_sheet.png").exists()
    return outcome


# -- silent wrong results --------------------------------------------------------------------

_TIGER_LIKE = ("discount: 0.9\nvalues: reward\nstates: 2\nactions: 2\nobservations: 2\n"
               "T: * identity\nO: * uniform\nR: 0 : 0 : * : * 1\n")


def _solve_text(root: Path, text: str) -> Outcome:
    path = _input(root) / "p.pomdp"
    path.write_text(text)
    out = _input(root) / "policy.npz"
    outcome = cli(["pomdp", "solve", str(path), "--timeout", "10", "--out", str(out)])
    assert not out.exists(), "a policy was written"
    return outcome


@case("reward 1e308", "a .pomdp whose reward is 1e308 (bounds NaN, exit 0 before)",
      "reward 1e+308 is outside [-1e+12, 1e+12]")
def reward_huge(root: Path) -> Outcome:
    return _solve_text(root, _TIGER_LIKE + "R: 1 : 1 : * : * 1e308\n")


@case(".pomdp 1_000", "a .pomdp reward written `1_000` (Python reads it, the format does not)",
      "expected a reward but found '1_000'")
def pomdp_underscore(root: Path) -> Outcome:
    return _solve_text(root, _TIGER_LIKE + "R: 1 : 1 : * : * 1_000\n")


def _config_file(root: Path, text: str) -> Outcome:
    path = _input(root) / "c.yaml"
    path.write_text(text)
    outcome = cli(["render", "-w", str(root / "ws"), "-c", str(path)])
    assert not (root / "ws").exists() or not any((root / "ws").iterdir()), "a stage ran"
    return outcome


@case("YAML: a second train:", "a configuration with two `train:` sections (epochs 5, then 25)",
      "the key 'train' is given twice (lines 1 and 4)")
def second_train_section(root: Path) -> Outcome:
    return _config_file(root, "train:\n  epochs: 5\nrender: {views: 6}\ntrain:\n  epochs: 25\n")


@case("YAML: seed twice", "`seed: 1` then `seed: 2` in a configuration file",
      "the key 'seed' is given twice (lines 1 and 2)")
def seed_twice(root: Path) -> Outcome:
    return _config_file(root, "seed: 1\nseed: 2\n")


@case("YAML: !!set of classes", "`classes: !!set {cup, mug, bicycle}` (order by hash seed)",
      "a !!set has no order")
def set_of_classes(root: Path) -> Outcome:
    return _config_file(root, "dataset:\n  classes: !!set {cup, mug, bicycle}\n")


def _generic_meshes(root: Path, names: dict[str, list[str]],
                    text: Callable[[str, int], str] | None = None) -> Path:
    """``input/meshes/<class>/<name>.obj`` tetrahedra (``text(class, i)``: a file's text)."""
    base = _input(root) / "meshes"
    for class_name, files in names.items():
        (base / class_name).mkdir(parents=True)
        for i, name in enumerate(files):
            body = text(class_name, i) if text else _tetrahedron(f"{class_name} {i}")
            (base / class_name / name).write_text(body)
    return base


def _generic_config(root: Path, base: Path) -> Path:
    config = _input(root) / "config.yaml"
    config.write_text(f"dataset: {{source: folder, path: {base}, layout: generic, "
                      "split: {train: 3, volume: 1, test: 1}}\n"
                      "camera: {width: 40, height: 30}\nrender: {views: 6}\n")
    return config


@case("2 GB PLY", "a class folder holding a 2 GB .ply (sparse: never written or read)",
      "2000 MB, over the mesh file cap of 256 MB (limits.mesh_file_mb); not read")
def huge_ply(root: Path) -> Outcome:
    base = _generic_meshes(root, {c: [f"m{i}.obj" for i in range(5)] for c in ("cone", "wedge")})
    (base / "cone" / "m0.obj").unlink()
    with open(base / "cone" / "m0.ply", "wb") as handle:
        handle.truncate(2 * 10**9)
    outcome = cli(["dataset", "-w", str(root / "ws"), "-c", str(_generic_config(root, base))])
    assert outcome.seconds < 30, f"took {outcome.seconds:.1f} s"
    return outcome


# -- the gymnasium environment ---------------------------------------------------------------

_ROBOT_TEMPLATE: Path | None = None


def _env(root: Path, **options: object):
    """The environment of a cached workspace whose robot stage is done (built once)."""
    global _ROBOT_TEMPLATE
    from rapomdp.experiment.env import ActiveRecognitionEnv

    if _ROBOT_TEMPLATE is None:
        base = Path(tempfile.mkdtemp(prefix="rapomdp-faults-env-"))
        ws = cached_workspace(base)
        result = cli(["run", "-w", str(ws), "--until", "robot"])
        assert result.exit_code == 0, result.detail
        _ROBOT_TEMPLATE = ws
    shutil.copytree(_ROBOT_TEMPLATE, root / "ws")
    return ActiveRecognitionEnv.from_workspace(root / "ws", seed=0, **options)  # type: ignore[arg-type]


def _refused(make: Callable[[], object]) -> Outcome:
    try:
        make()
    except ValueError as exc:
        return Outcome(2, str(exc))
    return Outcome(0, "accepted")


@case("env.step(np.array(3))", "`env.step(np.array(3))`, which action_space.contains accepts",
      "accepted as action_space.contains accepts it", succeeds=True)
def env_zero_d_action(root: Path) -> Outcome:
    env = _env(root)
    env.reset(seed=0)
    assert env.action_space.contains(np.array(3))
    _, reward, *_ = env.step(np.array(3))  # type: ignore[arg-type]
    return Outcome(0, f"accepted as action_space.contains accepts it (reward {reward:.3f})")


@case("env reset start=True", "`env.reset(options={'start': True})`",
      "reset: start viewpoint True is not in [0, 16) (a whole number)")
def env_start_true(root: Path) -> Outcome:
    env = _env(root)
    return _refused(lambda: env.reset(options={"start": True}))


@case("env reset model=True", "`env.reset(options={'model': True})` (meant model 1)",
      "reset: model True is not a scene index in [0, 3) (a whole number)")
def env_model_true(root: Path) -> Outcome:
    env = _env(root)
    return _refused(lambda: env.reset(options={"model": True}))


for _value in (float("inf"), float("nan"), 2.7):
    @case(f"env max_moves={_value}", f"`ActiveRecognitionEnv.from_workspace(W, max_moves="
          f"{_value})`" + (" (became 2)" if _value == 2.7 else " (crashed)"),
          f"max_moves must be a whole number of at least 1, got {_value}")
    def _env_max_moves(root: Path, value: float = _value) -> Outcome:
        return _refused(lambda: _env(root, max_moves=value))


# -- weaker ----------------------------------------------------------------------------------

@case("pomdp errors on stderr", "`rapomdp pomdp solve bad.pomdp` (its error went to stdout)",
      "stdout empty; stderr: error: ")
def pomdp_stderr(root: Path) -> Outcome:
    path = _input(root) / "bad.pomdp"
    path.write_text("discount: 0.9\nstates: 2\nactions: 2\nobservations: 2\nT: 7 : 0 : 0 1\n")
    child = cli_process(["pomdp", "solve", str(path)])
    out, err = child.communicate(timeout=60)
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1, (out, err)
    return Outcome(child.returncode, f"stdout empty; stderr: {lines[0]}")


@case("Ctrl-C", "SIGINT to the process group (as Ctrl-C sends it) while `rapomdp render` "
      "and its 2 workers render", "exit 130; stderr ends: error: interrupted", succeeds=True)
def ctrl_c(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    child = cli_process(["render", "-w", str(ws), "--workers", "2", "render.views=3000"],
                        start_new_session=True,
                        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        scratch = ws / ".rapomdp-tmp"  # where a stage's new folder grows
        wait_for(lambda: scratch.is_dir() and any(
            p.name.startswith("render.tmp-") and any(p.rglob("*.npz"))
            for p in scratch.iterdir()), 120, "the workers' first images")
    finally:
        os.killpg(child.pid, signal.SIGINT)
        _, err = child.communicate(timeout=60)
    last = err.strip().splitlines()[-1]
    outcome = Outcome(0 if child.returncode == 130 else child.returncode,
                      f"exit {child.returncode}; stderr ends: {last}",
                      traceback="Traceback (most recent call last)" in err, detail=err)
    rerun = cli(["render", "-w", str(ws)])
    assert rerun.exit_code == 0, rerun.detail
    return _kept(outcome, before, ws)


@case("disk full: npz write", "ENOSPC from inside an .npz (as write(2) gives it: no file "
      "name) while render writes its images", "no space left on the device")
def full_disk_unnamed(root: Path) -> Outcome:
    ws = cached_workspace(root)
    before = snapshot(ws)
    real_write = zipfile._ZipWriteFile.write  # type: ignore[attr-defined]
    written = [0]

    def fill(self: object, data: bytes) -> int:
        written[0] += len(data)
        if written[0] > 20_000:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(self, data)

    zipfile._ZipWriteFile.write = fill  # type: ignore[attr-defined]
    try:
        outcome = cli(["render", "-w", str(ws), "--workers", "1", "render.views=7"])
    finally:
        zipfile._ZipWriteFile.write = real_write  # type: ignore[attr-defined]
    assert "(unknown file)" not in outcome.message and ".npz" in outcome.message, \
        outcome.message
    return _kept(outcome, before, ws)


@case("250-byte mesh name", "a mesh file whose name is 250 bytes of UTF-8 (123 x 'é'; the "
      "temporary name overflowed 255)", "render     done", succeeds=True)
def long_mesh_name(root: Path) -> Outcome:
    long = "é" * 123 + ".obj"
    base = _generic_meshes(root, {c: [long if c == "cone" and i == 0 else f"m{i}.obj"
                                      for i in range(5)] for c in ("cone", "wedge")})
    outcome = cli(["render", "-w", str(root / "ws"), "-c", str(_generic_config(root, base))])
    data = json.loads((root / "ws" / "dataset" / "dataset.json").read_text())
    assert any(m["id"] == long[:-4] for m in data["models"]), [m["id"] for m in data["models"]]
    outcome.message = next((line for line in outcome.detail.splitlines() if "render " in line),
                           outcome.message)
    return outcome


@case("config -w FILE", "`rapomdp config -w FILE` (printed the defaults)",
      "is a file, not a folder")
def config_of_a_file(root: Path) -> Outcome:
    path = _input(root) / "notes.txt"
    path.write_text("the user's notes\n")
    before = snapshot(root / "input")
    return _kept(cli(["config", "-w", str(path)]), before, root / "input")


@case("test model = train file", "a class whose five model files have the same bytes (its "
      "test model is a training model)", "have the same bytes as a model of another role",
      succeeds=True)
def duplicate_across_roles(root: Path) -> Outcome:
    base = _generic_meshes(root, {c: [f"m{i}.obj" for i in range(5)] for c in ("cone", "wedge")},
                           text=lambda c, i: _tetrahedron(c if c == "cone" else f"{c} {i}"))
    outcome = cli(["dataset", "-w", str(root / "ws"), "-c", str(_generic_config(root, base))])
    warnings = [line for line in outcome.detail.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, outcome.detail
    outcome.message = warnings[0]
    return outcome
