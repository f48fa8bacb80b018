"""A workspace's claim and lock: what a folder is to a command that would write there (its
marker), and the one run at a time that holds ``W/.lock``."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rapomdp.io import ArtefactError, describe_os_error
from rapomdp.workspace.layout import (
    LOCK,
    MANIFEST,
    MARKER,
    MARKER_FORMAT,
    NotAWorkspaceError,
    WorkspaceBusyError,
)
from rapomdp.workspace.manifest import WorkspaceManifest

#: Workspaces this process has locked (a nested run, e.g. Fig. 2's, takes the lock again).
_HELD: dict[Path, int] = {}


class WorkspaceLock(WorkspaceManifest):
    """The marker, the claim and the lock (a base of :class:`Workspace`)."""

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
        (the valid ``manifest.json`` of a workspace made before markers existed).

        Returns:
            ``"new"``, ``"workspace"`` or ``"older"``.

        Raises:
            NotAWorkspaceError: Anything else (a file, a folder of other files, a workspace
                of a newer format), named.

        Example:
            >>> import tempfile
            >>> from pathlib import Path
            >>> from rapomdp.workspace import Workspace
            >>> tmp = tempfile.TemporaryDirectory()
            >>> ws = Workspace(Path(tmp.name) / "ws")
            >>> ws.check()
            'new'
            >>> ws.claim()  # makes the folder and its marker
            False
            >>> ws.check()
            'workspace'
            >>> (Path(tmp.name) / "notes.txt").write_text("mine")
            4
            >>> Workspace(tmp.name).check()  # doctest: +ELLIPSIS
            Traceback (most recent call last):
            ...
            rapomdp.workspace.layout.NotAWorkspaceError: ...: not a rapomdp workspace ...
            >>> tmp.cleanup()
        """
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
        becomes a new workspace (the folder and its marker).

        Returns:
            Whether the marker is still to be written (an older workspace: its next locked
            run writes it).

        Raises:
            NotAWorkspaceError: The root is not a workspace nor empty (:meth:`check`).
        """
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

    @contextmanager
    def locked(self) -> Iterator[None]:
        """Hold ``W/.lock`` (a second run exits naming the first's pid); then remove what a
        killed run left. The lock is the kernel's (flock): it ends with its process, even
        on SIGKILL. A read-only workspace is used unlocked: nothing can be written to it.
        A folder that is not a workspace is refused first (:meth:`claim`), its files untouched.
        The same process may take the lock again inside (a nested run).

        Raises:
            WorkspaceBusyError: Another process holds the lock (the message names its pid).
            NotAWorkspaceError: The root is not a workspace nor empty.

        Example:
            >>> import tempfile
            >>> from rapomdp.workspace import Workspace
            >>> tmp = tempfile.TemporaryDirectory()
            >>> with Workspace(tmp.name).locked():
            ...     print(sorted(p.name for p in Workspace(tmp.name).root.iterdir()))
            ['.lock', '.rapomdp-workspace']
            >>> tmp.cleanup()
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

