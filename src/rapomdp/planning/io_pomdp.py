"""Cassandra's ``.pomdp`` format: a complete reader and a writer for any flat POMDP.

The grammar (Cassandra, "POMDP file format"): a preamble of ``discount``, ``values``,
``states``, ``actions``, ``observations`` (count or names) and ``start`` (a distribution, a
state, ``uniform``, or ``start include`` / ``start exclude`` lists), then ``T:``, ``O:`` and
``R:`` specifications in their one-entry, row and matrix forms, with ``*`` wildcards and the
``uniform`` / ``identity`` keywords. Later specifications overwrite earlier ones. Every syntax
error is a :class:`PomdpParseError` naming the file and line.
"""

from __future__ import annotations

import math
import os
import re
import stat
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.io import write_text_atomic
from rapomdp.planning.memory import (
    DEFAULT_MEMORY_GB,
    ENTRY_BYTES,
    MemoryCapError,
    cap_bytes,
    check_memory,
    format_bytes,
)
from rapomdp.planning.pomdp import POMDP

#: How far a row of T or O may sum from 1 in a file (rows are renormalised).
SUM_TOL = 1e-3
#: The largest magnitude of a reward in a file: the bounds sum rewards over 1 / (1 - discount)
#: steps, and beyond this they lose every digit of a gap (1e308 made them inf - inf = NaN).
MAX_ABS_REWARD = 1e12
#: Memory the reader takes per byte of a file's text (tokens; measured at about 40 B).
READ_BYTES_PER_BYTE = 48
#: A number as the format writes one (no ``1_000``, ``inf``, ``nan`` or other Python forms).
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")


class PomdpParseError(ValueError):
    """A malformed ``.pomdp`` file; ``line`` is 1-based (0 when no single line is at fault)."""

    def __init__(self, message: str, line: int = 0, source: str = "<string>") -> None:
        self.message = message
        self.line = line
        self.source = source
        where = f"{source}:{line}" if line else source
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class _Tok:
    text: str
    line: int


#: bytes needed for (states, actions, observations)
SizeEstimate = Callable[[int, int, int], int]

_TOKEN_RE = re.compile(r":|[^\s:]+")
_PREAMBLE = ("discount", "values", "states", "actions", "observations", "start")


def _tokenize(text: str) -> list[_Tok]:
    tokens: list[_Tok] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0]
        tokens.extend(_Tok(m.group(0), lineno) for m in _TOKEN_RE.finditer(line))
    return tokens


