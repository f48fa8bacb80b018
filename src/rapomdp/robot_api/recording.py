"""Recorded sequences of depth images and camera poses: their format, a recording from the
simulator's closed loop (:func:`record_episode`) and a replay through an
:class:`~rapomdp.robot_api.recognizer.ActiveRecognizer` (:func:`replay`).

A recording is a folder (docs/robot-api.md, "Recorded sequences"): the frames as ``.npy``
(float metres, or uint16 millimetres) or 16-bit ``.png`` (millimetres), ``poses.csv`` (one row
per frame: its file name, then the 4 x 4 camera-to-world pose, 16 numbers row-major, in the
scene's world frame) and ``recording.json`` (the intrinsics, the depth unit, optionally the true
class and where the recording came from). Nothing is unpickled.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.experiment.episode import Episode, run_episode
from rapomdp.io import ArtefactError, atomic_path, read_json, write_json_atomic, write_text_atomic
from rapomdp.robot_api.recognizer import ActiveRecognizer, Observation

#: The file naming the recording's format, intrinsics and depth unit.
META_FILE = "recording.json"
#: One row per frame: the frame's file name, then its camera-to-world pose, row-major.
POSES_FILE = "poses.csv"
#: ``recording.json``'s ``format`` field.
FORMAT = "rapomdp-recording/1"
#: The depth units: float ``.npy`` metres, or uint16 ``.npy`` / 16-bit ``.png`` millimetres.
DEPTH_UNITS = ("m", "mm")
#: The frame files a recording may hold.
FRAME_SUFFIXES = (".npy", ".png")
POSE_COLUMNS = [f"m{r}{c}" for r in range(4) for c in range(4)]


class RecordingError(ArtefactError):
    """A recording folder that cannot be read or written; the message names the file (and the
    row) and the problem."""


@dataclass(frozen=True)
class Recording:
    """A recorded sequence: ``frames`` (file names in ``folder``, in order), ``poses`` (N, 4, 4)
    camera-to-world, ``intrinsics`` (fx, fy, cx, cy, width, height), ``depth_unit`` ("m" or
    "mm"), ``true_class`` (or None) and ``source`` (what made it, or {})."""

    folder: Path
    frames: list[str]
    poses: np.ndarray
    intrinsics: dict[str, float]
    depth_unit: str
    true_class: str | None = None
    source: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frames)

    def depth(self, index: int) -> np.ndarray:
        """Frame ``index`` as stored: (H, W) float metres or uint16 millimetres."""
        return read_depth_frame(self.folder / self.frames[index], self.depth_unit,
                                (int(self.intrinsics["height"]), int(self.intrinsics["width"])))


def read_depth_frame(path: Path, unit: str, shape: tuple[int, int]) -> np.ndarray:
    """One recorded depth image, checked against its unit and the recording's size.

    Args:
        path: a ``.npy`` file (read with ``allow_pickle=False``) or a 16-bit ``.png``.
        unit: "m" (a float ``.npy``) or "mm" (uint16 ``.npy``, or ``.png``).
        shape: (height, width) from ``recording.json``.

    Returns:
        (H, W) float metres or uint16 millimetres.
    """
    if not path.is_file():
        raise RecordingError(f"{path}: the frame is missing")
    if path.suffix == ".npy":
        try:
            depth = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise RecordingError(f"{path}: not a NumPy array file without objects ({exc})"
                                 ) from None
    elif path.suffix == ".png":
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(path) as image:
                if image.mode not in ("I;16", "I;16B", "I"):
                    raise RecordingError(f"{path}: a {image.mode} PNG; depth must be a "
                                         "16-bit greyscale PNG of millimetres")
                depth = np.asarray(image)
        except (UnidentifiedImageError, OSError) as exc:
            raise RecordingError(f"{path}: not a readable PNG ({exc})") from None
        if depth.dtype != np.uint16:
            if depth.min(initial=0) < 0 or depth.max(initial=0) > 65535:
                raise RecordingError(f"{path}: values outside 16 bits")
            depth = depth.astype(np.uint16)
    else:
        raise RecordingError(f"{path}: a frame must be .npy or .png")
    if depth.shape != shape:
        raise RecordingError(f"{path}: shape {depth.shape}, but {META_FILE} says "
                             f"(height, width) = {shape}")
    if unit == "m" and depth.dtype.kind != "f":
        raise RecordingError(f"{path}: dtype {depth.dtype}, but depth_unit 'm' needs float "
                             "metres")
    if unit == "mm" and depth.dtype != np.uint16:
        raise RecordingError(f"{path}: dtype {depth.dtype}, but depth_unit 'mm' needs uint16 "
                             "millimetres")
    return depth


def _read_meta(folder: Path) -> dict[str, Any]:
    path = folder / META_FILE
    if not path.is_file():
        raise RecordingError(f"{path}: missing; {folder} is not a recording")
    meta = read_json(path)
    if not isinstance(meta, dict):
        raise RecordingError(f"{path}: a map is expected")
    intrinsics = meta.get("intrinsics")
    keys = ("fx", "fy", "cx", "cy", "width", "height")
    if not isinstance(intrinsics, dict) or set(keys) - set(intrinsics):
        raise RecordingError(f"{path}: 'intrinsics' must hold {', '.join(keys)}")
    for key in keys:
        value = intrinsics[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                math.isfinite(value) and value > (0 if key in ("fx", "fy", "width", "height")
                                                  else -math.inf)):
            raise RecordingError(f"{path}: intrinsics.{key} is {value!r}, not a finite number"
                                 + (" above 0" if key in ("fx", "fy", "width", "height") else ""))
    if meta.get("depth_unit") not in DEPTH_UNITS:
        raise RecordingError(f"{path}: depth_unit is {meta.get('depth_unit')!r}, not one of "
                             f"{', '.join(DEPTH_UNITS)}")
    return meta


def _read_poses(folder: Path) -> tuple[list[str], np.ndarray]:
    path = folder / POSES_FILE
    if not path.is_file():
        raise RecordingError(f"{path}: missing (one row per frame: its file, 16 numbers)")
    frames: list[str] = []
    poses: list[np.ndarray] = []
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    if not rows or rows[0] != ["frame", *POSE_COLUMNS]:
        raise RecordingError(f"{path}: the header must be frame,{','.join(POSE_COLUMNS)}")
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        where = f"{path}, row {number}"
        if len(row) != 17:
            raise RecordingError(f"{where}: {len(row)} fields, expected 17 (the frame's file "
                                 "and 16 numbers)")
        name = row[0]
        if Path(name).name != name or Path(name).suffix not in FRAME_SUFFIXES:
            raise RecordingError(f"{where}: frame {name!r} must be a .npy or .png file of the "
                                 "recording's folder")
        if not (folder / name).is_file():
            raise RecordingError(f"{where}: frame {name} is missing")
        try:
            pose = np.array([float(x) for x in row[1:]]).reshape(4, 4)
        except ValueError as exc:
            raise RecordingError(f"{where}: a pose value is not a number ({exc})") from None
        if not np.all(np.isfinite(pose)):
            raise RecordingError(f"{where}: the pose has a value that is not finite")
        if not np.allclose(pose[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
            raise RecordingError(f"{where}: the pose's last row must be 0, 0, 0, 1, got "
                                 f"{pose[3].tolist()}")
        frames.append(name)
        poses.append(pose)
    if not frames:
        raise RecordingError(f"{path}: no frames")
    return frames, np.stack(poses)


def load_recording(folder: str | Path) -> Recording:
    """A recording folder, every file checked (the frames' shapes and dtypes included).

    Args:
        folder: the folder holding ``recording.json``, ``poses.csv`` and the frames.

    Returns:
        The :class:`Recording`; a problem raises :class:`RecordingError` naming the file (and
        the row of ``poses.csv``).
    """
    folder = Path(folder)
    meta = _read_meta(folder)
    frames, poses = _read_poses(folder)
    recording = Recording(folder, frames, poses,
                          {k: float(v) for k, v in meta["intrinsics"].items()},
                          str(meta["depth_unit"]), meta.get("true_class"),
                          dict(meta.get("source") or {}))
    for index in range(len(frames)):
        recording.depth(index)
    return recording


def write_recording(folder: str | Path, depths: Sequence[np.ndarray], poses: np.ndarray,
                    intrinsics: Mapping[str, float], true_class: str | None = None,
                    source: Mapping[str, Any] | None = None) -> Recording:
    """Write float32-metre frames ``000.npy``, ``001.npy``, ... with ``poses.csv`` and
    ``recording.json``, each atomically (``recording.json`` last).

    Args:
        folder: a new or empty folder, or an earlier recording (replaced: its frames that the
            new one lacks are removed); any other non-empty folder is refused.
        depths: the (H, W) images in metres.
        poses: (N, 4, 4) camera-to-world, the scene's world frame.
        intrinsics: fx, fy, cx, cy in pixels (width and height are the images').
        true_class: the object's class, if known.
        source: what made the recording (stored under ``source``).

    Returns:
        The recording as :func:`load_recording` reads it.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder")
    old: list[str] = []
    if folder.is_dir() and any(folder.iterdir()):
        if not (folder / META_FILE).is_file():
            raise RecordingError(f"{folder}: not empty and not a recording (no {META_FILE}); "
                                 "give a new or empty folder")
        if (folder / POSES_FILE).is_file():
            try:
                old = _read_poses_names(folder / POSES_FILE)
            except (OSError, ValueError):
                old = []
    poses = np.asarray(poses, dtype=np.float64)
    if len(depths) == 0 or poses.shape != (len(depths), 4, 4):
        raise RecordingError(f"{folder}: {len(depths)} frames need poses of shape "
                             f"({len(depths)}, 4, 4), got {poses.shape}")
    height, width = np.asarray(depths[0]).shape
    folder.mkdir(parents=True, exist_ok=True)
    names = [f"{i:03d}.npy" for i in range(len(depths))]
    for name, depth in zip(names, depths, strict=True):
        depth = np.asarray(depth, dtype=np.float32)
        if depth.shape != (height, width):
            raise RecordingError(f"{folder / name}: shape {depth.shape}, the first frame's is "
                                 f"{(height, width)}")
        buffer = io.BytesIO()
        np.save(buffer, depth, allow_pickle=False)
        with atomic_path(folder / name) as tmp:
            tmp.write_bytes(buffer.getvalue())
    lines = io.StringIO()
    writer = csv.writer(lines, lineterminator="\n")
    writer.writerow(["frame", *POSE_COLUMNS])
    for name, pose in zip(names, poses, strict=True):
        writer.writerow([name, *(repr(float(x)) for x in pose.ravel())])
    write_text_atomic(folder / POSES_FILE, lines.getvalue())
    meta = {"format": FORMAT, "depth_unit": "m",
            "intrinsics": {**{k: float(intrinsics[k]) for k in ("fx", "fy", "cx", "cy")},
                           "width": int(width), "height": int(height)},
            "true_class": true_class, "source": dict(source or {})}
    write_json_atomic(folder / META_FILE, meta)
    for name in set(old) - set(names):
        (folder / name).unlink(missing_ok=True)
    return load_recording(folder)


def _read_poses_names(path: Path) -> list[str]:
    with path.open(newline="", encoding="utf-8") as handle:
        return [row[0] for row in list(csv.reader(handle))[1:]
                if row and Path(row[0]).name == row[0]]


class _RecordingScene:
    """A scene that keeps every image the closed loop looks at, and where from."""

    def __init__(self, scene: Any) -> None:
        self.scene = scene
        self.looks: list[tuple[int, np.ndarray]] = []

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        depth = self.scene.look(viewpoint, rng)
        self.looks.append((int(viewpoint), np.array(depth, dtype=np.float32)))
        return depth


def record_episode(workspace: str | Path, out: str | Path, method: str = "ra",
                   model: str | None = None, start: int | None = None,
                   seed: int | None = None) -> tuple[Recording, Episode]:
    """Run one closed-loop episode of the simulator and record the images the camera took.

    The episode is :func:`rapomdp.experiment.episode.run_episode` on a test model's rendered
    views, each image classified as it is taken; each frame's pose is the camera pose the robot
    stage's IK solution reaches at that viewpoint.

    Args:
        workspace: a workspace whose stages up to ``solve`` have run.
        out: the recording's folder (see :func:`write_recording`).
        method: the method that chooses the views (a key of ``METHOD_NAMES``).
        model: a test model's file or id (default: the first test model).
        start: the start viewpoint (default: the evaluate stage's first start for the model).
        seed: seeds the episode's draws; None: the evaluate stage's own generator for this
            model, start and method (the recording is then that episode).

    Returns:
        (the recording, the closed loop's :class:`~rapomdp.experiment.episode.Episode`).
    """
    from rapomdp.data.dataset import load_dataset
    from rapomdp.data.test_views import TestViews
    from rapomdp.experiment.evaluation import episode_rng, start_viewpoints
    from rapomdp.geometry.camera import xtion_intrinsics
    from rapomdp.workspace import StageError, Workspace

    recognizer = ActiveRecognizer.load(workspace, method)
    ws = Workspace(workspace)
    config = recognizer.config
    dataset = load_dataset(ws.require("dataset"))
    tests = dataset.with_role("test")
    if not tests:
        raise StageError(f"{ws.root}: the dataset has no test models")
    if model is None:
        entry = tests[0]
    else:
        found = [m for m in tests if model in (m.file, m.id)]
        if not found:
            raise StageError(f"model {model!r} is not a test model of {ws.root}; test models: "
                             f"{', '.join(m.file for m in tests)}")
        entry = found[0]
    reachable = recognizer.motion.reachable
    if start is None:
        start = int(start_viewpoints(config.seed, entry, reachable,
                                     config.evaluate.starts_per_model)[0])
    if not 0 <= start < reachable.size or not reachable[start]:
        raise StageError(f"start viewpoint {start} is not a reachable viewpoint (reachable: "
                         f"{', '.join(map(str, np.flatnonzero(reachable)))})")
    rng = (episode_rng(config.seed, entry, start, method) if seed is None
           else np.random.default_rng(seed))
    scene = _RecordingScene(TestViews.of_model(dataset, entry, config.viewpoints,
                                               config.camera, config.render.noise))
    episode = run_episode(scene, recognizer.recogniser, recognizer.policy, recognizer.motion,
                          start, recognizer.max_moves, rng)
    camera = xtion_intrinsics(config.camera.width, config.camera.height)
    k = int(episode.declared)
    source = {"workspace": str(ws.root), "method": method, "model": entry.file,
              "start": start, "seed": seed, "workspace_seed": int(config.seed),
              "viewpoints": [int(v) for v in episode.viewpoints],
              "declared_class": recognizer.classes[k],
              "declared_confidence": float(episode.beliefs[-1][k])}
    recording = write_recording(
        out, [depth for _, depth in scene.looks],
        np.stack([recognizer.camera_poses_world[v] for v, _ in scene.looks]),
        {"fx": camera.fx, "fy": camera.fy, "cx": camera.cx, "cy": camera.cy},
        entry.class_name, source)
    return recording, episode


def replay_rng(recognizer: ActiveRecognizer, recording: Recording,
               seed: int | None = None) -> np.random.Generator:
    """The generator a replay's method draws from: ``seed``'s; else the recording's seed; else,
    for a recording of an evaluate-stage episode, that episode's generator for the
    recognizer's method; else seed 0."""
    from rapomdp.data.splits import class_seed

    if seed is not None:
        return np.random.default_rng(seed)
    source = recording.source
    if source.get("seed") is not None:
        return np.random.default_rng(int(source["seed"]))
    if {"model", "start", "workspace_seed"} <= set(source):
        return class_seed(int(source["workspace_seed"]),
                          f"evaluate/{source['model']}/{int(source['start'])}/"
                          f"{recognizer.method}")
    return np.random.default_rng(0)


@dataclass(frozen=True)
class ReplayStep:
    """One frame of a replay: what ``observe`` answered and what ``next_view`` chose."""

    frame: str
    observation: Observation
    action: str
    next_viewpoint: int
    next_pose: np.ndarray
    energy_m: float
    distance_m: float

    def row(self, classes: Sequence[str]) -> dict[str, Any]:
        """The step as a JSON-ready map."""
        seen = self.observation
        return {"frame": self.frame, "viewpoint": seen.viewpoint,
                "off_viewpoint_m": seen.off_viewpoint_m,
                "belief": dict(zip(classes, map(float, seen.belief), strict=True)),
                "declared_class": seen.declared_class_name,
                "declared_confidence": seen.declared_confidence, "done": seen.done,
                "action": self.action, "next_viewpoint": self.next_viewpoint,
                "next_pose": None if self.action == "declare" else self.next_pose.tolist(),
                "energy_m": None if self.action == "declare" else self.energy_m,
                "distance_m": None if self.action == "declare" else self.distance_m}


@dataclass(frozen=True)
class ReplayResult:
    """A replay: its ``steps`` (one per frame used), the declaration (None when the frames ran
    out first) and the frames left after it."""

    method: str
    steps: list[ReplayStep]
    declared_class: str | None
    declared_confidence: float | None
    unused_frames: int

    @property
    def chosen(self) -> list[int]:
        """The viewpoint observed at each step."""
        return [s.observation.viewpoint for s in self.steps]


def replay(recognizer: ActiveRecognizer, recording: Recording,
           rng: np.random.Generator | None = None) -> ReplayResult:
    """Run the recognizer on the recorded frames in order: ``observe`` each with its pose and
    the recording's intrinsics, then ``next_view``, until it declares or the frames run out.

    Args:
        recognizer: the method to run (its episode is reset here).
        recording: the frames and poses.
        rng: the method's draws (default: :func:`replay_rng`).

    Returns:
        The :class:`ReplayResult`.
    """
    recognizer.reset(rng=rng if rng is not None else replay_rng(recognizer, recording))
    intrinsics = {k: recording.intrinsics[k] for k in ("fx", "fy", "cx", "cy")}
    steps: list[ReplayStep] = []
    for index, name in enumerate(recording.frames):
        seen = recognizer.observe(recording.depth(index), recording.poses[index], intrinsics)
        nxt = recognizer.next_view()
        steps.append(ReplayStep(name, seen, nxt.action, nxt.viewpoint, nxt.camera_pose_world,
                                nxt.energy_m, nxt.distance_m))
        if nxt.is_declare:
            return ReplayResult(recognizer.method, steps, nxt.declared_class_name,
                                nxt.declared_confidence, len(recording) - index - 1)
    return ReplayResult(recognizer.method, steps, None, None, 0)


def replay_table(result: ReplayResult, recognizer: ActiveRecognizer,
                 recording: Recording) -> dict[str, Any]:
    """The replay as a JSON-ready map: the method, the recording, each step (with
    ``at_chosen_viewpoint``: whether its frame was taken where the step before chose; None at
    the start), the declaration, and whether it repeats the recorded closed loop's (when the
    recording says).

    Args:
        result: what :func:`replay` answered.
        recognizer: the recognizer it ran (its classes name the belief's entries).
        recording: the recording it ran on.

    Returns:
        The map :func:`write_replay_table` writes.
    """
    source = recording.source
    same: bool | None = None
    if "viewpoints" in source and source.get("method") == result.method:
        same = (result.chosen == list(source["viewpoints"])
                and result.declared_class == source.get("declared_class")
                and result.declared_confidence is not None
                and abs(result.declared_confidence - float(source["declared_confidence"]))
                <= 1e-6)
    rows = [s.row(recognizer.classes) for s in result.steps]
    for before, row in zip(rows, rows[1:], strict=False):  # each step and the one before
        row["at_chosen_viewpoint"] = row["viewpoint"] == before["next_viewpoint"]
    if rows:
        rows[0]["at_chosen_viewpoint"] = None  # the start: nothing was chosen
    return {"method": result.method, "recording": str(recording.folder),
            "true_class": recording.true_class, "frames": len(recording),
            "declared_class": result.declared_class,
            "declared_confidence": result.declared_confidence,
            "unused_frames": result.unused_frames, "same_as_recorded_closed_loop": same,
            "steps": rows}


def write_replay_table(path: str | Path, table: Mapping[str, Any]) -> None:
    """Write :func:`replay_table`'s map as JSON, atomically."""
    write_json_atomic(path, table)


def replay_summary(table: Mapping[str, Any]) -> list[str]:
    """A few lines saying what the replay chose and declared."""
    lines = [f"{s['frame']}: viewpoint {s['viewpoint']} ({s['off_viewpoint_m']:.3f} m off), "
             f"{s['declared_class']} at {s['declared_confidence']:.3f} -> "
             + (f"move to {s['next_viewpoint']} ({s['energy_m']:.3f} m energy)"
                if s["action"] == "move" else "declare")
             for s in table["steps"]]
    if table["declared_class"] is None:
        lines.append(f"no declaration: the {table['frames']} frames ran out first")
    else:
        lines.append(f"declared {table['declared_class']} at "
                     f"{table['declared_confidence']:.3f} after {len(table['steps'])} frames"
                     + (f" ({table['unused_frames']} unused)" if table["unused_frames"] else "")
                     + (f"; true class {table['true_class']}" if table["true_class"] else ""))
    if table["same_as_recorded_closed_loop"] is not None:
        lines.append("the same as the recorded closed loop: "
                     + ("yes" if table["same_as_recorded_closed_loop"] else "NO"))
    return lines
