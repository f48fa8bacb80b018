import json
import re
from pathlib import Path

import yaml
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.config import Config
from tests.conftest import tiny_config

runner = CliRunner()


def test_config_prints_the_default() -> None:
    result = runner.invoke(app, ["config"])
    assert result.exit_code == 0
    assert Config.model_validate(yaml.safe_load(result.stdout)) == Config()
    plain = runner.invoke(app, ["config", "--plain"])
    assert plain.stdout == Config().to_yaml() and "#" not in plain.stdout


def test_config_comments_say_what_each_key_is_and_its_unit() -> None:
    lines = runner.invoke(app, ["config"]).stdout.splitlines()
    assert "  radius_m: 0.2  # bounding-sphere radius after normalisation; unit: metres" in lines
    assert any(line.startswith("  wrong_declaration_cost_m: 8.0  # lambda (Eq. 1)")
               for line in lines)
    assert "    missing_start_deg: 70.0  # unit: degrees" in lines
    assert any(line.startswith("    joint_weight_m_per_rad: 0.0") and
               line.endswith("unit: metres per radian") for line in lines)
    # a section's comment is its docstring's first paragraph, above its key
    camera = lines.index("camera:")
    assert lines[camera - 1] == ("# The depth camera: an Asus Xtion Pro Live rendered at "
                                 "width x height.")


def test_version_and_command_names_are_the_stage_names() -> None:
    from rapomdp import __version__
    from rapomdp.pipeline import STAGE_NAMES

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.stdout == f"rapomdp {__version__}\n"
    import typer.main

    group = typer.main.get_command(app)
    shown = {name for name, command in group.commands.items() if not command.hidden}
    assert set(STAGE_NAMES) - {"crossfit"} <= shown  # the crossfit stage is retired
    assert "crossfit" not in group.commands
    # the former spelling still runs the same command, but is not listed
    assert group.commands["evaluate-classifier"].hidden
    alias, command = group.commands["evaluate-classifier"], group.commands["classifier_eval"]
    assert alias.callback.__wrapped__ is command.callback.__wrapped__
    assert "evaluate-classifier" not in runner.invoke(app, ["--help"]).stdout


def test_the_retired_crossfit_command_is_an_unknown_command(tmp_path: Path) -> None:
    result = runner.invoke(app, ["crossfit", "-w", str(tmp_path / "ws")])
    assert result.exit_code == 2
    assert "No such command 'crossfit'" in result.output
    assert not (tmp_path / "ws").exists()


def test_force_is_a_flag_everywhere_and_redo_names_a_stage(tmp_path: Path) -> None:
    import typer.main

    group = typer.main.get_command(app)
    for name, command in group.commands.items():
        for param in command.params:
            if "--force" in param.opts:
                assert param.is_flag, name
    path = tmp_path / "tiny.yaml"
    path.write_text(tiny_config().to_yaml())
    base = ["run", "-w", str(tmp_path / "ws"), "-c", str(path), "--until", "render"]
    assert runner.invoke(app, base).exit_code == 0
    cached = runner.invoke(app, base).output
    assert "dataset    cached" in cached and "render     cached" in cached
    redo = runner.invoke(app, [*base, "--redo", "render"]).output
    assert "dataset    cached" in redo and "render     done" in redo
    forced = runner.invoke(app, [*base, "--force"]).output
    assert "dataset    done" in forced and "render     done" in forced


def test_status_of_a_missing_workspace_is_an_error(tmp_path: Path) -> None:
    result = runner.invoke(app, ["status", "-w", str(tmp_path / "mistyped")])
    assert result.exit_code == 2
    assert f"workspace {tmp_path / 'mistyped'} does not exist" in result.output
    assert not (tmp_path / "mistyped").exists()


def test_bad_config_exits_2_naming_the_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("camera:\n  widht: 10\n")
    result = runner.invoke(app, ["run", "-w", str(tmp_path / "ws"), "-c", str(path)])
    assert result.exit_code == 2
    assert "camera.widht: unknown key" in result.output
    assert not (tmp_path / "ws" / "manifest.json").exists()


