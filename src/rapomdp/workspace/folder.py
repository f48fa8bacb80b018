"""A workspace's folder: its paths, the scratch folder of a run's temporary files, atomic
writes of the workspace's own files, and the swap that puts a stage's new folder in place."""

from __future__ import annotations

import os
import re
import shutil
import stat
from pathlib import Path

from rapomdp.io import ArtefactError, describe_os_error, file_mode, write_text_atomic
from rapomdp.workspace.layout import CONFIG_FILE, MANIFEST, MARKER, SCRATCH, StageError

_LEFTOVER = re.compile(r"(?P<name>.+)\.(?P<kind>tmp|old)-(?P<pid>\d+)")


class WorkspaceFolder:
    """The paths of a workspace and its temporary files (the base of :class:`Workspace`)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    @property
    def manifest_path(self) -> Path:
        """``W/manifest.json``: every stage's record."""
        return self.root / MANIFEST

    @property
    def marker_path(self) -> Path:
        """``W/.rapomdp-workspace``: the file that makes the folder a workspace."""
        return self.root / MARKER

    @property
    def scratch(self) -> Path:
        """:data:`SCRATCH`: where a run keeps what it is still writing."""
        return self.root / SCRATCH

    def _named(self) -> str:
        """The root as the user knows it (the current folder's path for ``.``)."""
        return str(self.root) if str(self.root) not in ("", ".") else str(Path.cwd())

    @property
    def config_path(self) -> Path:
        """``W/config.yaml``: the configuration the artefacts were made with."""
        return self.root / CONFIG_FILE

    def stage_dir(self, name: str) -> Path:
        """``W/name``, the folder of stage ``name`` (whether or not it has run)."""
        return self.root / name

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


def link_or_copy(source: str, target: str) -> None:
    """A hard link of ``source`` at ``target``, or a copy where links cannot be made."""
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)

