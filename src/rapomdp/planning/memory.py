"""Memory caps for the solvers: structures are sized before they are allocated.

Every solver and reader estimates the bytes its arrays will take from the problem's sizes and
compares them with a cap (``memory_gb``, default :data:`DEFAULT_MEMORY_GB`); a problem that
cannot fit is refused with :class:`MemoryCapError` before anything large is allocated, and an
optional structure that does not fit (the grid upper bound, say) is left out with a note.
The cap is in decimal gigabytes (10⁹ bytes), the unit ``ru_maxrss`` figures are quoted in.
"""

from __future__ import annotations

import math

#: The memory cap when none is given: 4 GB.
DEFAULT_MEMORY_GB = 4.0
#: Bytes of one float64 / int64 entry.
ENTRY_BYTES = 8


class MemoryCapError(MemoryError):
    """A problem whose arrays, estimated before allocation, would exceed the memory cap."""

    def __init__(self, what: str, needed_bytes: float, cap_bytes: float) -> None:
        self.what = what
        self.needed_bytes = needed_bytes
        self.cap_bytes = cap_bytes
        super().__init__(
            f"{what} needs about {format_bytes(needed_bytes)}, over the memory cap of "
            f"{format_bytes(cap_bytes)} (raise it with --memory-gb or solve.memory_gb, or "
            "make the problem smaller)"
        )

    def __reduce__(self) -> tuple[type, tuple[str, float, float]]:
        # rebuilt from its fields when it crosses a process boundary (a worker's error)
        return (type(self), (self.what, self.needed_bytes, self.cap_bytes))


def format_bytes(n: float) -> str:
    """``n`` bytes as a short decimal figure: 512 kB, 37 MB, 11.9 GB."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            value = n / size
            return f"{value:.3g} {unit}" if value < 100 else f"{value:.0f} {unit}"
    return f"{n:.0f} B"


def cap_bytes(memory_gb: float) -> float:
    """The cap in bytes; ValueError unless ``memory_gb`` is a positive finite number."""
    if not (isinstance(memory_gb, int | float) and math.isfinite(memory_gb) and memory_gb > 0):
        raise ValueError(f"memory_gb must be a positive finite number, got {memory_gb!r}")
    return float(memory_gb) * 1e9


def check_memory(what: str, needed_bytes: float, memory_gb: float) -> None:
    """Raise :class:`MemoryCapError` when ``needed_bytes`` exceeds the cap."""
    cap = cap_bytes(memory_gb)
    if needed_bytes > cap:
        raise MemoryCapError(what, needed_bytes, cap)