class _Parser:
    def __init__(self, text: str, source: str, memory_gb: float = DEFAULT_MEMORY_GB,
                 solver_bytes: SizeEstimate | None = None) -> None:
        self.toks = _tokenize(text)
        self.i = 0
        self.source = source
        self.memory_gb = memory_gb
        self.solver_bytes = solver_bytes
        self.discount: float | None = None
        self.discount_line = 0
        self.values = "reward"
        self.names: dict[str, list[str] | None] = {}
        self.index: dict[str, dict[str, int]] = {}  # name -> index, per kind
        self.sizes: dict[str, int] = {}
        self.start: np.ndarray | None = None
        self.start_spec: tuple[str, list[_Tok], int] | None = None

    # -- token helpers -------------------------------------------------------------------
    def error(self, message: str, tok: _Tok | None = None) -> PomdpParseError:
        if tok is None:
            tok = self.toks[self.i] if self.i < len(self.toks) else None
        line = tok.line if tok else (self.toks[-1].line if self.toks else 0)
        return PomdpParseError(message, line, self.source)

    def peek(self, k: int = 0) -> _Tok | None:
        j = self.i + k
        return self.toks[j] if j < len(self.toks) else None

    def peek_text(self, k: int = 0) -> str | None:
        tok = self.peek(k)
        return None if tok is None else tok.text

    def next(self, what: str) -> _Tok:
        tok = self.peek()
        if tok is None:
            raise self.error(f"unexpected end of file, expected {what}")
        self.i += 1
        return tok

    def expect_colon(self) -> None:
        tok = self.next("':'")
        if tok.text != ":":
            raise self.error(f"expected ':' but found {tok.text!r}", tok)

    def number(self, what: str = "a number") -> float:
        tok = self.next(what)
        if not _NUMBER.fullmatch(tok.text):
            raise self.error(f"expected {what} but found {tok.text[:40]!r}", tok)
        value = float(tok.text)
        if not math.isfinite(value):
            raise self.error(f"{what} must be finite, found {tok.text!r}", tok)
        return value

    def numbers(self, count: int, what: str) -> np.ndarray:
        return np.array([self.number(what) for _ in range(count)], dtype=np.float64)

    def at_keyword(self) -> bool:
        tok = self.peek()
        return tok is not None and tok.text in ("T", "O", "R", *_PREAMBLE)

    # -- preamble ------------------------------------------------------------------------
    def parse_preamble(self) -> None:
        seen: set[str] = set()
        while True:
            tok = self.peek()
            if tok is None or tok.text not in _PREAMBLE:
                break
            key = tok.text
            if key == "start" and self.peek_text(1) in ("include", "exclude"):
                self.i += 2
                self.expect_colon()
                key = f"start {self.toks[self.i - 2].text}"
                self.start_spec = (key, self.collect_until_keyword(), tok.line)
                if "start" in seen:
                    raise self.error("more than one start specification", tok)
                seen.add("start")
                continue
            self.i += 1
            self.expect_colon()
            if key in seen:
                raise self.error(f"'{key}' is given twice", tok)
            seen.add(key)
            if key == "discount":
                d = self.number("a discount factor")
                if not 0.0 <= d <= 1.0:
                    raise self.error(f"discount must be in [0, 1], got {d}", tok)
                self.discount = d
                self.discount_line = tok.line
            elif key == "values":
                v = self.next("'reward' or 'cost'")
                if v.text not in ("reward", "cost"):
                    raise self.error(f"values must be 'reward' or 'cost', not {v.text!r}", v)
                self.values = v.text
            elif key in ("states", "actions", "observations"):
                self.parse_set(key, tok)
            else:
                self.start_spec = ("start", self.collect_until_keyword(), tok.line)
        for key in ("discount", "states", "actions", "observations"):
            if key not in seen:
                raise self.error(f"the preamble lacks '{key}:'")

    def parse_set(self, key: str, keytok: _Tok) -> None:
        items = self.collect_until_keyword()
        if not items:
            raise self.error(f"'{key}:' needs a count or a list of names", keytok)
        if len(items) == 1 and re.fullmatch(r"[0-9]+", items[0].text):
            n = int(items[0].text)
            if n < 1:
                raise self.error(f"'{key}:' count must be positive", items[0])
            self.sizes[key] = n
            self.names[key] = None
        else:
            names = [t.text for t in items]
            index = {name: i for i, name in enumerate(names)}  # linear: one pass
            if len(index) < len(names):
                dup = sorted(name for name, count in Counter(names).items() if count > 1)
                shown = ", ".join(dup[:5]) + (f" and {len(dup) - 5} more" if len(dup) > 5 else "")
                raise self.error(f"duplicate {key} name(s): {shown}", items[0])
            numeric = next((t for t in items if re.match(r"[0-9+\-.]", t.text)), None)
            if numeric is not None:  # a name starts with a letter; a count is digits only
                raise self.error(f"{numeric.text[:40]!r} is neither a count (digits only) nor "
                                 f"a name (starts with a letter) in '{key}:'", numeric)
            bad = [n for n in ("*", "T", "O", "R") if n in index]
            if bad:
                raise self.error(f"{bad[0]!r} cannot be a name in '{key}:'", items[0])
            self.sizes[key] = len(names)
            self.names[key] = names
            self.index[key] = index

    def collect_until_keyword(self) -> list[_Tok]:
        out: list[_Tok] = []
        while (
            self.peek_text() not in (None, ":")
            and not self.at_keyword()
            and self.peek_text(1) != ":"
        ):
            out.append(self.next("a value"))
        return out

    # -- references ----------------------------------------------------------------------
    def ref(self, kind: str, tok: _Tok) -> slice | int:
        """Index (or ``slice(None)`` for '*') of a state/action/observation reference."""
        if tok.text == "*":
            return slice(None)
        index = self.index.get(kind)
        if index is not None and tok.text in index:
            return index[tok.text]
        if re.fullmatch(r"[0-9]+", tok.text):
            idx = int(tok.text)
            if idx < self.sizes[kind]:
                return idx
            raise self.error(
                f"{kind[:-1]} index {idx} is out of range (there are {self.sizes[kind]})", tok
            )
        raise self.error(f"unknown {kind[:-1]} {tok.text!r}", tok)

    def build_start(self, n_s: int) -> np.ndarray:
        if self.start_spec is None:
            return np.full(n_s, 1.0 / n_s)
        key, items, line = self.start_spec
        if key == "start":
            if len(items) == 1 and items[0].text == "uniform":
                return np.full(n_s, 1.0 / n_s)
            if n_s == 1 and len(items) == 1:
                if not _is_float(items[0].text):
                    self.ref("states", items[0])
                return np.ones(1)
            if len(items) == n_s:
                if not all(_is_float(t.text) for t in items):
                    raise PomdpParseError(
                        "start distribution must be numbers", line, self.source
                    )
                b = np.array([float(t.text) for t in items])
                if not np.all(np.isfinite(b)) or np.any(b < 0):
                    raise PomdpParseError(
                        "start distribution has a negative or non-finite entry", line, self.source
                    )
                if abs(b.sum() - 1.0) > SUM_TOL:
                    raise PomdpParseError(
                        f"start distribution sums to {b.sum():.6g}, not 1", line, self.source
                    )
                return b / b.sum()
            if len(items) == 1:
                b = np.zeros(n_s)
                b[self.ref("states", items[0])] = 1.0
                return b
            raise PomdpParseError(
                f"start needs {n_s} probabilities, 'uniform' or one state; got {len(items)} values",
                line,
                self.source,
            )
        if not items:
            raise PomdpParseError(f"'{key}:' needs at least one state", line, self.source)
        mask = np.zeros(n_s, dtype=bool)
        for t in items:
            mask[self.ref("states", t)] = True
        if key == "start exclude":
            mask = ~mask
        if not mask.any():
            raise PomdpParseError(f"'{key}:' leaves no start state", line, self.source)
        return mask / mask.sum()

    # -- parameters ----------------------------------------------------------------------
    def parse(self) -> POMDP:
        self.parse_preamble()
        n_s, n_a, n_z = self.sizes["states"], self.sizes["actions"], self.sizes["observations"]
        # T, O and their row-sum copies, the line tables, R and the POMDP's checks
        need = ENTRY_BYTES * (2 * n_a * n_s * n_s + 2 * n_a * n_s * n_z + 6 * n_a * n_s)
        sizes = f"{n_s} states x {n_a} actions x {n_z} observations"
        if self.solver_bytes is not None:  # refuse before reading what cannot be solved
            check_memory(f"solving {self.source} ({sizes})", self.solver_bytes(n_s, n_a, n_z),
                         self.memory_gb)
        check_memory(f"reading {self.source} ({sizes}, dense)", need, self.memory_gb)
        T = np.zeros((n_a, n_s, n_s))
        Z = np.zeros((n_a, n_s, n_z))
        T_line = np.zeros((n_a, n_s), dtype=np.int64)
        O_line = np.zeros((n_a, n_s), dtype=np.int64)
        R2 = np.zeros((n_a, n_s))
        R4: np.ndarray | None = None
        while self.peek() is not None:
            tok = self.next("T:, O: or R:")
            if tok.text in _PREAMBLE:
                raise self.error(f"'{tok.text}:' must come before the T/O/R specifications", tok)
            if tok.text not in ("T", "O", "R"):
                raise self.error(f"expected 'T:', 'O:' or 'R:' but found {tok.text!r}", tok)
            self.expect_colon()
            if tok.text == "T":
                self.parse_prob("T", T, T_line, "states", n_s, tok)
            elif tok.text == "O":
                self.parse_prob("O", Z, O_line, "observations", n_z, tok)
            else:
                R4 = self.parse_reward(R2, R4, tok)
        self.check_rows("T", T, T_line)
        self.check_rows("O", Z, O_line)
        T /= T.sum(axis=2, keepdims=True)
        Z /= Z.sum(axis=2, keepdims=True)
        if R4 is not None:
            R = np.einsum("ast,atz,astz->as", T, Z, R4)
        else:
            R = R2
        if self.values == "cost":
            R = -R
        b0 = self.build_start(n_s)
        discount = float(self.discount if self.discount is not None else 0.95)
        if discount >= 1.0:
            raise PomdpParseError(
                "discount 1 is not supported (the solver needs discount < 1)",
                self.discount_line, self.source,
            )
        return POMDP.from_arrays(
            T,
            Z,
            R,
            discount,
            b0,
            state_names=self.names["states"] or [],
            action_names=self.names["actions"] or [],
            observation_names=self.names["observations"] or [],
        )

    def parse_prob(
        self, name: str, arr: np.ndarray, lines: np.ndarray, second: str, n_last: int, key: _Tok
    ) -> None:
        """``T: a [: s [: s' p]]`` or ``O: a [: s' [: o p]]`` with rows/matrices/keywords."""
        a = self.ref("actions", self.next("an action"))
        n_s = arr.shape[1]
        if self.peek_text() == ":":
            self.i += 1
            s = self.ref("states", self.next("a state"))
            if self.peek_text() == ":":
                self.i += 1
                target = self.ref(second, self.next(f"a {second[:-1]}"))
                value = self.number("a probability")
                if not 0.0 <= value <= 1.0:
                    raise self.error(f"probability {value} is outside [0, 1]", key)
                arr[a, s, target] = value
            else:
                tok = self.peek()
                if tok is not None and tok.text == "uniform":
                    self.i += 1
                    row = np.full(n_last, 1.0 / n_last)
                else:
                    row = self.numbers(n_last, "a probability")
                    self.check_probs(row, key)
                arr[a, s, :] = row
            lines[a, s] = key.line
            return
        tok = self.peek()
        if tok is not None and tok.text == "uniform":
            self.i += 1
            arr[a] = 1.0 / n_last
        elif tok is not None and tok.text == "identity":
            if name != "T":
                raise self.error("'identity' is only defined for T", tok)
            self.i += 1
            arr[a] = np.eye(n_s)
        else:
            matrix = self.numbers(n_s * n_last, "a probability").reshape(n_s, n_last)
            self.check_probs(matrix, key)
            arr[a] = matrix
        lines[a] = key.line

    def check_probs(self, values: np.ndarray, key: _Tok) -> None:
        if np.any(values < 0) or np.any(values > 1):
            raise self.error("probabilities must lie in [0, 1]", key)

    def check_rows(self, name: str, arr: np.ndarray, lines: np.ndarray) -> None:
        sums = arr.sum(axis=2)
        bad = np.argwhere(np.abs(sums - 1.0) > SUM_TOL)
        if bad.size:
            a, s = (int(v) for v in bad[0])
            an = self.names["actions"][a] if self.names["actions"] else str(a)
            sn = self.names["states"][s] if self.names["states"] else str(s)
            what = "end state" if name == "O" else "start state"
            msg = (
                f"{name} probabilities for action {an!r}, {what} {sn!r} sum to "
                f"{sums[a, s]:.6g}, not 1"
            )
            if lines[a, s] == 0:
                msg += " (never specified)"
            raise PomdpParseError(msg, int(lines[a, s]), self.source)

    def parse_reward(self, R2: np.ndarray, R4: np.ndarray | None, key: _Tok) -> np.ndarray | None:
        """``R: a : s [: s' [: o v]]`` and the row/matrix forms; expands to (A,S,S,Z) only
        when a reward depends on the next state or the observation."""
        n_a, n_s = R2.shape
        n_z = self.sizes["observations"]
        a = self.ref("actions", self.next("an action"))
        self.expect_colon()
        s = self.ref("states", self.next("a state"))
        s2: slice | int = slice(None)
        o: slice | int = slice(None)
        if self.peek_text() == ":":
            self.i += 1
            s2 = self.ref("states", self.next("an end state"))
            if self.peek_text() == ":":
                self.i += 1
                o = self.ref("observations", self.next("an observation"))
                value: np.ndarray | float = self.number("a reward")
            else:
                value = self.numbers(n_z, "a reward")
        else:
            value = self.numbers(n_s * n_z, "a reward").reshape(n_s, n_z)
        flat = np.ravel(value)
        if np.any(np.abs(flat) > MAX_ABS_REWARD):
            worst = float(flat[np.argmax(np.abs(flat))])
            raise self.error(f"reward {worst:g} is outside [-{MAX_ABS_REWARD:g}, "
                             f"{MAX_ABS_REWARD:g}] (the value bounds would overflow)", key)
        simple = isinstance(s2, slice) and isinstance(o, slice) and bool(np.all(flat == flat[0]))
        if R4 is None and simple:
            R2[a, s] = float(np.ravel(value)[0])
            return None
        if R4 is None:
            try:
                check_memory(f"rewards that depend on the end state or observation in "
                             f"{self.source} (a dense A x S x S x Z table)",
                             2 * ENTRY_BYTES * n_a * n_s * n_s * n_z, self.memory_gb)
            except MemoryCapError as exc:
                raise self.error(str(exc), key) from None
            R4 = np.broadcast_to(R2[:, :, None, None], (n_a, n_s, n_s, n_z)).copy()
        R4[a, s, s2, o] = value
        return R4


