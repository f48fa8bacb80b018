"""The fault-injection harness: a tiny cached workspace, simulated read-only folders and full
disks, a snapshot of every file, and the CLI run in this process or in a child.

Each case (tests/faults/cases.py) sets a fault up, runs what a user would run and returns an
:class:`Outcome`; the suite asserts it and ``benchmarks/fault_table.py`` prints them all.
"""

from __future__ import annotations

import builtins
import errno
import hashlib
import http.server
import io
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from typer.testing import CliRunner

from rapomdp.cli import app

REPO = Path(__file__).resolve().parents[2]

#: The configuration of every case: three procedural classes, tiny renders (seconds).
TINY_YAML = """\
seed: 3
dataset: {classes: [cup, mug, bicycle], split: {train: 3, volume: 1, test: 1}}
camera: {width: 40, height: 30}
render: {views: 6}
viewpoints: {count: 16}
"""


@dataclass
class Outcome:
    """What a user saw and what became of their files."""

    exit_code: int
    message: str
    traceback: bool = False
    outside: list[str] = field(default_factory=list)
    lost: list[str] = field(default_factory=list)
    seconds: float = 0.0
    detail: str = ""


@dataclass(frozen=True)
class Case:
    """One bad input or fault: what is done, what must happen (``expect`` in the message;
    ``succeeds``: exit 0 is right), and the function that does it."""

    name: str
    fault: str
    expect: str
    run: Callable[[Path], Outcome]
    succeeds: bool = False


def snapshot(root: Path) -> dict[str, str]:
    """SHA-256 of every file under ``root`` (the lock file left out)."""
    if not root.exists():
        return {}
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".lock"}


def lost_files(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """Files that were there and are gone or changed."""
    return sorted(k for k, digest in before.items() if after.get(k) != digest)


def files_outside(root: Path, allowed: tuple[str, ...] = ("ws", "input", "tiny.yaml")) -> list[str]:
    """Anything under ``root`` that is neither the workspace nor the case's inputs."""
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")
                  if p.is_file() and p.relative_to(root).parts[0] not in allowed)


_TEMPLATE: Path | None = None


def cached_workspace(root: Path) -> Path:
    """``root/ws``: a workspace whose dataset and render stages are done (copied from one
    built once per process), and ``root/tiny.yaml``, its configuration."""
    global _TEMPLATE
    if _TEMPLATE is None:
        base = Path(tempfile.mkdtemp(prefix="rapomdp-faults-"))
        (base / "tiny.yaml").write_text(TINY_YAML)
        result = cli(["render", "-w", str(base / "ws"), "-c", str(base / "tiny.yaml")])
        assert result.exit_code == 0, result.message
        _TEMPLATE = base
    shutil.copytree(_TEMPLATE / "ws", root / "ws")
    shutil.copy(_TEMPLATE / "tiny.yaml", root / "tiny.yaml")
    return root / "ws"


def cli(args: list[str]) -> Outcome:
    """The ``rapomdp`` command in this process: exit code, its error line, any traceback."""
    start = time.perf_counter()
    result = CliRunner().invoke(app, args, env={"COLUMNS": "250"})
    seconds = time.perf_counter() - start
    crashed = result.exception is not None and not isinstance(result.exception, SystemExit)
    text = result.output
    if crashed:
        text += "".join(traceback.format_exception(result.exception))
    lines = text.splitlines()
    first = next((i for i, line in enumerate(lines) if line.startswith("error:")), None)
    if first is None:
        message = text.strip()[-300:]
    else:  # the error line and the lines indented under it (one per wrong key)
        block = [lines[first]]
        for line in lines[first + 1:]:
            if not line.startswith("  "):
                break
            block.append(line.strip())
        message = " ".join(block)
    return Outcome(result.exit_code, message,
                   traceback=crashed or "Traceback (most recent call last)" in text,
                   seconds=seconds, detail=text)


