r"""The Debian package behind the real-CAD sets: fetched with ``apt-get download``, checked by
its control fields, its VRML folders unpacked once, and each file's licence read from the
package's DEP-5 ``copyright`` file.

Example:
    >>> stanzas = parse_copyright("Files: *\nLicense: CC-BY-SA-4.0\n\n"
    ...                           "Files: Capacitor_THT.3dshapes/*\nLicense: GPL-3+\n")
    >>> licence_for("Capacitor_THT.3dshapes/C.wrl", stanzas), licence_for("LED.wrl", stanzas)
    ('GPL-3+', 'CC-BY-SA-4.0')
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import re
import shutil
import subprocess
from pathlib import Path

from rapomdp.data.build.common import DatasetBuildError, refuse_held_back
from rapomdp.io import write_text_atomic

PACKAGE = "kicad-packages3d"
MODELS_DIR = "usr/share/kicad/3dmodels"
COPYRIGHT = f"usr/share/doc/{PACKAGE}/copyright"


def parse_copyright(text: str) -> list[tuple[list[str], str]]:
    """The stanzas of a DEP-5 (machine-readable) Debian copyright file.

    Args:
        text: the file's text.

    Returns:
        (``Files:`` patterns, ``License:`` short name) per stanza, in file order.
    """
    stanzas = []
    for block in re.split(r"\n\s*\n", text):
        files = re.search(r"^Files:(.*?)(?=^\S)", block + "\nEnd:", re.S | re.M)
        licence = re.search(r"^License:\s*(\S+)", block, re.M)
        if files and licence:
            stanzas.append((files.group(1).split(), licence.group(1)))
    return stanzas


def licence_for(path: str, stanzas: list[tuple[list[str], str]]) -> str:
    """The licence of one file under DEP-5: the last matching stanza wins.

    Args:
        path: the file, relative to the models folder (``Crystal.3dshapes/X.wrl``).
        stanzas: :func:`parse_copyright`'s.

    Returns:
        The licence's short name, or ``"unknown"``.
    """
    found = "unknown"
    for patterns, licence in stanzas:
        if any(fnmatch.fnmatchcase(path, pattern) for pattern in patterns):
            found = licence
    return found


def fetch_deb(cache: Path, package: str = PACKAGE) -> Path:
    """The package's ``.deb`` in ``cache``, downloaded with ``apt-get download`` when missing.

    Args:
        cache: a folder kept between builds.
        package: the Debian package.

    Returns:
        The newest cached ``<package>_*.deb``.

    Raises:
        DatasetBuildError: a held-back package, no ``apt-get``, or the download failed.
    """
    refuse_held_back([package], "package")
    cache.mkdir(parents=True, exist_ok=True)
    debs = sorted(cache.glob(f"{package}_*.deb"))
    if debs:
        return debs[-1]
    if shutil.which("apt-get") is None:
        raise DatasetBuildError(f"apt-get is not on this system: download {package}'s .deb "
                                "elsewhere and pass it with --deb")
    result = subprocess.run(["apt-get", "download", package], cwd=cache, capture_output=True,
                            text=True, check=False)
    debs = sorted(cache.glob(f"{package}_*.deb"))
    if result.returncode != 0 or not debs:
        raise DatasetBuildError(f"apt-get download {package} failed (run 'apt-get update' "
                                f"first?): {result.stderr.strip()}")
    return debs[-1]


def deb_field(deb: Path, name: str) -> str:
    """One control field of a ``.deb`` (``dpkg-deb -f``).

    Args:
        deb: the package file.
        name: the field (``Package``, ``Version``, ``Homepage`` ...).

    Returns:
        Its value, or "" when the package has no such field.

    Raises:
        DatasetBuildError: no ``dpkg-deb``, or the file is not a package.
    """
    if shutil.which("dpkg-deb") is None:
        raise DatasetBuildError("dpkg-deb is not on this system (Debian's dpkg): unpack the "
                                "package elsewhere and pass the folder with --source")
    result = subprocess.run(["dpkg-deb", "-f", str(deb), name], capture_output=True, text=True,
                            check=False)
    if result.returncode != 0:
        raise DatasetBuildError(f"{deb} is not a Debian package: {result.stderr.strip()}")
    return result.stdout.strip()


def check_deb(deb: Path) -> None:
    """Refuse a ``.deb`` that is held back or not ``kicad-packages3d``, by name and by its
    ``Package`` field.

    Args:
        deb: the package file given.

    Raises:
        DatasetBuildError: saying which.
    """
    refuse_held_back([deb.name], "--deb file")
    if not deb.is_file():
        raise DatasetBuildError(f"--deb {deb}: no such file")
    package = deb_field(deb, "Package")
    refuse_held_back([package], "package")
    if package != PACKAGE:
        raise DatasetBuildError(f"{deb} is the package {package!r}, not {PACKAGE}")


def extract(deb: Path, cache: Path, class_map: dict[str, str]) -> Path:
    """The VRML files of the mapped folders and the copyright file, unpacked once.

    Args:
        deb: the package file.
        cache: where the extraction is kept (a marker written last says it is complete).
        class_map: KiCad folder -> class; only these folders are extracted.

    Returns:
        The unpacked root (it holds :data:`MODELS_DIR` and :data:`COPYRIGHT`).

    Raises:
        DatasetBuildError: ``dpkg-deb`` or ``tar`` failed.
    """
    digest = hashlib.sha256(json.dumps(sorted(class_map)).encode()).hexdigest()[:10]
    root = cache / f"{deb.stem}-{digest}"
    if (root / ".complete").is_file():
        return root
    partial = root.with_name(root.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    patterns = [f"./{MODELS_DIR}/{folder}.3dshapes/*.wrl" for folder in class_map]
    with subprocess.Popen(["tar", "-x", "-C", str(partial), "--wildcards", f"./{COPYRIGHT}",
                           *patterns], stdin=subprocess.PIPE, stderr=subprocess.PIPE) as tar:
        dpkg = subprocess.run(["dpkg-deb", "--fsys-tarfile", str(deb)], stdout=tar.stdin,
                              stderr=subprocess.PIPE, check=False)
        assert tar.stdin is not None and tar.stderr is not None
        tar.stdin.close()
        failed = tar.wait() != 0 or dpkg.returncode != 0
        message = (tar.stderr.read().decode(errors="replace")
                   + dpkg.stderr.decode(errors="replace")).strip()
    if failed:
        shutil.rmtree(partial, ignore_errors=True)
        raise DatasetBuildError(f"extracting {deb} failed: {message}")
    write_text_atomic(partial / ".complete", "ok\n")
    shutil.rmtree(root, ignore_errors=True)
    partial.rename(root)
    return root