def _is_float(text: str) -> bool:
    return _NUMBER.fullmatch(text) is not None


def parse_pomdp(text: str, source: str = "<string>", memory_gb: float = DEFAULT_MEMORY_GB,
                solver_bytes: SizeEstimate | None = None) -> POMDP:
    """Parse the text of a ``.pomdp`` file (Cassandra's format, as the reference SARSOP reads
    it); time and memory are linear in the text's size.

    Args:
        text: The file's text.
        source: The file's name in error messages.
        memory_gb: The memory cap in GB.
        solver_bytes: ``(states, actions, observations) -> bytes`` the caller will also need
            to solve it (counted against the cap too).

    Returns:
        The POMDP: T (A, S, S), Z (A, S, O), R (A, S) (rewards R(s, a, s', o) folded in),
        discount, initial belief and names.

    Raises:
        PomdpParseError: A syntax or model error, with its line.
        MemoryCapError: The arrays would exceed ``memory_gb`` (before any is allocated).

    Example:
        >>> listen = parse_pomdp("discount: 0.95\\nvalues: reward\\nstates: left right\\n"
        ...                      "actions: listen\\nobservations: hear-left hear-right\\n"
        ...                      "T: listen\\nidentity\\nO: listen\\n0.85 0.15\\n0.15 0.85\\n"
        ...                      "R: listen : * : * : * -1\\n")
        >>> listen.T.shape, listen.Z[0].tolist(), listen.R.tolist()
        ((1, 2, 2), [[0.85, 0.15], [0.15, 0.85]], [[-1.0, -1.0]])
        >>> parse_pomdp("discount: 0.9\\nstates: 2\\nactions: 1\\nobservations: 1\\n"
        ...             "T: 7 : 0 : 0 1\\n")
        Traceback (most recent call last):
        ...
        rapomdp.planning.io_pomdp.PomdpParseError: <string>:5: action index 7 is out of range ...
    """
    try:
        return _Parser(text, source, memory_gb, solver_bytes).parse()
    except PomdpParseError:
        raise
    except ValueError as exc:  # a model-level check (e.g. from POMDP.__post_init__)
        raise PomdpParseError(str(exc), 0, source) from None


