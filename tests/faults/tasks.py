"""Worker tasks of the kill tests, in a module that imports nothing heavy (a spawned worker
imports it to find them)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path


def sleep_and_report_pid(folder: str, seconds: float) -> int:
    """Write this worker's pid to ``folder``, then sleep."""
    Path(folder, f"{os.getpid()}.pid").write_text(str(os.getpid()))
    time.sleep(seconds)
    return os.getpid()


def die(code: int) -> None:
    """End this worker at once, as the kernel does to one that runs out of memory."""
    os.kill(os.getpid(), signal.SIGKILL)
