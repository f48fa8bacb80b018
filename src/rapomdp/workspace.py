"""A workspace folder holding each stage's artefacts, cached under a hash of what made them.

A stage's key hashes its name and version, the configuration sections it reads, the keys of the
stages it reads and any external input (a user's mesh folder). A stage whose key is unchanged is
skipped. A stage writes into a temporary folder which replaces its folder only when it has
finished, so an interrupted or failed run leaves the earlier artefacts intact.
``W/manifest.json`` lists, for every stage, its key, configuration and files;
``W/config.yaml`` is the configuration those artefacts were made with (written only together
with them). ``W/.rapomdp-workspace`` marks a folder as a workspace: a command writes only into
one, or into an empty or new folder (which becomes one). One run at a time holds ``W/.lock``.
Everything temporary lives in ``W/.rapomdp-tmp/``, the one folder the next run empties: nothing
outside the stage folders and the files the project wrote is ever deleted, moved or replaced.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import shutil
import stat
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, overload

from rapomdp.config import Config, ConfigError, config_from_dict, read_config_data
from rapomdp.context import RunContext
from rapomdp.io import (
    ArtefactError,
    check_output_path,
    describe_os_error,
    file_mode,
    read_json,
    stable_hash,
    write_json_atomic,
    write_text_atomic,
)

MANIFEST = "manifest.json"
#: The configuration a workspace's artefacts were made with (recorded after a run succeeds).
CONFIG_FILE = "config.yaml"
STAGE_RECORD = "stage.json"
LOCK = ".lock"
#: The file that makes a folder a workspace, written when the project makes it (JSON: the
#: workspace format and the version that made it).
MARKER = ".rapomdp-workspace"
MARKER_FORMAT = 1
#: The folder of a run's temporary files and folders: a stage's new folder
#: (``STAGE.tmp-PID``), the folder it replaces (``STAGE.old-PID``), a file being written.
SCRATCH = ".rapomdp-tmp"

_LEFTOVER = re.compile(r"(?P<name>.+)\.(?P<kind>tmp|old)-(?P<pid>\d+)")

#: Workspaces this process has locked (a nested run, e.g. Fig. 2's, takes the lock again).
_HELD: dict[Path, int] = {}


class StageError(RuntimeError):
    """A stage cannot run: a missing input, or bad data it names."""


class WorkspaceBusyError(StageError):
    """Another run holds the workspace's lock."""


class NotAWorkspaceError(StageError):
    """A folder a command would write into is not a workspace (nor empty), or not a folder."""