def cli_process(args: list[str], **popen: object) -> subprocess.Popen[str]:
    """The ``rapomdp`` command in a child process (for kills and locks)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO),
                                          os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-m", "rapomdp.cli", *args], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **popen)


def python_process(code: str) -> subprocess.Popen[str]:
    """A child Python running ``code`` with the project and the tests importable."""
    env = {**os.environ, "OMP_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO),
                                          os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-c", code], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def wait_for(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.05)


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie waiting to be reaped counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _under(path: object, root: Path) -> bool:
    try:
        return Path(os.fsdecode(path)).resolve().is_relative_to(root)  # type: ignore[arg-type]
    except (TypeError, ValueError, OSError):
        return False


@contextmanager
def read_only(root: Path) -> Iterator[None]:
    """Every write under ``root`` fails with EROFS, as on a read-only mount (the tests run as
    root here, for whom permission bits do not stop a write)."""
    root = root.resolve()
    real_open, real_os_open = builtins.open, os.open
    real = {name: getattr(os, name) for name in ("mkdir", "replace", "rename", "unlink",
                                                 "rmdir")}

    def refuse(path: object) -> None:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fsdecode(path))  # type: ignore[arg-type]

    def guarded_open(file: object, mode: str = "r", *args: object, **kwargs: object):
        if any(c in mode for c in "wax+") and _under(file, root):
            refuse(file)
        return real_open(file, mode, *args, **kwargs)  # type: ignore[call-overload]

    def guarded_os_open(path: object, flags: int, *args: object, **kwargs: object) -> int:
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and _under(path, root):
            refuse(path)
        return real_os_open(path, flags, *args, **kwargs)  # type: ignore[arg-type]

    def guard(name: str) -> Callable[..., object]:
        def guarded(path: object, *args: object, **kwargs: object) -> object:
            if _under(path, root):
                refuse(path)
            return real[name](path, *args, **kwargs)
        return guarded

    builtins.open = io.open = guarded_open  # type: ignore[assignment]
    os.open = guarded_os_open  # type: ignore[assignment]
    for name in real:
        setattr(os, name, guard(name))
    try:
        yield
    finally:
        builtins.open = io.open = real_open  # type: ignore[assignment]
        os.open = real_os_open  # type: ignore[assignment]
        for name, function in real.items():
            setattr(os, name, function)


class _FullDiskFile(io.FileIO):
    """A file that takes ``room`` bytes, then fails as a full disk does."""

    room = 4096

    def write(self, data: object) -> int:  # type: ignore[override]
        size = len(memoryview(data))  # type: ignore[arg-type]
        if self.tell() + size > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.name)
        return super().write(data)  # type: ignore[arg-type]


@contextmanager
def disk_full(root: Path) -> Iterator[None]:
    """Files written under ``root`` fail with ENOSPC after a few kilobytes."""
    root = root.resolve()
    real_open = builtins.open

    def guarded_open(file: object, mode: str = "r", *args: object, **kwargs: object):
        if any(c in mode for c in "wax+") and "b" in mode and _under(file, root):
            raw = _FullDiskFile(os.fsdecode(file), mode.replace("b", "").replace("+", "")  # type: ignore[arg-type]
                                + ("+" if "+" in mode else ""))
            return io.BufferedRandom(raw) if "+" in mode else io.BufferedWriter(raw)
        return real_open(file, mode, *args, **kwargs)  # type: ignore[call-overload]

    builtins.open = io.open = guarded_open  # type: ignore[assignment]
    try:
        yield
    finally:
        builtins.open = io.open = real_open  # type: ignore[assignment]


@contextmanager
def foreign_service(reply: bytes | None) -> Iterator[str]:
    """A service on 127.0.0.1 (a free port): an HTTP server (``reply`` None), else one that
    sends ``reply`` to every connection and stays silent."""
    if reply is None:
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                                 http.server.BaseHTTPRequestHandler)
        server.RequestHandlerClass.log_message = lambda *args: None  # type: ignore[method-assign]
        threading.Thread(target=server.serve_forever, daemon=True).start()
        try:
            yield f"tcp://127.0.0.1:{server.server_address[1]}"
        finally:
            server.shutdown()
            server.server_close()
        return
    listener = socket.create_server(("127.0.0.1", 0))
    connections: list[socket.socket] = []

    def answer() -> None:
        while True:
            try:
                connection, _ = listener.accept()
            except OSError:
                return
            connection.sendall(reply)
            connections.append(connection)

    threading.Thread(target=answer, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        listener.close()
        for connection in connections:
            connection.close()
