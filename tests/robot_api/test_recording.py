"""Recorded sequences: a recording of the simulator's closed loop, replayed through the robot
API, repeats that episode; a broken recording is refused naming its file and row."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.robot_api.recognizer import ActiveRecognizer
from rapomdp.robot_api.recording import (
    META_FILE,
    POSES_FILE,
    RecordingError,
    load_recording,
    record_episode,
    replay,
    replay_summary,
    replay_table,
    write_recording,
)


@pytest.fixture(scope="module")
def recorded(pipeline_workspace, tmp_path_factory):
    """The tiny workspace's RA-POMDP episode on its first test model from the evaluate stage's
    first start, recorded."""
    ws, _ = pipeline_workspace
    out = tmp_path_factory.mktemp("recording") / "episode"
    return record_episode(ws.root, out, "ra")


@pytest.mark.parametrize("method", ["ra", "random"])
def test_a_replayed_recording_repeats_the_closed_loops_episode(pipeline_workspace, tmp_path,
                                                               method: str) -> None:
    """The episode recorded from the simulator is the evaluate stage's (same views, same
    declaration); replayed frame by frame through the object it chooses the same viewpoints
    step by step and declares the same class at the same confidence (1e-6)."""
    ws, config = pipeline_workspace
    recording, episode = record_episode(ws.root, tmp_path / "rec", method)
    assert len(recording) == len(episode.viewpoints)
    assert recording.depth_unit == "m" and recording.true_class in ("cup", "bicycle", "teapot")
    table = EpisodeTable.load(ws.require("evaluate") / EPISODES_FILE)
    mine = [e for e in np.flatnonzero(table.method == method)
            if str(table.model[e]) == recording.source["model"]
            and int(table.start[e]) == recording.source["start"]]
    assert len(mine) == 1
    assert episode.viewpoints.tolist() == table.viewpoints_of(mine[0]).tolist()
    assert episode.declared == int(table.declared[mine[0]])

    recognizer = ActiveRecognizer.load(ws.root, method)
    result = replay(recognizer, load_recording(tmp_path / "rec"))
    assert result.chosen == episode.viewpoints.tolist()
    moves = [s.next_viewpoint for s in result.steps if s.action == "move"]
    assert moves == episode.viewpoints[1:].tolist()
    for step, energy in zip(result.steps[:-1], episode.move_energy, strict=True):
        assert step.energy_m == pytest.approx(energy, abs=1e-12)
    np.testing.assert_allclose(np.stack([s.observation.belief for s in result.steps]),
                               episode.beliefs, atol=1e-6)
    assert result.declared_class == recognizer.classes[episode.declared]
    assert result.declared_confidence == pytest.approx(
        float(episode.beliefs[-1][episode.declared]), abs=1e-6)
    assert result.unused_frames == 0
    table = replay_table(result, recognizer, recording)
    assert table["same_as_recorded_closed_loop"] is True
    assert [s["at_chosen_viewpoint"] for s in table["steps"]] == [None] + [True] * (
        len(recording) - 1)


def test_a_recording_that_ends_before_the_declaration_is_said(recorded, recognizer,
                                                              tmp_path) -> None:
    """Two frames of a longer episode: the replay makes two steps, declares nothing and says
    so; the same two frames in the other order are counted where they were taken."""
    recording, episode = recorded
    assert len(recording) > 2
    depths = [recording.depth(0), recording.depth(1)]
    short = write_recording(tmp_path / "short", depths, recording.poses[:2],
                            recording.intrinsics, recording.true_class,
                            {**recording.source, "seed": None})
    result = replay(recognizer, short)
    assert result.declared_class is None and len(result.steps) == 2
    assert result.chosen == episode.viewpoints[:2].tolist()
    table = replay_table(result, recognizer, short)
    assert table["same_as_recorded_closed_loop"] is False
    assert replay_summary(table)[-2] == "no declaration: the 2 frames ran out first"
    swapped = write_recording(tmp_path / "swapped", depths[::-1], recording.poses[1::-1],
                              recording.intrinsics)
    steps = replay_table(replay(recognizer, swapped), recognizer, swapped)["steps"]
    assert [s["viewpoint"] for s in steps] == episode.viewpoints[1::-1].tolist()
    assert steps[1]["at_chosen_viewpoint"] is (steps[0]["next_viewpoint"]
                                               == int(episode.viewpoints[0]))


def test_the_recording_format_on_disk(recorded) -> None:
    recording, episode = recorded
    folder = recording.folder
    names = sorted(p.name for p in folder.iterdir())
    frames = [f"{i:03d}.npy" for i in range(len(episode.viewpoints))]
    assert names == sorted([*frames, POSES_FILE, META_FILE])
    meta = json.loads((folder / META_FILE).read_text())
    assert meta["intrinsics"]["width"] == 64 and meta["intrinsics"]["height"] == 48
    assert meta["depth_unit"] == "m" and meta["source"]["method"] == "ra"
    rows = (folder / POSES_FILE).read_text().splitlines()
    assert rows[0].split(",")[:3] == ["frame", "m00", "m01"] and len(rows) == len(frames) + 1
    first = np.load(folder / "000.npy", allow_pickle=False)
    assert first.dtype == np.float32 and first.shape == (48, 64)
    np.testing.assert_array_equal(recording.poses[:, 3], np.tile([0, 0, 0, 1.0],
                                                                 (len(frames), 1)))


def copy_recording(recording, folder: Path) -> Path:
    folder.mkdir()
    for path in recording.folder.iterdir():
        (folder / path.name).write_bytes(path.read_bytes())
    return folder


def test_millimetre_frames_as_npy_and_png_replay_the_same(recorded, recognizer,
                                                          tmp_path) -> None:
    """The recording's frames rounded to uint16 millimetres, once as .npy and once as 16-bit
    .png: both read back bit for bit and replay to the same choices."""
    from PIL import Image

    recording, _ = recorded
    answers = []
    for suffix in (".npy", ".png"):
        folder = copy_recording(recording, tmp_path / suffix[1:])
        lines = (folder / POSES_FILE).read_text().splitlines()
        for index, name in enumerate(recording.frames):
            mm = np.round(recording.depth(index) * 1000.0).astype(np.uint16)
            (folder / name).unlink()
            new = Path(name).with_suffix(suffix).name
            if suffix == ".npy":
                np.save(folder / new, mm)
            else:
                Image.fromarray(mm).save(folder / new)
            lines[index + 1] = lines[index + 1].replace(name, new)
        (folder / POSES_FILE).write_text("\n".join(lines) + "\n")
        meta = json.loads((folder / META_FILE).read_text())
        (folder / META_FILE).write_text(json.dumps({**meta, "depth_unit": "mm"}))
        again = load_recording(folder)
        assert again.depth(0).dtype == np.uint16
        np.testing.assert_array_equal(
            again.depth(0), np.round(recording.depth(0) * 1000.0).astype(np.uint16))
        answers.append(replay(recognizer, again, np.random.default_rng(0)))
    assert answers[0].chosen == answers[1].chosen
    assert answers[0].declared_confidence == answers[1].declared_confidence


def broken(recorded, tmp_path: Path, change) -> Path:
    folder = copy_recording(recorded[0], tmp_path / "broken")
    change(folder)
    return folder


def edit_row(row: int, edit):
    def change(folder: Path) -> None:
        lines = (folder / POSES_FILE).read_text().splitlines()
        lines[row] = edit(lines[row])
        (folder / POSES_FILE).write_text("\n".join(lines) + "\n")
    return change


BROKEN = {
    "a missing frame": (lambda f: (f / "001.npy").unlink(),
                        r"poses.csv, row 3: frame 001.npy is missing"),
    "a pose value that is not a number": (
        edit_row(2, lambda line: line.rsplit(",", 1)[0] + ",x"),
        r"poses.csv, row 3: a pose value is not a number"),
    "a row short of a number": (edit_row(1, lambda line: line.rsplit(",", 1)[0]),
                                r"poses.csv, row 2: 16 fields, expected 17"),
    "a bad last row": (edit_row(1, lambda line: line.rsplit(",", 1)[0] + ",2.0"),
                       r"poses.csv, row 2: the pose's last row must be 0, 0, 0, 1"),
    "a frame of the wrong shape": (
        lambda f: np.save(f / "000.npy", np.zeros((10, 10), dtype=np.float32)),
        r"000.npy: shape \(10, 10\), but recording.json says \(height, width\) = \(48, 64\)"),
    "a frame of the wrong dtype": (
        lambda f: np.save(f / "000.npy", np.zeros((48, 64), dtype=np.uint16)),
        r"000.npy: dtype uint16, but depth_unit 'm' needs float metres"),
    "a pickled frame": (
        lambda f: np.save(f / "000.npy", np.array([{"a": 1}], dtype=object),
                          allow_pickle=True),
        r"000.npy: not a NumPy array file without objects"),
    "no recording.json": (lambda f: (f / META_FILE).unlink(), r"recording.json: missing"),
    "a bad depth unit": (
        lambda f: (f / META_FILE).write_text(json.dumps({
            **json.loads((f / META_FILE).read_text()), "depth_unit": "cm"})),
        r"depth_unit is 'cm', not one of m, mm"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_broken_recording_is_refused_naming_the_file_and_row(recorded, tmp_path,
                                                              case: str) -> None:
    change, message = BROKEN[case]
    folder = broken(recorded, tmp_path, change)
    with pytest.raises(RecordingError, match=message):
        load_recording(folder)


def test_a_non_empty_folder_that_is_not_a_recording_is_not_overwritten(recorded,
                                                                       tmp_path) -> None:
    recording, _ = recorded
    (tmp_path / "notes.txt").write_text("mine")
    depths = [recording.depth(i) for i in range(len(recording))]
    intrinsics = recording.intrinsics
    with pytest.raises(RecordingError, match="not empty and not a recording"):
        write_recording(tmp_path, depths, recording.poses, intrinsics)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    # an earlier recording is replaced, its extra frames removed
    folder = copy_recording(recording, tmp_path / "again")
    shorter = write_recording(folder, depths[:1], recording.poses[:1], intrinsics)
    assert shorter.frames == ["000.npy"]
    assert sorted(p.name for p in folder.iterdir()) == sorted(["000.npy", META_FILE, POSES_FILE])


def test_rapomdp_record_and_replay_write_the_recording_and_the_table(pipeline_workspace,
                                                                    tmp_path) -> None:
    from rapomdp.cli import app

    ws, _ = pipeline_workspace
    runner = CliRunner()
    out = tmp_path / "rec"
    made = runner.invoke(app, ["record", "-w", str(ws.root), str(out), "--method", "ra"],
                         env={"COLUMNS": "200"})
    assert made.exit_code == 0, made.output
    assert "recorded" in made.output and (out / META_FILE).is_file()
    table_path = tmp_path / "table.json"
    ran = runner.invoke(app, ["replay", "-w", str(ws.root), str(out), "--out",
                              str(table_path)], env={"COLUMNS": "200"})
    assert ran.exit_code == 0, ran.output
    table = json.loads(table_path.read_text())
    meta = json.loads((out / META_FILE).read_text())
    assert [s["viewpoint"] for s in table["steps"]] == meta["source"]["viewpoints"]
    assert table["declared_class"] == meta["source"]["declared_class"]
    assert table["same_as_recorded_closed_loop"] is True
    assert "the same as the recorded closed loop: yes" in ran.output
    refused = runner.invoke(app, ["record", "-w", str(ws.root), str(tmp_path)],
                            env={"COLUMNS": "200"})
    assert refused.exit_code == 2 and "not empty and not a recording" in refused.output
    missing = runner.invoke(app, ["replay", "-w", str(ws.root), str(tmp_path / "none")],
                            env={"COLUMNS": "200"})
    assert missing.exit_code == 2 and "recording.json: missing" in missing.output