class _Upstream:
    """A :class:`StageInputs` attribute named after an earlier stage: that stage's folder, or a
    :class:`StageError` naming the stage when it was not given (a required input)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.stage = name

    @overload
    def __get__(self, inputs: None, owner: type | None = None) -> _Upstream: ...

    @overload
    def __get__(self, inputs: StageInputs, owner: type | None = None) -> Path: ...

    def __get__(self, inputs: StageInputs | None, owner: type | None = None
                ) -> _Upstream | Path:
        if inputs is None:
            return self
        folder: Path | None = getattr(inputs, f"{self.stage}_dir")
        if folder is None:
            reader = f"stage '{inputs.stage}'" if inputs.stage else "this stage"
            raise StageError(
                f"{reader} needs the folder of stage '{self.stage}', which it was not given: "
                f"run `rapomdp {self.stage} -w WORKSPACE` first, or pass "
                f"StageInputs({self.stage}_dir=...)")
        return folder


@dataclass(frozen=True, repr=False)
class StageInputs:
    """The folders of the earlier stages a stage reads: one typed attribute per stage.

    ``inputs.train`` is the train stage's folder, or a :class:`StageError` naming the train
    stage when it was not given; ``inputs.train_dir`` is that folder or None, for an input the
    stage can do without. ``stage`` names the reading stage in those errors. The pipeline
    builds one per stage from the stage graph (:meth:`Workspace.inputs`); a library caller
    names the folders it has: ``StageInputs("solve", observe_dir=..., robot_dir=...)``.
    """

    stage: str = ""
    dataset_dir: Path | None = None
    render_dir: Path | None = None
    train_dir: Path | None = None
    xrho_dir: Path | None = None
    classifier_eval_dir: Path | None = None
    saliency_dir: Path | None = None
    volume_dir: Path | None = None
    robot_dir: Path | None = None
    observe_dir: Path | None = None
    vptree_dir: Path | None = None
    solve_dir: Path | None = None
    learn_dir: Path | None = None
    evaluate_dir: Path | None = None

    dataset = _Upstream()
    render = _Upstream()
    train = _Upstream()
    xrho = _Upstream()
    classifier_eval = _Upstream()
    saliency = _Upstream()
    volume = _Upstream()
    robot = _Upstream()
    observe = _Upstream()
    vptree = _Upstream()
    solve = _Upstream()
    learn = _Upstream()
    evaluate = _Upstream()

    def __post_init__(self) -> None:
        for name, folder in self._folders():  # a str from a library caller becomes a Path
            if folder is not None and not isinstance(folder, Path):
                object.__setattr__(self, f"{name}_dir", Path(folder))

    def _folders(self) -> Iterator[tuple[str, Path | None]]:
        for item in fields(self):
            if item.name.endswith("_dir"):
                yield item.name.removesuffix("_dir"), getattr(self, item.name)

    @classmethod
    def of(cls, stage: str, folders: Mapping[str, str | Path]) -> StageInputs:
        """The inputs of ``stage`` from ``{upstream stage: folder}`` (the stage graph's names);
        a name that is no pipeline stage raises a :class:`StageError`."""
        known = [name for name, _ in cls()._folders()]
        unknown = [name for name in folders if name not in known]
        if unknown:
            raise StageError(f"stage '{stage}' reads {', '.join(map(repr, unknown))}, which "
                             f"StageInputs has no folder for (it has {', '.join(known)})")
        given: dict[str, Any] = {f"{name}_dir": Path(folder) for name, folder in folders.items()}
        return cls(stage, **given)

    def given(self) -> dict[str, Path]:
        """``{stage: folder}`` for every folder given, in pipeline order."""
        return {name: folder for name, folder in self._folders() if folder is not None}

    def __repr__(self) -> str:  # the folders given only
        given = "".join(f", {name}_dir={str(folder)!r}" for name, folder in self.given().items())
        return f"StageInputs({self.stage!r}{given})"


@dataclass(frozen=True)
class Stage:
    """One pipeline stage: reads ``inputs`` (earlier stages) and writes its own folder."""

    name: str
    run: Callable[[Config, StageInputs, Path, RunContext], None]
    sections: Sequence[str] = ()
    inputs: Sequence[str] = ()
    version: str = "1"
    fingerprint: Callable[[Config], str] | None = None
    description: str = ""


def stage_key(stage: Stage, config: Config, upstream: Mapping[str, str],
              external: str | None) -> str:
    """The cache key of ``stage``: its name and version, the configuration sections it reads,
    its inputs' keys (``upstream``) and its external fingerprint."""
    return stable_hash(
        {
            "stage": stage.name,
            "version": stage.version,
            "config": {s: config.section(s) for s in stage.sections},
            "inputs": dict(upstream),
            "external": external,
        }
    )


@dataclass
class StageResult:
    """What running a stage did: ``cached`` (nothing to do), or done in ``seconds``;
    ``shared_from``: the workspace whose identical artefacts it took instead of running."""

    name: str
    key: str
    cached: bool
    seconds: float
    files: list[str] = field(default_factory=list)
    shared_from: str | None = None


@dataclass(frozen=True)
class StageStatus:
    """What a workspace holds of one stage (``rapomdp status``): ``state`` is ``current``,
    ``stale`` (``reasons`` say why) or ``not run``; the rest is the stage's manifest record
    (``seconds``: its run's wall time; ``finished``: when, as recorded)."""

    name: str
    state: str
    reasons: list[str] = field(default_factory=list)
    files: int | None = None
    key: str | None = None
    seconds: float | None = None
    finished: str | None = None
    shared_from: str | None = None


class Workspace:
    """A folder of stage outputs plus ``manifest.json``."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    @property
    def manifest_path(self) -> Path:
        return self.root / MANIFEST

    def manifest(self) -> dict[str, Any]:
        """``manifest.json`` checked for its shape (a named ArtefactError when it is not one)."""
        if not self.manifest_path.exists():
            return {"stages": {}}
        data = read_json(self.manifest_path)
        stages = data.get("stages") if isinstance(data, dict) else None
        if not isinstance(stages, dict):
            got = "a mapping without it" if isinstance(data, dict) else type(data).__name__
            raise ArtefactError(
                f"{self.manifest_path}: not a rapomdp manifest (expected a mapping with "
                f"'stages', got {got}); move it away and rerun the stages")
        for name, record in stages.items():
            if (not isinstance(record, dict) or not isinstance(record.get("key"), str)
                    or not isinstance(record.get("files"), list)):
                raise ArtefactError(f"{self.manifest_path}: the record of stage {str(name)[:40]!r}"
                                    " is damaged (no key or files); rerun it with --force")
        return data

    @property
    def marker_path(self) -> Path:
        return self.root / MARKER

    @property
    def scratch(self) -> Path:
        """:data:`SCRATCH`: where a run keeps what it is still writing."""
        return self.root / SCRATCH

    def _named(self) -> str:
        """The root as the user knows it (the current folder's path for ``.``)."""
        return str(self.root) if str(self.root) not in ("", ".") else str(Path.cwd())

    def _marker_format(self) -> int | None:
        """The workspace format its marker names (1 when unreadable), None without one."""
        try:
            if not stat.S_ISREG(os.lstat(self.marker_path).st_mode):
                return None
        except OSError:
            return None
        try:
            with open(self.marker_path, "rb") as handle:
                data = json.loads(handle.read(4096).decode("utf-8"))
            found = data.get("format") if isinstance(data, dict) else None
            return found if isinstance(found, int) and not isinstance(found, bool) else 1
        except (OSError, ValueError):
            return 1  # damaged, but no one else writes a file of that name

    def _write_marker(self) -> None:
        """Write the marker unless it is there (another run may be making it too)."""
        from rapomdp import __version__

        text = json.dumps({"format": MARKER_FORMAT, "made_by": f"rapomdp {__version__}"}) + "\n"
        try:
            fd = os.open(self.marker_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            return
        try:
            os.write(fd, text.encode())
        finally:
            os.close(fd)

    def check(self) -> str:
        """What the root is to a command that would write there, found without writing:
        ``"new"`` (a missing or empty folder), ``"workspace"`` (its marker) or ``"older"``
        (the valid ``manifest.json`` of a workspace made before markers existed). Anything
        else is a :class:`NotAWorkspaceError` naming it."""
        name = self._named()
        try:
            mode = os.stat(self.root).st_mode
        except FileNotFoundError:
            if os.path.islink(self.root):
                raise NotAWorkspaceError(f"{name}: a symbolic link to a folder that does not "
                                         f"exist ({os.readlink(self.root)[:200]})") from None
            return "new"
        except OSError as exc:
            raise NotAWorkspaceError(describe_os_error(exc, name)) from None
        if not stat.S_ISDIR(mode):
            raise NotAWorkspaceError(f"{name}: not a folder; a workspace is a folder (give "
                                     "the path of a new one)")
        found = self._marker_format()
        if found is not None:
            if found > MARKER_FORMAT:
                raise NotAWorkspaceError(
                    f"{name}: a workspace of format {found}, made by a newer rapomdp (this one "
                    f"knows format {MARKER_FORMAT}): upgrade rapomdp, or use another workspace")
            return "workspace"
        try:
            entries = os.listdir(self.root)
        except OSError as exc:
            raise NotAWorkspaceError(describe_os_error(exc, name)) from None
        if not entries:
            return "new"
        why = f"no {MARKER} or {MANIFEST}"
        if MANIFEST in entries:
            try:
                self.manifest()
                return "older"
            except ArtefactError:
                why = f"no {MARKER}, and its {MANIFEST} is not a rapomdp manifest"
        raise NotAWorkspaceError(
            f"{name}: not a rapomdp workspace ({why}) and not empty; rapomdp writes only into "
            f"a workspace it made or an empty folder: give a new folder, e.g. "
            f"{Path(name) / 'workspace'}")

    def claim(self) -> bool:
        """:meth:`check` the root before anything is written there; a missing or empty folder
        becomes a new workspace (the folder and its marker). Returns whether the marker is
        still to be written (an older workspace: its next locked run writes it)."""
        state = self.check()
        if state == "new":
            self._create()
        return state == "older"

    def _create(self) -> None:
        """Make the root (and its parents) a new workspace: the folder and its marker."""
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self._write_marker()
        except OSError as exc:
            raise ArtefactError(describe_os_error(exc)) from None

    def recorded_config(self) -> Config | None:
        """The configuration the workspace's artefacts were made with (``W/config.yaml``; when
        it is missing, the one the stage records hold, :meth:`records_config_data`), or None
        for a new workspace."""
        if self.config_path.exists():
            return config_from_dict(read_config_data(self.config_path), str(self.config_path))
        data = self.records_config_data()
        return None if data is None else config_from_dict(data, self.records_source())

    def records_config_data(self) -> dict[str, Any] | None:
        """The configuration sections the manifest's stage records hold, merged (where two
        disagree, the stage that finished last wins; a section no stage read is left out, so
        it is the default), or None when no stage is recorded."""
        records = [record for record in self.manifest()["stages"].values()
                   if isinstance(record.get("config"), dict)]
        if not records:
            return None
        data: dict[str, Any] = {}
        for record in sorted(records, key=lambda r: str(r.get("finished", ""))):  # stable
            data.update(record["config"])
        return data

    def records_source(self) -> str:
        """How a configuration rebuilt from the stage records is named in messages."""
        return f"the stage records of {self.manifest_path} ({CONFIG_FILE} is missing)"

    def _write_file(self, path: Path, text: str) -> None:
        """Write one of the workspace's own files atomically, its temporary in the scratch
        folder (so that a kill leaves nothing beside the user's files)."""
        scratch = self._scratch_dir()
        try:
            write_text_atomic(path, text, scratch)
        finally:
            self._drop_scratch()

    def _drop_scratch(self) -> None:
        try:
            self.scratch.rmdir()  # only when empty
        except OSError:
            pass

    def record_config(self, config: Config) -> None:
        """Write ``W/config.yaml`` (skipped when unchanged, so a read-only cached run works)."""
        text = config.to_yaml()
        try:
            if self.config_path.exists() and self.config_path.read_text("utf-8") == text:
                return
        except (OSError, UnicodeDecodeError):
            pass
        self._write_file(self.config_path, text)

    @contextmanager
    def locked(self) -> Iterator[None]:
        """Hold ``W/.lock`` (a second run exits naming the first's pid); then remove what a
        killed run left. The lock is the kernel's (flock): it ends with its process, even
        on SIGKILL. A read-only workspace is used unlocked: nothing can be written to it.
        A folder that is not a workspace is refused first (:meth:`claim`), its files untouched.
        """
        needs_marker = self.claim()
        key = self.root.resolve()
        if key in _HELD:
            _HELD[key] += 1
            try:
                yield
            finally:
                _HELD[key] -= 1
            return
        fd = self._open_lock()
        if fd is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
                shared = os.fstat(fd).st_nlink > 1
                os.close(fd)
                if shared:  # a hard-linked copy of a workspace shares the kernel's lock
                    raise WorkspaceBusyError(
                        f"{self.root}: its {LOCK} is a hard link shared with another folder "
                        f"(a copy made with cp -al?), where rapomdp run pid {holder} holds it; "
                        f"delete {self.root / LOCK} (only this link) and rerun") from None
                raise WorkspaceBusyError(
                    f"{self.root}: in use by another rapomdp run (pid {holder}); wait for it "
                    "to finish, or use another workspace") from None
            if os.access(self.root / LOCK, os.W_OK):
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                if needs_marker:
                    self._write_marker()
                self.clean_leftovers()
        _HELD[key] = 1
        try:
            yield
        finally:
            del _HELD[key]
            if fd is not None:
                os.close(fd)  # closing releases the flock

    def _own(self, name: str, folder: bool) -> Path:
        """``W/name``, one of the workspace's own files (or, ``folder``, folders), when it is
        that or absent: a symbolic link or anything else there is refused by name, so that
        nothing is written, truncated or emptied through it."""
        path = self.root / name
        mode = file_mode(path)
        if mode is None:
            return path
        if not (stat.S_ISDIR(mode) if folder else stat.S_ISREG(mode)):
            kind = "a symbolic link" if stat.S_ISLNK(mode) else "not a " + (
                "folder" if folder else "regular file")
            raise StageError(f"{path}: {kind}; it is the workspace's own "
                             f"{'folder' if folder else 'file'}: remove it and rerun")
        return path

    def _scratch_dir(self) -> Path:
        """The scratch folder, made when missing (a real folder: :meth:`_own`)."""
        path = self._own(SCRATCH, folder=True)
        try:
            path.mkdir(exist_ok=True)
        except OSError as exc:
            raise ArtefactError(describe_os_error(exc)) from None
        return self._own(SCRATCH, folder=True)

    def _open_lock(self) -> int | None:
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            path = self._own(LOCK, folder=False)
            if path.exists() and not os.access(path, os.W_OK):
                return os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
            return os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o666)
        except OSError as exc:
            if exc.errno in (errno.EACCES, errno.EROFS, errno.EPERM) and self.root.is_dir():
                return None
            raise ArtefactError(describe_os_error(exc)) from None

    def clean_leftovers(self) -> list[str]:
        """Empty the scratch folder of runs that died (call holding the lock); returns the
        names it held.

        A stage folder a run had moved aside (``STAGE.old-PID``) is moved back when the swap
        did not finish, so a kill at any instant loses nothing; the rest is removed. Nothing
        outside the scratch folder is looked at: only the project writes there.
        """
        try:
            entries = sorted(self._own(SCRATCH, folder=True).iterdir())
        except FileNotFoundError:
            return []
        cleaned = []
        for path in entries:
            match = _LEFTOVER.fullmatch(path.name)
            target = self.root / match["name"] if match is not None else None
            if (match is not None and target is not None and match["kind"] == "old"
                    and "/" not in match["name"] and match["name"] not in (".", "..")
                    and not os.path.lexists(target)):
                os.replace(path, target)
            elif path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            else:
                path.unlink()
            cleaned.append(path.name)
        self._drop_scratch()
        return cleaned

    @property
    def config_path(self) -> Path:
        return self.root / CONFIG_FILE

    def config(self, default: Config | None = None) -> Config:
        """The configuration the workspace was run with: ``W/config.yaml``, validated.

        When the file is missing: ``default`` if given, else a :class:`StageError` naming it.
        """
        recorded = self.recorded_config()
        if recorded is not None:
            return recorded
        if default is not None:
            return default
        raise StageError(f"{self.config_path}: not found; a workspace made by `rapomdp` "
                         f"holds the configuration it ran with")

    def stage_dir(self, name: str) -> Path:
        return self.root / name

    def inputs(self, stage: Stage) -> StageInputs:
        """The folders of ``stage``'s inputs here, each a finished stage (:meth:`require`)."""
        return StageInputs.of(stage.name, {name: self.require(name) for name in stage.inputs})

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

    def _key_parts(self, stage: Stage, config: Config) -> tuple[str, dict[str, str], str | None]:
        """The stage's key, its inputs' keys and its external fingerprint."""
        stages = self.manifest()["stages"]
        upstream = {}
        for name in stage.inputs:
            if name not in stages:
                raise StageError(f"stage '{stage.name}' needs stage '{name}', which has not run")
            upstream[name] = stages[name]["key"]
        external = stage.fingerprint(config) if stage.fingerprint else None
        return stage_key(stage, config, upstream, external), upstream, external

    def key_of(self, stage: Stage, config: Config) -> str:
        return self._key_parts(stage, config)[0]

    def staleness(self, stages: Sequence[Stage], config: Config,
                  external: bool = True) -> dict[str, list[str]]:
        """Why each recorded stage's artefacts would not be reused under ``config``.

        ``stages`` in pipeline order; a stage is stale when a section it reads changed, its
        code version changed, an input stage is stale or was redone since, or (``external``)
        the files it reads from outside changed. Stages without a record are left out.
        """
        records = self.manifest()["stages"]
        stale: dict[str, list[str]] = {}
        for stage in stages:
            record = records.get(stage.name)
            if record is None:
                continue
            reasons = []
            if not self.stage_dir(stage.name).is_dir():
                reasons.append("its folder is missing")
            if str(record.get("version")) != stage.version:
                reasons.append(f"stage version {record.get('version')} -> {stage.version}")
            recorded = record.get("config") if isinstance(record.get("config"), dict) else {}
            for section in stage.sections:
                if recorded.get(section) != config.section(section):
                    reasons.append(describe_change(section, recorded.get(section),
                                                   config.section(section)))
            input_keys = record.get("input_keys")
            for name in stage.inputs:
                if name in stale:
                    reasons.append(f"input {name} is stale")
                elif name not in records:
                    reasons.append(f"input {name} has no record")
                elif isinstance(input_keys, dict) and input_keys.get(name) != records[name]["key"]:
                    reasons.append(f"input {name} was redone since")
            if external and not reasons:
                try:
                    if self.key_of(stage, config) != record["key"]:
                        reasons.append("its input files changed" if stage.fingerprint
                                       else "its inputs changed")
                except (StageError, ArtefactError, ConfigError, OSError) as exc:
                    reasons.append(f"its inputs cannot be read ({str(exc)[:120]})")
            if reasons:
                stale[stage.name] = reasons
        return stale

    def status(self, stages: Sequence[Stage], config: Config) -> list[StageStatus]:
        """One :class:`StageStatus` per stage of ``stages`` (pipeline order), from the manifest
        and :meth:`staleness` under ``config`` (input files included)."""
        records = self.manifest()["stages"]
        stale = self.staleness(stages, config)
        rows = []
        for stage in stages:
            record = records.get(stage.name)
            if record is None:
                rows.append(StageStatus(stage.name, "not run"))
                continue
            seconds = record.get("seconds")
            rows.append(StageStatus(
                stage.name, "stale" if stage.name in stale else "current",
                stale.get(stage.name, []), len(record["files"]), record["key"],
                float(seconds) if isinstance(seconds, int | float) else None,
                str(record["finished"]) if record.get("finished") is not None else None,
                record.get("shared_from")))
        return rows

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
        workers, threads and progress bars; a stage that ran is recorded in the manifest."""
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
            shutil.copytree(folder, tmp, copy_function=_link_or_copy)
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

    def _swap_in(self, new: Path, target: Path) -> None:
        """Replace ``target`` (a stage's folder, :meth:`_check_replaceable`) by ``new``: two
        renames, the old folder moved aside into the scratch folder, undone if the second
        fails."""
        old = self.scratch / f"{target.name}.old-{os.getpid()}"
        moved = False
        try:
            if os.path.lexists(old):
                shutil.rmtree(old)
            if os.path.lexists(target):
                os.replace(target, old)
                moved = True
            try:
                os.replace(new, target)
            except OSError:
                if moved and not os.path.lexists(target):
                    os.replace(old, target)
                    moved = False
                raise
        except OSError as exc:
            raise ArtefactError(
                f"{target}: the new artefacts could not be moved into place "
                f"({describe_os_error(exc).split(': ', 1)[-1]}); the earlier ones are intact"
            ) from None
        if moved:
            shutil.rmtree(old, ignore_errors=True)


def _link_or_copy(source: str, target: str) -> None:
    """A hard link of ``source`` at ``target``, or a copy where links cannot be made."""
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def _flatten(value: Any, prefix: str) -> dict[str, Any]:
    if isinstance(value, dict):
        flat: dict[str, Any] = {}
        for key, item in value.items():
            flat.update(_flatten(item, f"{prefix}.{key}"))
        return flat
    return {prefix: value}


def describe_change(section: str, old: Any, new: Any, limit: int = 3) -> str:
    """``train.epochs 25 -> 5, ...``: the keys of a section that differ, values bounded."""
    before, after = _flatten(old, section), _flatten(new, section)
    keys = [k for k in sorted(before.keys() | after.keys()) if before.get(k) != after.get(k)]

    def shown(value: Any) -> str:
        return json.dumps(value, default=str)[:40]

    parts = [f"{k} {shown(before.get(k))} -> {shown(after.get(k))}" for k in keys[:limit]]
    more = f", +{len(keys) - limit} more" if len(keys) > limit else ""
    return (", ".join(parts) + more) if parts else f"{section} changed"


def read_stage_record(path: Path) -> dict[str, Any]:
    try:
        return read_json(path / STAGE_RECORD)
    except ArtefactError as exc:
        raise StageError(str(exc)) from exc