def test_run_status_and_preview(tmp_path: Path) -> None:
    path = tmp_path / "tiny.yaml"
    path.write_text(tiny_config().to_yaml())
    ws = tmp_path / "ws"
    result = runner.invoke(app, ["render", "-w", str(ws), "-c", str(path)])
    assert result.exit_code == 0, result.output
    assert (ws / "render" / "render.json").exists()
    assert yaml.safe_load((ws / "config.yaml").read_text())["render"]["views"] == 6
    again = runner.invoke(app, ["run", "-w", str(ws), "-c", str(path), "--until", "render"])
    assert "cached" in again.output
    sheet = tmp_path / "sheet.png"
    preview = runner.invoke(app, ["dataset", "preview", "-w", str(ws), "--out", str(sheet),
                                  "--width", "64"])
    assert preview.exit_code == 0, preview.output
    assert sheet.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # one tile per model in a fixed grid: a class a row, 1.9 x 1.55 in a tile at 110 dpi (the
    # tight bounding box trims the margins only)
    import matplotlib.image

    from rapomdp.data.dataset import load_dataset
    from rapomdp.data.preview import TILE_IN

    dataset = load_dataset(ws / "dataset")
    rows = len(dataset.classes)
    cols = max(sum(m.class_name == c for m in dataset.models) for c in dataset.classes)
    height, width = matplotlib.image.imread(sheet).shape[:2]
    assert 0.8 < height / (TILE_IN[1] * rows * 110) < 1.3
    assert 0.8 < width / (TILE_IN[0] * cols * 110) < 1.5
    status = runner.invoke(app, ["status", "-w", str(ws)])
    assert "dataset" in status.output and "render" in status.output


def test_preview_without_a_dataset_says_how_to_make_one(tmp_path: Path) -> None:
    result = runner.invoke(app, ["dataset", "preview", "-w", str(tmp_path)])
    assert result.exit_code == 2
    assert "stage 'dataset' has not been run here" in result.output


def test_robot_command_reports_reachability(tmp_path: Path) -> None:
    path = tmp_path / "tiny.yaml"
    path.write_text(tiny_config().to_yaml())
    result = runner.invoke(app, ["robot", "-w", str(tmp_path / "ws"), "-c", str(path)])
    assert result.exit_code == 0, result.output
    assert "/16 viewpoints reachable" in result.output
    assert (tmp_path / "ws" / "robot" / "robot.npz").exists()


