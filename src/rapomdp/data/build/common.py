"""What every dataset builder shares: its error, the refusal of held-back sources, and the
folder swap that makes a rebuilt mesh folder appear whole or not at all."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable
from pathlib import Path

#: Sources this project never reads, in datasets, corpora or tests, refused by name: the Debian
#: packages of Sweet Home 3D's furniture models are held back for judging.
HELD_BACK = ("sweethome3d",)
#: Written into every folder a builder makes: only such a folder (or an empty one) is replaced.
BUILT_MARKER = ".rapomdp-dataset-build"


class DatasetBuildError(ValueError):
    """A dataset cannot be built as asked (the message says why and what to do)."""


def refuse_held_back(names: Iterable[str], what: str) -> None:
    """Refuse any source whose name contains a held-back name (case-insensitive).

    Args:
        names: package names, file names or path parts a builder is about to read.
        what: what the names are, for the message ("package", "--deb file" ...).

    Raises:
        DatasetBuildError: naming the held-back source.

    Example:
        >>> refuse_held_back(["kicad-packages3d"], "package")
        >>> try:
        ...     refuse_held_back(["sweethome3d-furniture"], "package")
        ... except DatasetBuildError as exc:
        ...     print(str(exc).split(" (")[0])
        package 'sweethome3d-furniture' is held back
    """
    for name in names:
        for held in HELD_BACK:
            if held in str(name).lower():
                raise DatasetBuildError(
                    f"{what} {name!r} is held back (no {held}* source is read by this "
                    "project's datasets, corpora or tests); use another source")


def check_replaceable(out: Path) -> Path:
    """Refuse an ``out`` a build may not replace: anything but a new or empty folder, or one
    a builder made (it holds :data:`BUILT_MARKER`). Builders call it before any work.

    Args:
        out: the mesh folder a build would replace whole.

    Returns:
        ``out``, resolved.

    Raises:
        DatasetBuildError: naming the folder and what to do.
    """
    out = out.resolve()
    if out.exists() and not (out.is_dir() and (not any(out.iterdir())
                                               or (out / BUILT_MARKER).is_file())):
        raise DatasetBuildError(
            f"{out} exists and was not made by 'rapomdp dataset build' (no {BUILT_MARKER}): "
            "a build replaces its --out folder whole; name a new or empty folder")
    return out


def building_folder(out: Path) -> Path:
    """A fresh hidden folder beside ``out`` to build into, after removing any left by an
    interrupted build of the same ``out``.

    Args:
        out: the mesh folder the build will replace.

    Returns:
        ``out.parent/.<name>.building-<pid>``, holding only :data:`BUILT_MARKER`.

    Raises:
        DatasetBuildError: ``out`` exists and is not an empty folder or one a builder made
            (it would be replaced whole: a folder of the user's own is never deleted).
    """
    out = check_replaceable(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.building-*"):
        shutil.rmtree(stale, ignore_errors=True)
    for stale in out.parent.glob(f".{out.name}.old-*"):
        shutil.rmtree(stale, ignore_errors=True)
    building = out.parent / f".{out.name}.building-{os.getpid()}"
    building.mkdir()
    (building / BUILT_MARKER).write_text("made by rapomdp dataset build; replaced whole by the "
                                         "next build into this folder\n")
    return building


def swap_in(building: Path, out: Path) -> Path:
    """Replace ``out`` by the finished ``building`` folder: renames only, so a reader sees the
    old folder or the new one, never a mix.

    Args:
        building: the folder :func:`building_folder` made, now complete.
        out: the mesh folder to replace (it need not exist).

    Returns:
        ``out``, resolved.
    """
    out = out.resolve()
    old = out.parent / f".{out.name}.old-{os.getpid()}"
    if out.exists():
        out.rename(old)
    building.rename(out)
    shutil.rmtree(old, ignore_errors=True)
    return out
