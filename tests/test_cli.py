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