def test_console_script_exits_with_the_commands_status_and_no_teardown_noise(tmp_path):
    import os
    import subprocess
    import sys

    config = tmp_path / "tiny.yaml"
    config.write_text(tiny_config().to_yaml())
    run = [sys.executable, "-m", "rapomdp.cli", "robot", "-w", str(tmp_path / "ws"),
           "-c", str(config)]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(run, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "leaked" not in done.stderr and "viewpoints reachable" in done.stderr
    assert (tmp_path / "ws" / "robot" / "robot.npz").exists()
    bad = subprocess.run(run[:-1] + [str(tmp_path / "missing.yaml")], capture_output=True,
                         text=True, env=env, timeout=300)
    assert bad.returncode == 2 and "missing.yaml: cannot read" in bad.stderr


def test_the_workspace_keeps_its_configuration(tmp_path: Path) -> None:
    path = tmp_path / "tiny.yaml"
    path.write_text(tiny_config().to_yaml())
    ws = tmp_path / "ws"
    assert runner.invoke(app, ["dataset", "-w", str(ws), "-c", str(path)]).exit_code == 0
    recorded = (ws / "config.yaml").read_text()
    shown = runner.invoke(app, ["config", "-w", str(ws), "train.epochs=5"])
    assert shown.exit_code == 0, shown.output
    assert yaml.safe_load(shown.stdout)["train"]["epochs"] == 5
    assert yaml.safe_load(shown.stdout)["seed"] == tiny_config().seed
    assert (ws / "config.yaml").read_text() == recorded, "config only shows"
    again = runner.invoke(app, ["dataset", "-w", str(ws)])
    assert again.exit_code == 0 and "dataset    cached" in again.output
    changed = runner.invoke(app, ["render", "-w", str(ws), "seed=4"])
    assert changed.exit_code == 0, changed.output
    assert "1 recorded stage(s) differ:\n  dataset: seed 3 -> 4" in changed.output
    assert yaml.safe_load((ws / "config.yaml").read_text())["seed"] == 4
    kept = runner.invoke(app, ["run", "-w", str(ws), "--until", "dataset", "render.views=9"])
    assert kept.exit_code == 0 and "config.yaml is unchanged: this command made no" in kept.output
    assert yaml.safe_load((ws / "config.yaml").read_text())["render"]["views"] == 6
    refused = runner.invoke(app, ["dataset", "-w", str(ws), "-c", str(path)])
    assert refused.exit_code == 2
    assert "pass --reconfigure to redo 2 stage(s)" in refused.output
    assert "dataset: seed 4 -> 3" in refused.output


def test_workers_and_threads_reach_the_stages_as_one_run_context(tmp_path: Path,
                                                                 monkeypatch) -> None:
    from rapomdp import pipeline
    from rapomdp.context import RunContext

    seen: list[RunContext] = []

    def record(config, workspace, until, force, on_result, context):  # noqa: ANN001
        seen.append(context)
        return []

    monkeypatch.setattr(pipeline, "run_pipeline", record)  # the CLI imports it lazily
    result = runner.invoke(app, ["run", "-w", str(tmp_path / "ws"), "--until", "dataset",
                                 "--workers", "3", "--threads", "2"])
    assert result.exit_code == 0, result.output
    assert seen == [RunContext(workers=3, threads=2, progress=True)]
    runner.invoke(app, ["train", "-w", str(tmp_path / "ws")])
    assert seen[-1] == RunContext()
    runner.invoke(app, ["train", "-w", str(tmp_path / "ws"), "--workers", "3"])
    assert seen[-1] == RunContext(workers=3)  # an ensemble's members spread over them


def test_fig1_view_help_says_what_write_fig1_picks() -> None:
    """`figure fig1 --view` defaults to awareness.figures.most_salient_view: the training view
    nearest the test viewpoint of highest score, the most object pixels only when every score
    is equal."""
    import typer.main

    fig1 = typer.main.get_command(app).commands["figure"].commands["fig1"]
    (view,) = [p for p in fig1.params if "--view" in p.opts]
    assert "nearest the test viewpoint of highest score" in view.help
    assert "where every score is equal, the one with the most object pixels" in view.help


# --- help texts, status, errors, the end of a run, the demo -----------------------------------



def _commands() -> list[tuple[list[str], object]]:
    """Every command of the app (sub-apps' too), with its path of names."""
    import typer.main

    found = []

    def walk(command: object, path: list[str]) -> None:
        found.append((path, command))
        for name, sub in getattr(command, "commands", {}).items():
            if not sub.hidden:
                walk(sub, [*path, name])

    walk(typer.main.get_command(app), [])
    return found


def test_help_paragraphs_wrap_at_the_terminal_width_not_at_the_docstrings_breaks() -> None:
    width = 100
    for path, _ in _commands():
        result = runner.invoke(app, [*path, "--help"], env={"COLUMNS": str(width)})
        assert result.exit_code == 0, path
        prose = result.output.split("╭")[0].splitlines()
        lines = [line.strip() for line in prose]
        for this, after in zip(lines, lines[1:], strict=False):
            if this and after and not this.startswith("Usage:"):
                # the next line's first word would not have fitted on this one
                assert len(this) + 1 + len(after.split()[0]) > width - 4, (path, this)
    run_help = runner.invoke(app, ["run", "--help"], env={"COLUMNS": "100"}).output
    assert "rapomdp run -w W reruns what changed," in run_help
    assert "dataset.classes=[cup,mug]" in run_help  # not taken for markup


#: Figures a run can change, typed into a help text or a configuration description: percents,
#: counts of classes / episodes / test models, "x 4 = 512" sums, correlations, measured times.
TYPED_FIGURE = re.compile(
    r"\d+(\.\d+)?\s?%|\b\d+\s+(classes|episodes|images|test models)\b|=\s*\d{2,}\b"
    r"|\br\s?=\s?0?\.\d|\b\d+(\.\d+)?\s?(s|min|minutes|seconds|hours?)\b")


def test_no_help_text_holds_what_markdown_would_take_for_a_tag() -> None:
    # typer's markdown mode drops <word>: "S/<configuration>/seed-<seed>" printed as "S//seed-"
    tag = re.compile(r"<[A-Za-z_][^<>]*>")
    found = [f"rapomdp {' '.join(path)}: {m.group(0)}"
             for path, command in _commands()
             for text in [command.help or ""] + [getattr(p, "help", None) or ""
                                                 for p in command.params]
             for m in tag.finditer(text)]
    assert found == []
    shown = runner.invoke(app, ["study", "--help"], env={"COLUMNS": "200"}).output
    assert "S/CONFIGURATION/seed-N" in shown


def _config_texts() -> list[tuple[str, str]]:
    """What `rapomdp config` comments with: each section's first paragraph, each key's
    description."""
    from pydantic import BaseModel

    texts = []

    def walk(model: BaseModel, prefix: str) -> None:
        doc = (type(model).__doc__ or "").strip().split("\n\n")[0]
        texts.append((prefix or "(top level)", " ".join(doc.split())))
        for name, field in type(model).model_fields.items():
            value = getattr(model, name)
            if isinstance(value, BaseModel):
                walk(value, f"{prefix}{name}.")
            elif field.description:
                texts.append((prefix + name, " ".join(field.description.split())))

    walk(Config(), "")
    return texts


def test_no_figure_a_run_can_change_is_typed_into_help_or_config_descriptions() -> None:
    found = []
    for path, command in _commands():
        texts = [command.help or ""] + [getattr(p, "help", None) or "" for p in command.params]
        found += [f"rapomdp {' '.join(path)}: {m.group(0)!r} in {' '.join(t.split())[:80]!r}"
                  for t in texts for m in TYPED_FIGURE.finditer(" ".join(t.split()))]
    found += [f"config {where}: {m.group(0)!r} in {text[:80]!r}"
              for where, text in _config_texts() for m in TYPED_FIGURE.finditer(text)]
    assert found == []
    # the pattern sees what it is for
    for typed in ("57.0 %", "32 classes", "560 episodes", "x 4 = 512", "r = 0.989",
                  "under 5 min", "4 test models"):
        assert TYPED_FIGURE.search(typed), typed


def _tiny_dataset(tmp_path: Path) -> tuple[Path, Path]:
    path = tmp_path / "tiny.yaml"
    path.write_text(tiny_config().to_yaml())
    ws = tmp_path / "ws"
    assert runner.invoke(app, ["dataset", "-w", str(ws), "-c", str(path)]).exit_code == 0
    return path, ws


def test_status_json_matches_the_manifest_and_the_table_fits_80_columns(tmp_path: Path) -> None:
    _, ws = _tiny_dataset(tmp_path)
    shown = runner.invoke(app, ["status", "-w", str(ws), "--json"])
    assert shown.exit_code == 0, shown.output
    data = json.loads(shown.stdout)
    manifest = json.loads((ws / "manifest.json").read_text())["stages"]
    from rapomdp.pipeline import STAGE_NAMES

    assert [s["name"] for s in data["stages"]] == STAGE_NAMES
    assert data["workspace"] == str(ws) and data["config_missing"] is False
    for stage in data["stages"]:
        record = manifest.get(stage["name"])
        if record is None:
            assert stage["state"] == "not run" and stage["key"] is None
            continue
        assert stage["state"] == "current" and stage["reasons"] == []
        assert (stage["key"], stage["files"], stage["seconds"], stage["finished"]) == (
            record["key"], len(record["files"]), record["seconds"], record["finished"])
    assert {s["name"] for s in data["stages"] if s["state"] != "not run"} == set(manifest)
    # a changed configuration: the stage is stale, and says why
    config = yaml.safe_load((ws / "config.yaml").read_text())
    config["seed"] = 11
    (ws / "config.yaml").write_text(yaml.safe_dump(config))
    stale = json.loads(runner.invoke(app, ["status", "-w", str(ws), "--json"]).stdout)
    assert stale["stages"][0]["state"] == "stale"
    assert stale["stages"][0]["reasons"] == ["seed 3 -> 11"]
    table = runner.invoke(app, ["status", "-w", str(ws)], env={"COLUMNS": "80"})
    assert table.exit_code == 0
    lines = table.output.splitlines()
    assert max(len(line) for line in lines) <= 80
    finished = manifest["dataset"]["finished"][:16].replace("T", " ")
    row = next(line for line in lines if line.startswith("│ dataset"))
    assert "stale" in row and finished in row  # one line, the time to the minute
    seconds = manifest["dataset"]["seconds"]
    assert f"{seconds:.1f} s" in row
    assert "1 stale stage(s)" in table.output and "dataset: seed 3 -> 11" in table.output


def test_stage_durations_read_as_a_person_would() -> None:
    from rapomdp.cli import _duration

    assert [_duration(s) for s in (0.004, 3.016, 42.4, 555.0, 7322.0)] == [
        "0.0 s", "3.0 s", "42 s", "9 min 15 s", "2 h 02 min"]


def test_a_mistyped_stage_or_key_is_named_with_what_was_meant(tmp_path: Path) -> None:
    result = runner.invoke(app, ["run", "-w", str(tmp_path / "ws"), "--until", "evalute"])
    assert result.exit_code == 2
    assert "unknown stage 'evalute' (did you mean 'evaluate'?)" in result.output
    assert not (tmp_path / "ws").exists()
    typo = runner.invoke(app, ["config", "train.epohcs=5"])
    assert typo.exit_code == 2
    assert "None" not in typo.output
    assert ("error: the default configuration with train.epohcs=5: invalid configuration"
            in typo.output)
    assert "train.epohcs: unknown key (did you mean train.epochs?)" in typo.output
    path = tmp_path / "typo.yaml"
    path.write_text("trian:\n  epochs: 3\n")
    in_file = runner.invoke(app, ["run", "-w", str(tmp_path / "ws2"), "-c", str(path)])
    assert f"error: {path}: invalid configuration" in in_file.output
    assert "trian: unknown key (did you mean train?)" in in_file.output


def test_a_folder_dataset_prints_its_split_and_one_warning_line_per_problem(tmp_path: Path) -> None:
    import trimesh

    root = tmp_path / "meshes"
    for c, (name, count) in enumerate({"bench": 5, "lamp": 7, "vase": 3}.items()):
        for i in range(count):
            (root / name).mkdir(parents=True, exist_ok=True)
            trimesh.creation.box(extents=(0.1 + i * 0.01, 0.2 + c * 0.01, 0.4)).export(
                root / name / f"m{i}.stl")
    args = ["dataset", "-w", str(tmp_path / "ws")]
    config = tmp_path / "folder.yaml"
    config.write_text(yaml.safe_dump({"dataset": {"source": "folder", "path": str(root)}}))
    refused = runner.invoke(app, [*args, "-c", str(config)])
    assert refused.exit_code == 2
    assert ("error: class 'vase' has 3 model(s); split: auto needs at least 5 a class (3 train, "
            "1 volume, 1 test)") in refused.output
    config.write_text(yaml.safe_dump({"dataset": {"source": "folder", "path": str(root),
                                                  "too_few_models": "drop"}}))
    done = runner.invoke(app, [*args, "-c", str(config)], env={"COLUMNS": "200"})
    assert done.exit_code == 0, done.output
    lines = done.output.splitlines()
    assert "  split: auto (every model used); held-out groups (volume models of the smallest " \
           "class): 1 (too few for a leave-one-group-out choice)" in lines
    assert "  3 train, 2 volume, 2 test model(s) per class (1 classes: lamp)" in lines
    warnings = [line for line in lines if line.startswith("warning:")]
    assert warnings == ["warning: class 'vase' has 3 model(s); split: auto needs at least 5 a "
                        "class (3 train, 1 volume, 1 test): class(es) left out"]
    assert "UserWarning" not in done.output and "stage.run(" not in done.output


def test_make_demo_runs_the_demo_command() -> None:
    makefile = (Path(__file__).parents[1] / "Makefile").read_text()
    recipe = makefile.split("\ndemo: ")[1].split("\n\n")[0]
    assert "rapomdp demo --workspace $(DEMO_WORKSPACE)" in recipe
    assert "rapomdp run" not in recipe and "dataset preview" not in recipe


def test_dataset_build_writes_the_mesh_set_and_refuses_what_it_cannot_build(
        tmp_path: Path) -> None:
    out = tmp_path / "mesh-set"
    result = runner.invoke(app, ["dataset", "build", "mesh-set", "--out", str(out),
                                 "--models", "2", "--seed", "3"])
    assert result.exit_code == 0, result.output
    assert "wrote 22 meshes of 11 classes" in result.output
    assert sorted(p.name for p in out.iterdir() if p.is_dir())[:3] == ["arch", "bench", "dumbbell"]
    assert len(list(out.rglob("*.stl"))) == 22
    refusals = {
        "held back": ["real-cad", "--out", str(tmp_path / "x"), "--source",
                      str(tmp_path / "sweethome3d-models")],
        "does not take --set": ["mesh-set", "--out", str(tmp_path / "x"), "--set", "second"],
        "no dataset builder 'modelnet'": ["modelnet", "--out", str(tmp_path / "x")],
        "--set must be one of first, second": ["real-cad", "--out", str(tmp_path / "x"),
                                               "--set", "third", "--source", str(tmp_path)],
    }
    for message, args in refusals.items():
        refused = runner.invoke(app, ["dataset", "build", *args])
        assert refused.exit_code == 2, (args, refused.output)
        assert message in refused.output
    assert not (tmp_path / "x").exists()


def test_dataset_build_help_says_what_each_builder_needs() -> None:
    result = runner.invoke(app, ["dataset", "build", "--help"], terminal_width=200)
    assert result.exit_code == 0
    text = " ".join(result.output.split())
    assert "real-cad: electronic components from Debian's kicad-packages3d" in text
    assert "Needs apt-get and dpkg-deb" in text and "about a minute a set" in text
    assert "mesh-set: objects composed of primitives" in text and "Takes seconds" in text
    assert "sweethome3d*: refused by name" in text
