"""Safe, atomic artefact I/O (every file appears whole or not at all, nothing is unpickled) and
the content hashes that key cached stages."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import re
import stat
import tempfile
import zipfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    pass


def _default_file_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


_FILE_MODE = _default_file_mode()


class ArtefactError(RuntimeError):
    """An artefact is missing, unreadable or not what the reader expects."""


def _short_name(name: str, limit: int = 200) -> str:
    """``name`` cut to at most ``limit`` bytes of UTF-8 (whole characters kept)."""
    return name.encode("utf-8")[:limit].decode("utf-8", errors="ignore")


def _kind_of(mode: int) -> str:
    """What a file of this ``st_mode`` is, in words (for a refusal)."""
    for test, words in ((stat.S_ISDIR, "a folder"), (stat.S_ISLNK, "a symbolic link"),
                        (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                        (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return words
    return "a special file"


def file_mode(path: str | Path) -> int | None:
    """The ``st_mode`` of what is at ``path`` itself (a link, not its target), or None when
    nothing is there; any other failure is a named ArtefactError."""
    try:
        return os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ArtefactError(describe_os_error(exc, path)) from None


def check_output_path(path: str | Path) -> Path:
    """``path`` when a file may be written there: nothing is there yet, or a regular file
    (which the new one replaces); a folder, symbolic link, device, FIFO, socket or other
    special file is refused by name (an ArtefactError), before anything is written."""
    path = Path(path)
    mode = file_mode(path)
    if mode is None:
        return path
    if not stat.S_ISREG(mode):
        raise ArtefactError(f"{path}: {_kind_of(mode)}, not a regular file; an output replaces "
                            "only a regular file (or makes a new one): give another path")
    return path


@contextmanager
def atomic_path(path: str | Path, tmp_dir: str | Path | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (or in ``tmp_dir``, a folder on the same file
    system); it replaces ``path`` only if the block succeeds, and only when ``path`` is a
    regular file or absent (:func:`check_output_path`, checked before and after the block)."""
    path = check_output_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    folder = path.parent if tmp_dir is None else Path(tmp_dir)
    # the name cut so the temporary one fits the 255-byte limit of a file name
    fd, tmp = tempfile.mkstemp(prefix=f".{_short_name(path.name)}.", suffix=".tmp", dir=folder)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, _FILE_MODE)  # mkstemp makes 0600; artefacts get the usual mode
        check_output_path(path)  # nothing else took its place meanwhile
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_bytes_atomic(path: str | Path, data: bytes, tmp_dir: str | Path | None = None) -> None:
    with atomic_path(path, tmp_dir) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: str | Path, text: str, tmp_dir: str | Path | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    write_bytes_atomic(path, text.encode("utf-8"), tmp_dir)
    return Path(path)


def write_json_atomic(path: str | Path, obj: Any, tmp_dir: str | Path | None = None) -> None:
    write_bytes_atomic(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode(),
                       tmp_dir)


#: Why an operating-system error happened, in words a user acts on (by errno).
_OS_HINTS = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied (a read-only folder?)",
    errno.EPERM: "operation not permitted",
    errno.ENOENT: "not found",
    errno.EISDIR: "is a folder, not a file",
    errno.ENOTDIR: "a part of the path is not a folder",
    errno.ELOOP: "too many levels of symbolic links (a link that leads back to itself?)",
}


def describe_os_error(exc: OSError, path: str | Path | None = None) -> str:
    """One line naming the file and the cause of an operating-system error."""
    where = path if path is not None else (exc.filename or "(unknown file)")
    reason = _OS_HINTS.get(exc.errno or -1) or exc.strerror or type(exc).__name__
    if exc.filename2:
        where = f"{where} -> {exc.filename2}"
    return f"{where}: {reason}"


def decode_text(data: bytes, source: str | Path) -> str:
    """Text of a file in any common encoding: UTF-8 (with or without a byte-order mark), UTF-16
    or UTF-32 with one, else Windows-1252 / Latin-1 (a comment written on an older system);
    a named ArtefactError for binary data (NUL bytes).

    A statistical guess (charset_normalizer) misreads short files such as a configuration, so
    the single-byte fallbacks are fixed: every byte sequence decodes under Latin-1.
    """
    for bom, codec in ((b"\xef\xbb\xbf", "utf-8-sig"), (b"\xff\xfe\x00\x00", "utf-32"),
                       (b"\x00\x00\xfe\xff", "utf-32"), (b"\xff\xfe", "utf-16"),
                       (b"\xfe\xff", "utf-16")):
        if data.startswith(bom):
            try:
                return data.decode(codec)
            except UnicodeDecodeError:
                raise ArtefactError(f"{source}: not valid {codec} text although it starts "
                                    "with that byte-order mark") from None
    if b"\x00" in data:
        raise ArtefactError(f"{source}: binary data (NUL bytes), not a text file")
    for codec in ("utf-8", "cp1252"):
        try:
            return data.decode(codec)
        except UnicodeDecodeError:
            pass
    return data.decode("latin-1")


