"""The names of a workspace's own files and folders, and the errors of its stages."""

from __future__ import annotations

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


class StageError(RuntimeError):
    """A stage cannot run: a missing input, or bad data it names."""


class WorkspaceBusyError(StageError):
    """Another run holds the workspace's lock."""


class NotAWorkspaceError(StageError):
    """A folder a command would write into is not a workspace (nor empty), or not a folder."""


