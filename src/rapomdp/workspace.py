"""A workspace folder holding each stage's artefacts, cached under a hash of what made them.

A stage's key hashes its name and version, the configuration sections it reads, the keys of the
stages it reads and any external input (a user's mesh folder). A stage whose key is unchanged is
skipped. A stage writes into a temporary folder which replaces its folder only when it has
finished, so an interrupted or failed run leaves the earlier artefacts intact.
``W/manifest.json`` lists, for every stage, its key, configuration and files.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rapomdp.config import Config, load_config
from rapomdp.context import RunContext
from rapomdp.io import ArtefactError, atomic_path, read_json, stable_hash, write_json_atomic

MANIFEST = "manifest.json"
#: The configuration a workspace was run with (written by the CLI before its stages run).
CONFIG_FILE = "config.yaml"
STAGE_RECORD = "stage.json"


class StageError(RuntimeError):
    """A stage cannot run: a missing input, or bad data it names."""


@dataclass(frozen=True)
class Stage:
    """One pipeline stage: reads ``inputs`` (earlier stages) and writes its own folder."""

    name: str
    run: Callable[[Config, dict[str, Path], Path, RunContext], None]
    sections: Sequence[str] = ()
    inputs: Sequence[str] = ()
    version: str = "1"
    fingerprint: Callable[[Config], str] | None = None
    description: str = ""


@dataclass
class StageResult:
    name: str
    key: str
    cached: bool
    seconds: float
    files: list[str] = field(default_factory=list)


class Workspace:
    """A folder of stage outputs plus ``manifest.json``."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    @property
    def manifest_path(self) -> Path:
        return self.root / MANIFEST

    def manifest(self) -> dict[str, Any]:
        if not self.manifest_path.exists():
            return {"stages": {}}
        return read_json(self.manifest_path)

    @property
    def config_path(self) -> Path:
        return self.root / CONFIG_FILE

    def save_config(self, config: Config) -> None:
        """Record the configuration this workspace runs with (``W/config.yaml``, atomically)."""
        self.root.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.config_path) as tmp:
            tmp.write_text(config.to_yaml())

    def config(self, default: Config | None = None) -> Config:
        """The configuration the workspace was run with: ``W/config.yaml``, validated.

        When the file is missing: ``default`` if given, else a :class:`StageError` naming it.
        """
        if not self.config_path.exists():
            if default is not None:
                return default
            raise StageError(f"{self.config_path}: not found; a workspace made by `rapomdp` "
                             f"holds the configuration it ran with")
        return load_config(self.config_path)

    def stage_dir(self, name: str) -> Path:
        return self.root / name

    def require(self, name: str) -> Path:
        """The folder of a finished stage, or an error saying how to make it."""
        record = self.manifest()["stages"].get(name)
        path = self.stage_dir(name)
        if record is None or not path.is_dir():
            raise StageError(
                f"{self.root}: stage '{name}' has not been run here; "
                f"run `rapomdp run --workspace {self.root} --until {name}` first"
            )
        return path

    def key_of(self, stage: Stage, config: Config) -> str:
        stages = self.manifest()["stages"]
        upstream = {}
        for name in stage.inputs:
            if name not in stages:
                raise StageError(f"stage '{stage.name}' needs stage '{name}', which has not run")
            upstream[name] = stages[name]["key"]
        return stable_hash(
            {
                "stage": stage.name,
                "version": stage.version,
                "config": {s: config.section(s) for s in stage.sections},
                "inputs": upstream,
                "external": stage.fingerprint(config) if stage.fingerprint else None,
            }
        )

    def is_current(self, stage: Stage, config: Config) -> bool:
        record = self.manifest()["stages"].get(stage.name)
        return (
            record is not None
            and self.stage_dir(stage.name).is_dir()
            and record["key"] == self.key_of(stage, config)
        )

    def run(self, stage: Stage, config: Config, force: bool = False,
            context: RunContext = RunContext()) -> StageResult:
        """Run ``stage`` unless its cached output is current (or ``force``), with ``context``'s
        workers, threads and progress bars."""
        self.root.mkdir(parents=True, exist_ok=True)
        key = self.key_of(stage, config)
        if not force and self.is_current(stage, config):
            record = self.manifest()["stages"][stage.name]
            return StageResult(stage.name, key, True, 0.0, record.get("files", []))
        inputs = {name: self.require(name) for name in stage.inputs}
        tmp = self.root / f".{stage.name}.tmp-{os.getpid()}"
        if tmp.exists():
            shutil.rmtree(tmp)
        tmp.mkdir()
        start = time.perf_counter()
        try:
            stage.run(config, inputs, tmp, context)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        seconds = time.perf_counter() - start
        files = sorted(str(p.relative_to(tmp)) for p in tmp.rglob("*") if p.is_file())
        record = {
            "key": key,
            "version": stage.version,
            "config": {s: config.section(s) for s in stage.sections},
            "inputs": list(stage.inputs),
            "files": files,
            "seconds": round(seconds, 3),
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        write_json_atomic(tmp / STAGE_RECORD, record)
        self._swap_in(tmp, self.stage_dir(stage.name))
        manifest = self.manifest()
        manifest["stages"][stage.name] = record
        write_json_atomic(self.manifest_path, manifest)
        return StageResult(stage.name, key, False, seconds, files)

    @staticmethod
    def _swap_in(new: Path, target: Path) -> None:
        old = target.with_name(f".{target.name}.old-{os.getpid()}")
        if target.exists():
            os.replace(target, old)
        os.replace(new, target)
        if old.exists():
            shutil.rmtree(old, ignore_errors=True)


def read_stage_record(path: Path) -> dict[str, Any]:
    try:
        return read_json(path / STAGE_RECORD)
    except ArtefactError as exc:
        raise StageError(str(exc)) from exc
