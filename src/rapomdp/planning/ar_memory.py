"""The memory plan of the active-recognition solver: every structure sized against one cap.

The working blocks come first (:func:`fit_chunk` shrinks them until they take at most half of
the cap), then the grid upper bound (:func:`plan_grid`: the finest resolution that fits half
of what is left and the time budget's entry count), then the library of lower-bound vectors and
upper-bound points (:func:`plan_library`: half each of the rest). A problem whose smallest
blocks do not fit is refused with a :class:`~rapomdp.planning.memory.MemoryCapError`.
"""

from __future__ import annotations

from rapomdp.planning.grid_bound import grid_bytes, grid_entries
from rapomdp.planning.memory import ENTRY_BYTES, MemoryCapError, cap_bytes, format_bytes

#: Visited (belief, viewpoint) pairs kept for pruning the library.
KEEP_PAIRS = 20_000
#: Smallest working block (entries) the memory cap may shrink ``chunk`` to.
MIN_CHUNK = 65_536
#: Vectors and points the library can always hold (the memory check reserves them).
LIBRARY_MIN = 1_000
#: The grid resolutions tried, coarsest first, when the caller names none.
GRID_RESOLUTIONS = (2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64, 80, 96, 128)


def working_bytes(chunk: int, n_viewpoints: int, n_targets: int, n_classes: int) -> int:
    """Bytes of the solver's fixed arrays and working blocks, before any library.

    The problem's arrays (V·C² + 2·J·C² + 3·V·J + V²), one belief's children and their
    plans (10 arrays of J·C²), eight blocks of ``chunk`` entries, the visited pairs kept
    for pruning (3 copies of 20 000 × (C + 1)).

    Args:
        chunk: Entries of one working block.
        n_viewpoints: V, the viewpoints of the problem.
        n_targets: J, the move targets.
        n_classes: C, the hidden states a belief is over.

    Returns:
        The bytes, at :data:`~rapomdp.planning.memory.ENTRY_BYTES` per entry.

    Example:
        >>> working_bytes(65_536, n_viewpoints=10, n_targets=10, n_classes=3)
        6126864
    """
    v, j, c = n_viewpoints, n_targets, n_classes
    problem = v * c * c + 2 * j * c * c + 3 * v * j + v * v
    children = 10 * j * c * c
    visited = 3 * KEEP_PAIRS * (c + 1)
    return ENTRY_BYTES * (problem + children + 8 * chunk + visited)


def fit_chunk(chunk: int, n_v: int, n_j: int, n_c: int, cap: float) -> int:
    """``chunk`` or less so that the working arrays take at most half of the cap; refused
    (:class:`MemoryCapError`) when even the smallest blocks do not fit.

    Args:
        chunk: The working block the caller asked for (entries).
        n_v: Viewpoints V.
        n_j: Move targets J.
        n_c: Hidden states C.
        cap: The memory cap in bytes.

    Returns:
        The block size (entries), halved from ``chunk`` down to at least
        max(:data:`MIN_CHUNK`, J·C²).

    Raises:
        MemoryCapError: When the smallest blocks and :data:`LIBRARY_MIN` library entries
            exceed ``cap``.
    """
    smallest = max(MIN_CHUNK, n_j * n_c * n_c)
    fitted = int(chunk)
    while fitted > smallest and working_bytes(fitted, n_v, n_j, n_c) > cap / 2:
        fitted = max(smallest, fitted // 2)
    need = working_bytes(fitted, n_v, n_j, n_c) + LIBRARY_MIN * ENTRY_BYTES * (
        4 * n_c + n_v + n_j)
    if need > cap:
        raise MemoryCapError(
            f"the active-recognition problem ({n_v} viewpoints x {n_c} classes, {n_j} move "
            "targets)", need, cap)
    return fitted


def grid_resolutions(grid: bool | int) -> list[int]:
    """The grid resolutions to try: the one ``grid`` names (an int), else
    :data:`GRID_RESOLUTIONS`."""
    if isinstance(grid, int) and not isinstance(grid, bool):
        return [int(grid)]
    return list(GRID_RESOLUTIONS)


def plan_grid(shape: tuple[int, int, int, int], chunk: int, memory_gb: float,
              grid: bool | int, max_entries: int) -> tuple[int, str]:
    """The finest grid resolution whose structures fit in the memory left and in
    ``max_entries`` (0: no grid), and a note saying which bound was chosen and why.

    Args:
        shape: (V viewpoints, C hidden states, J move targets, O labels).
        chunk: The working block (entries) :func:`fit_chunk` chose.
        memory_gb: The cap in GB.
        grid: False (no grid), True (the finest that fits) or one resolution.
        max_entries: The most grid entries the time budget allows.

    Returns:
        ``(resolution, note)``: 0 and why when no grid is used.
    """
    n_v, n_c, n_j, n_o = shape
    if grid is False:
        return 0, "upper bound: sawtooth only (grid turned off)"
    cap = cap_bytes(memory_gb)
    left = cap - working_bytes(chunk, n_v, n_j, n_c)
    # the grid's share: at most half of what is left, the rest is the library's
    budget = left / 2
    extra = 6 * n_j * n_c * n_o * ENTRY_BYTES  # interpolating one belief's children
    best, refusal = 0, ""
    for res in grid_resolutions(grid):
        entries = grid_entries(res, n_c, n_j, n_o)
        if entries > max_entries:
            refusal = refusal or (f"resolution {res} has {entries:.3g} entries, over "
                                  f"the {max_entries:.3g} the time budget allows")
            break
        need = grid_bytes(res, n_c, n_v, n_j, n_o) + extra
        if need > budget:
            refusal = (f"resolution {res} needs {format_bytes(need)}, over the "
                       f"{format_bytes(budget)} the {format_bytes(cap)} cap leaves it")
            break
        best = res
    if best == 0:
        return 0, f"upper bound: sawtooth only, grid skipped ({refusal})"
    if refusal and "cap" in refusal:
        return best, f"upper bound: grid up to resolution {best} + sawtooth ({refusal})"
    return best, f"upper bound: grid up to resolution {best} + sawtooth"


def plan_library(shape: tuple[int, int, int, int], chunk: int, memory_gb: float,
                 resolution: int) -> tuple[int, int]:
    """Most lower-bound vectors and upper-bound points the memory left can hold.

    Args:
        shape: (V viewpoints, C hidden states, J move targets, O labels).
        chunk: The working block (entries).
        memory_gb: The cap in GB.
        resolution: The grid's resolution (0: none).

    Returns:
        ``(max_vectors, max_points)``, each at least :data:`LIBRARY_MIN`.
    """
    n_v, n_c, n_j, n_o = shape
    left = cap_bytes(memory_gb) - working_bytes(chunk, n_v, n_j, n_c)
    if resolution:
        left -= grid_bytes(resolution, n_c, n_v, n_j, n_o)
    left = max(left, 0.0)
    per_vector = ENTRY_BYTES * (2 * n_c + 2 + n_v)  # β, slot, copies in pruning, scores
    per_point = ENTRY_BYTES * (4 * n_c + n_v + n_j)  # b, 1/b, offset, values, a copy
    return (max(LIBRARY_MIN, int(left / 2 / per_vector)),
            max(LIBRARY_MIN, int(left / 2 / per_point)))
