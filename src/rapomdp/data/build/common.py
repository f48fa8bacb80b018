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


def building_folder(out: Path) -> Path:
    """A fresh hidden folder beside ``out`` to build into, after removing any left by an
    interrupted build of the same ``out``.

    Args:
        out: the mesh folder the build will replace.

    Returns:
        ``out.parent/.<name>.building-<pid>``, created empty.
    """
    out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.building-*"):
        shutil.rmtree(stale, ignore_errors=True)
    for stale in out.parent.glob(f".{out.name}.old-*"):
        shutil.rmtree(stale, ignore_errors=True)
    building = out.parent / f".{out.name}.building-{os.getpid()}"
    building.mkdir()
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
