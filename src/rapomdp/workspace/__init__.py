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

One home per concern: :mod:`~rapomdp.workspace.layout` (the file names and the errors),
:mod:`~rapomdp.workspace.stages` (a stage, its inputs, its key and its records),
:mod:`~rapomdp.workspace.folder` (paths, temporary folders, atomic writes and swaps),
:mod:`~rapomdp.workspace.manifest` (the manifest, the recorded configuration, staleness),
:mod:`~rapomdp.workspace.lock` (the marker, the claim and the lock) and
:mod:`~rapomdp.workspace.running` (running a stage: :class:`Workspace`).
"""

from __future__ import annotations

from rapomdp.workspace.layout import (
    CONFIG_FILE,
    LOCK,
    MANIFEST,
    MARKER,
    MARKER_FORMAT,
    SCRATCH,
    STAGE_RECORD,
    NotAWorkspaceError,
    StageError,
    WorkspaceBusyError,
)
from rapomdp.workspace.running import Workspace
from rapomdp.workspace.stages import (
    Stage,
    StageInputs,
    StageResult,
    StageStatus,
    describe_change,
    read_stage_record,
    stage_key,
)

__all__ = [
    "CONFIG_FILE",
    "LOCK",
    "MANIFEST",
    "MARKER",
    "MARKER_FORMAT",
    "SCRATCH",
    "STAGE_RECORD",
    "NotAWorkspaceError",
    "Stage",
    "StageError",
    "StageInputs",
    "StageResult",
    "StageStatus",
    "Workspace",
    "WorkspaceBusyError",
    "describe_change",
    "read_stage_record",
    "stage_key",
]
