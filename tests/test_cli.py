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
    assert set(STAGE_NAMES) <= shown
    # the former spelling still runs the same command, but is not listed
    assert group.commands["evaluate-classifier"].hidden
    alias, command = group.commands["evaluate-classifier"], group.commands["classifier_eval"]
    assert alias.callback.__wrapped__ is command.callback.__wrapped__
    assert "evaluate-classifier" not in runner.invoke(app, ["--help"]).stdout


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


def test_fig1_view_help_says_what_write_fig1_picks() -> None:
    """`figure fig1 --view` defaults to awareness.figures.most_salient_view: the training view
    nearest the test viewpoint of highest score, the most object pixels only when every score
    is equal."""
    import typer.main

    fig1 = typer.main.get_command(app).commands["figure"].commands["fig1"]
    (view,) = [p for p in fig1.params if "--view" in p.opts]
    assert "nearest the test viewpoint of highest score" in view.help
    assert "where every score is equal, the one with the most object pixels" in view.help