def read_pomdp(path: str | os.PathLike[str], memory_gb: float = DEFAULT_MEMORY_GB,
               solver_bytes: SizeEstimate | None = None) -> POMDP:
    """Read a ``.pomdp`` file; a missing or undecodable file is a :class:`PomdpParseError`;
    see :func:`parse_pomdp`. The file is sized before it is read (a device or pipe is read no
    further than the memory cap allows): :class:`~rapomdp.planning.memory.MemoryCapError`.

    Args:
        path: The ``.pomdp`` file; ``memory_gb`` and ``solver_bytes`` as :func:`parse_pomdp`'s.

    Returns:
        The POMDP. Example: ``read_pomdp("tests/planning/data/Hallway.pomdp").n_states`` is 60.
    """
    path = Path(path)
    limit = int(cap_bytes(memory_gb) // READ_BYTES_PER_BYTE)
    try:
        with path.open("rb") as handle:
            info = os.fstat(handle.fileno())
            if stat.S_ISREG(info.st_mode):
                check_memory(f"reading {path} ({format_bytes(info.st_size)} of text)",
                             READ_BYTES_PER_BYTE * info.st_size, memory_gb)
                raw = handle.read()
            else:
                raw = handle.read(limit + 1)
                if len(raw) > limit:
                    raise PomdpParseError(
                        f"not a regular file, and longer than the {format_bytes(limit)} of "
                        f"text a memory cap of {memory_gb:g} GB lets the reader take", 0,
                        str(path))
        text = raw.decode("utf-8", errors="strict")
    except OSError as exc:
        raise PomdpParseError(f"cannot read file ({exc.strerror or exc})", 0, str(path)) from None
    except UnicodeDecodeError as exc:
        raise PomdpParseError(f"not UTF-8 text (byte {exc.start})", 0, str(path)) from None
    return parse_pomdp(text, str(path), memory_gb, solver_bytes)


def _fmt(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _matrix_lines(key: str, action: str, matrix: np.ndarray) -> list[str]:
    """One action's T or O as rows, or as ``key: a : i : j p`` entries when those are
    fewer numbers (unlisted entries are 0 in the format): an exported active-recognition
    problem has one non-zero per row of T, so its file stays linear in the states."""
    rows, cols = np.nonzero(matrix)
    if 4 * rows.size < matrix.size:
        return [f"{key}: {action} : {i} : {j} {float(matrix[i, j])!r}"
                for i, j in zip(rows.tolist(), cols.tolist(), strict=True)]
    return [f"{key}: {action}", *(_fmt(row) for row in matrix)]


def format_pomdp(pomdp: POMDP) -> str:
    """The ``.pomdp`` text of a flat POMDP (names kept when they are valid identifiers).

    T and O are written per action as rows or, when sparse, as single entries; an O that is
    the same for every action is written once with ``*``.

    The text :func:`parse_pomdp` reads back to the same arrays.

    Example:
        >>> import numpy as np
        >>> from rapomdp.planning import POMDP
        >>> pomdp = POMDP.from_arrays(np.array([np.eye(2)]), np.array([[[0.8, 0.2], [0.3, 0.7]]]),
        ...                           np.array([[1.0, 0.0]]), 0.9, np.array([0.5, 0.5]))
        >>> again = parse_pomdp(format_pomdp(pomdp))
        >>> bool(np.array_equal(again.Z, pomdp.Z) and np.array_equal(again.R, pomdp.R))
        True
    """

    def names(items: list[str], n: int) -> str:
        ok = all(re.fullmatch(r"[A-Za-z][\w\-.]*", x) for x in items) and len(items) == n
        return " ".join(items) if ok else str(n)

    lines = [
        "# written by rapomdp",
        f"discount: {pomdp.discount!r}",
        "values: reward",
        f"states: {names(pomdp.state_names, pomdp.n_states)}",
        f"actions: {names(pomdp.action_names, pomdp.n_actions)}",
        f"observations: {names(pomdp.observation_names, pomdp.n_observations)}",
        f"start: {_fmt(pomdp.initial_belief)}",
        "",
    ]
    for a in range(pomdp.n_actions):
        lines.extend(_matrix_lines("T", str(a), pomdp.T[a]))
    if pomdp.n_actions > 1 and bool(np.all(pomdp.Z == pomdp.Z[0])):
        lines.extend(_matrix_lines("O", "*", pomdp.Z[0]))
    else:
        for a in range(pomdp.n_actions):
            lines.extend(_matrix_lines("O", str(a), pomdp.Z[a]))
    for a in range(pomdp.n_actions):
        for s in np.flatnonzero(pomdp.R[a]):
            lines.append(f"R: {a} : {s} : * : * {float(pomdp.R[a, s])!r}")
    return "\n".join(lines) + "\n"


def write_pomdp(pomdp: POMDP, path: str | os.PathLike[str]) -> Path:
    """Write ``pomdp`` as a ``.pomdp`` file at ``path`` (replaced whole, atomically:
    :func:`format_pomdp`'s text); returns ``path``."""
    return write_text_atomic(Path(path), format_pomdp(pomdp))
