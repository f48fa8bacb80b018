"""Running a stage in a workspace (or taking its artefacts from another): the
:class:`Workspace` itself."""

from __future__ import annotations

import json
import os
import shutil
import stat
import time

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.io import (
    ArtefactError,
    check_output_path,
    describe_os_error,
    file_mode,
    write_json_atomic,
)
from rapomdp.workspace.folder import link_or_copy
from rapomdp.workspace.layout import STAGE_RECORD, StageError
from rapomdp.workspace.lock import WorkspaceLock
from rapomdp.workspace.stages import Stage, StageResult


class Workspace(WorkspaceLock):
    """A folder of stage outputs plus ``manifest.json``: the cache every pipeline stage runs in.

    Each stage writes one folder ``W/STAGE``, recorded in ``W/manifest.json`` under a key that
    hashes what made it (:func:`~rapomdp.workspace.stage_key`); a stage whose key is unchanged
    is not run again. A run writes into ``W/.rapomdp-tmp`` and swaps the finished folder in,
    so a failure or a kill leaves the earlier artefacts intact; one run at a time holds the
    lock (:meth:`locked`). Making a ``Workspace`` touches nothing on disk: the folder is
    claimed (made, with its marker) by the first method that writes.

    The methods come from four layers, one concern each: the folder and its temporary files
    (:class:`~rapomdp.workspace.folder.WorkspaceFolder`), the manifest and the keys
    (:class:`~rapomdp.workspace.manifest.WorkspaceManifest`), the marker and the lock
    (:class:`~rapomdp.workspace.lock.WorkspaceLock`), and running a stage (this class).

    Args:
        root: The workspace folder (made when missing; a folder that is neither a workspace
            nor empty is refused when a command would write there).

    Example:
        A stage that writes the camera's size, run twice: the second run is cached.

        >>> import tempfile
        >>> from pathlib import Path
        >>> from rapomdp.config import Config
        >>> from rapomdp.workspace import Stage, Workspace
        >>> def write_size(config, inputs, out, context):
        ...     (out / "size.txt").write_text(f"{config.camera.width}x{config.camera.height}")
        >>> stage = Stage("size", write_size, sections=("camera",))
        >>> tmp = tempfile.TemporaryDirectory()
        >>> ws = Workspace(Path(tmp.name) / "ws")
        >>> first = ws.run(stage, Config())
        >>> (first.cached, first.files)
        (False, ['size.txt'])
        >>> ws.run(stage, Config()).cached
        True
        >>> (ws.stage_dir("size") / "size.txt").read_text()
        '160x120'
        >>> ws.staleness([stage], Config(camera={"width": 64, "height": 48}))
        {'size': ['camera.height 120 -> 48, camera.width 160 -> 64']}
        >>> tmp.cleanup()
    """

    def run(self, stage: Stage, config: Config, force: bool = False,
            context: RunContext = RunContext()) -> StageResult:
        """Run ``stage`` unless its cached output is current (or ``force``), with ``context``'s
        workers, threads and progress bars; a stage that ran is recorded in the manifest.

        The stage writes into a temporary folder that replaces ``W/STAGE`` only when it has
        finished; ``W/config.yaml`` is then rewritten with ``config``. Call it holding the
        lock (:meth:`locked`) when another run may use the workspace.

        Args:
            stage: The stage to run; its inputs must have run here (:meth:`require`).
            config: The configuration; the sections ``stage.sections`` enter its key.
            force: Run it even when its cached output is current.
            context: Workers, threads, scheduler and progress bars of the run.

        Returns:
            What was done: ``cached`` (with the recorded files) or the files written and the
            wall time in seconds.

        Raises:
            StageError: An input stage has not run here, or the stage's folder is not one
                rapomdp made.
            ArtefactError: The workspace cannot be written (its earlier artefacts intact).
        """
        self.claim()
        key, upstream, external = self._key_parts(stage, config)
        if not force and self.is_current(stage, config):
            record = self.manifest()["stages"][stage.name]
            return StageResult(stage.name, key, True, 0.0, record.get("files", []))
        self._check_replaceable(stage.name)
        check_output_path(self.manifest_path)  # refused before the work, not after it
        inputs = self.inputs(stage)
        tmp = self._scratch_dir() / f"{stage.name}.tmp-{os.getpid()}"
        try:
            if tmp.exists():
                shutil.rmtree(tmp)
            tmp.mkdir()
        except OSError as exc:
            raise ArtefactError(describe_os_error(exc)) from None
        start = time.perf_counter()
        try:
            stage.run(config, inputs, tmp, context)
            seconds = time.perf_counter() - start
            files = sorted(str(p.relative_to(tmp)) for p in tmp.rglob("*") if p.is_file())
            record = {
                "key": key,
                "version": stage.version,
                "config": {s: config.section(s) for s in stage.sections},
                "inputs": list(stage.inputs),
                "input_keys": upstream,
                "external": external,
                "files": files,
                "seconds": round(seconds, 3),
                "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            }
            write_json_atomic(tmp / STAGE_RECORD, record)
            self._swap_in(tmp, self.stage_dir(stage.name))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            self._drop_scratch()
        manifest = self.manifest()
        manifest["stages"][stage.name] = record
        self._write_file(self.manifest_path,
                         json.dumps(manifest, indent=2, sort_keys=True) + "\n")
        self.record_config(config)
        return StageResult(stage.name, key, False, seconds, files)

    def adopt(self, stage: Stage, config: Config, source: Workspace) -> StageResult | None:
        """Take ``stage``'s finished artefacts from ``source`` when they are exactly what this
        workspace would make (the same key), instead of running it; None when they are not.

        The files are hard links (a copy across file systems): a stage's artefacts are only
        ever replaced whole, never edited, so neither workspace can change the other's. The
        record keeps the source's key and notes ``shared_from``; its seconds count 0 here.
        A study shares the stages its seeds have in common this way.

        Args:
            stage: The stage to take.
            config: This workspace's configuration (its key must equal the source's record).
            source: Another workspace holding the stage (the same one: None).

        Returns:
            The result (``cached``, ``shared_from`` the source's folder), or None when the
            source holds no such artefacts.
        """
        if source.root.resolve() == self.root.resolve():
            return None
        try:
            key = self.key_of(stage, config)
            record = source.manifest()["stages"].get(stage.name)
        except (StageError, ArtefactError):
            return None
        folder = source.stage_dir(stage.name)
        if record is None or record.get("key") != key or not folder.is_dir():
            return None
        self.claim()
        self._check_replaceable(stage.name)
        check_output_path(self.manifest_path)
        tmp = self._scratch_dir() / f"{stage.name}.tmp-{os.getpid()}"
        try:
            if tmp.exists():
                shutil.rmtree(tmp)
            shutil.copytree(folder, tmp, copy_function=link_or_copy)
            shared = {**record, "seconds": 0.0, "shared_from": str(source.root),
                      "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
            write_json_atomic(tmp / STAGE_RECORD, shared)  # a new file: the link is broken
            self._swap_in(tmp, self.stage_dir(stage.name))
        except OSError as exc:
            raise ArtefactError(describe_os_error(exc)) from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            self._drop_scratch()
        manifest = self.manifest()
        manifest["stages"][stage.name] = shared
        self._write_file(self.manifest_path,
                         json.dumps(manifest, indent=2, sort_keys=True) + "\n")
        self.record_config(config)
        return StageResult(stage.name, key, True, 0.0, list(record.get("files", [])),
                           shared_from=str(source.root))

    def _check_replaceable(self, name: str) -> None:
        """Refuse, before stage ``name`` runs, to replace what is at its folder's path unless
        the project made it: a real folder (no symbolic link: its new folder would replace the
        link, and the artefacts the link points to would go stale unseen) holding the stage's
        record or recorded in the manifest."""
        target = self.stage_dir(name)
        mode = file_mode(target)
        if mode is None:
            return
        if stat.S_ISLNK(mode):
            raise StageError(
                f"{target}: a symbolic link (to {os.readlink(target)[:200]}); a stage's folder is "
                "replaced whole when the stage is redone, so it must be a folder in the "
                "workspace: put the folder it points to in its place (or link the whole "
                "workspace instead)")
        if not stat.S_ISDIR(mode):
            raise StageError(f"{target}: not a folder, where stage '{name}' keeps its folder; "
                             "move it away")
        if (not (target / STAGE_RECORD).is_file()
                and name not in self.manifest()["stages"]):
            raise StageError(f"{target}: a folder rapomdp did not make (no {STAGE_RECORD}); "
                             f"move it away so that stage '{name}' can write its own")