def read_text(path: str | Path) -> str:
    """A text file (configuration, OBJ, table) in any common encoding (:func:`decode_text`)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ArtefactError(describe_os_error(exc, path)) from None
    return decode_text(data, path)


def read_json(path: str | Path) -> Any:
    """A JSON file the project wrote (always UTF-8); named errors when it is not."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError as exc:
        raise ArtefactError(f"{path}: not found") from exc
    except OSError as exc:
        raise ArtefactError(describe_os_error(exc, path)) from None
    except UnicodeDecodeError as exc:
        raise ArtefactError(f"{path}: not valid JSON (byte {exc.start} is not UTF-8)") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ArtefactError(f"{path}: not valid JSON ({exc})") from exc
    except RecursionError:
        raise ArtefactError(f"{path}: not valid JSON (nested too deeply)") from None


#: A name that may become one path component on any common file system: no path separator,
#: none of ``: * ? " < > |``, no control character, no leading dot, no leading or trailing
#: space, no trailing dot; 1 to 128 characters.
_BAD = '\\x00-\\x1f\\x7f/\\\\:*?"<>|'
_PLAIN_NAME = re.compile(f"[^{_BAD}. ]|[^{_BAD}. ][^{_BAD}]{{0,126}}[^{_BAD}. ]")
_UNSAFE_CHARACTER = re.compile(f"[{_BAD}]")


def plain_name(text: str) -> str:
    """``text`` made a plain name (:func:`check_plain_name`): unsafe characters become ``_``,
    leading dots and spaces are dropped. For model ids taken from file names."""
    name = _UNSAFE_CHARACTER.sub("_", text).lstrip(". ").rstrip(". ")[:128]
    return name if _PLAIN_NAME.fullmatch(name) else "model"


def check_plain_name(name: object, what: str, source: str | Path) -> str:
    """``name`` when it is safe as one file or folder name; else a named ArtefactError.

    Class and model names are data, not paths: ``../../x``, ``a/b``, ``.hidden`` or a name
    with a control character never reach the file system.
    """
    if not isinstance(name, str) or not _PLAIN_NAME.fullmatch(name):
        shown = repr(name[:80]) if isinstance(name, str) else type(name).__name__
        raise ArtefactError(
            f"{source}: {what} {shown} is not a plain name (no / \\ : * ? \" < > | or control "
            "character, no leading dot, 1 to 128 characters): names are data, not paths")
    return name


def save_npz(path: str | Path, compressed: bool = False, **arrays: np.ndarray) -> None:
    """Write arrays to ``path`` (.npz) atomically; object arrays are refused (no pickle).

    ``compressed`` deflates at zlib level 3: half the time of NumPy's default level for depth
    images, at about 15 % more bytes.
    """
    for name, value in arrays.items():
        if np.asarray(value).dtype == object:
            raise TypeError(f"array {name!r} has dtype object, which would need pickle")
    method = zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED
    try:
        with atomic_path(path) as tmp:
            with zipfile.ZipFile(tmp, "w", compression=method, compresslevel=3) as archive:
                for name, value in arrays.items():
                    with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                        np.lib.format.write_array(member, np.asanyarray(value),
                                                  allow_pickle=False)
    except OSError as exc:  # a write in the archive says no file (ENOSPC): name the target
        if exc.filename is None:
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise


def load_npz(path: str | Path, keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Read every array of an .npz file (or only those named by ``keys``: the others are not
    read), never unpickling."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in keys or () if k not in data.files]
            if missing:
                raise ArtefactError(f"{path}: lacks the array(s) {', '.join(missing)}")
            return {key: data[key] for key in (data.files if keys is None else keys)}
    except ArtefactError:
        raise
    except FileNotFoundError as exc:
        raise ArtefactError(f"{path}: not found") from exc
    except ValueError as exc:
        raise ArtefactError(f"{path}: not a plain .npz archive ({exc})") from exc
    except EOFError:
        raise ArtefactError(f"{path}: empty file, not an .npz archive") from None
    except OSError as exc:
        raise ArtefactError(describe_os_error(exc, path)) from None
    except Exception as exc:  # BadZipFile, zlib.error, a member cut short: a damaged archive
        raise ArtefactError(f"{path}: damaged .npz archive ({type(exc).__name__}: "
                            f"{str(exc)[:200]})") from None


def stable_hash(obj: Any) -> str:
    """SHA-256 of an object's canonical JSON."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def fingerprint_files(paths: Sequence[Path]) -> str:
    """Hash of files' paths, sizes and modification times (as make does; cheap on big data)."""
    entries = []
    for path in sorted(paths):
        stat = path.stat()
        entries.append([str(path), stat.st_size, stat.st_mtime_ns])
    return stable_hash(entries)
