"""What a stage is to a workspace: its inputs, its cache key, and the records of a run."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, overload

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.io import ArtefactError, read_json, stable_hash
from rapomdp.workspace.layout import STAGE_RECORD, StageError


class _Upstream:
    """A :class:`StageInputs` attribute named after an earlier stage: that stage's folder, or a
    :class:`StageError` naming the stage when it was not given (a required input)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.stage = name

    @overload
    def __get__(self, inputs: None, owner: type | None = None) -> _Upstream: ...

    @overload
    def __get__(self, inputs: StageInputs, owner: type | None = None) -> Path: ...

    def __get__(self, inputs: StageInputs | None, owner: type | None = None
                ) -> _Upstream | Path:
        if inputs is None:
            return self
        folder: Path | None = getattr(inputs, f"{self.stage}_dir")
        if folder is None:
            reader = f"stage '{inputs.stage}'" if inputs.stage else "this stage"
            raise StageError(
                f"{reader} needs the folder of stage '{self.stage}', which it was not given: "
                f"run `rapomdp {self.stage} -w WORKSPACE` first, or pass "
                f"StageInputs({self.stage}_dir=...)")
        return folder


@dataclass(frozen=True, repr=False)
class StageInputs:
    """The folders of the earlier stages a stage reads: one typed attribute per stage.

    ``inputs.train`` is the train stage's folder, or a :class:`StageError` naming the train
    stage when it was not given; ``inputs.train_dir`` is that folder or None, for an input the
    stage can do without. ``stage`` names the reading stage in those errors. The pipeline
    builds one per stage from the stage graph (:meth:`Workspace.inputs`); a library caller
    names the folders it has: ``StageInputs("solve", observe_dir=..., robot_dir=...)``.

    Example:
        >>> from rapomdp.workspace import StageInputs
        >>> inputs = StageInputs.of("solve", {"observe": "W/observe", "robot": "W/robot"})
        >>> inputs
        StageInputs('solve', robot_dir='W/robot', observe_dir='W/observe')
        >>> inputs.observe.name
        'observe'
        >>> inputs.train  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        rapomdp.workspace.layout.StageError: stage 'solve' needs the folder of stage 'train', ...
    """

    stage: str = ""
    dataset_dir: Path | None = None
    render_dir: Path | None = None
    train_dir: Path | None = None
    xrho_dir: Path | None = None
    classifier_eval_dir: Path | None = None
    saliency_dir: Path | None = None
    volume_dir: Path | None = None
    robot_dir: Path | None = None
    observe_dir: Path | None = None
    vptree_dir: Path | None = None
    solve_dir: Path | None = None
    learn_dir: Path | None = None
    evaluate_dir: Path | None = None

    dataset = _Upstream()
    render = _Upstream()
    train = _Upstream()
    xrho = _Upstream()
    classifier_eval = _Upstream()
    saliency = _Upstream()
    volume = _Upstream()
    robot = _Upstream()
    observe = _Upstream()
    vptree = _Upstream()
    solve = _Upstream()
    learn = _Upstream()
    evaluate = _Upstream()

    def __post_init__(self) -> None:
        for name, folder in self._folders():  # a str from a library caller becomes a Path
            if folder is not None and not isinstance(folder, Path):
                object.__setattr__(self, f"{name}_dir", Path(folder))

    def _folders(self) -> Iterator[tuple[str, Path | None]]:
        for item in fields(self):
            if item.name.endswith("_dir"):
                yield item.name.removesuffix("_dir"), getattr(self, item.name)

    @classmethod
    def of(cls, stage: str, folders: Mapping[str, str | Path]) -> StageInputs:
        """The inputs of ``stage`` from ``{upstream stage: folder}`` (the stage graph's names);
        a name that is no pipeline stage raises a :class:`StageError`."""
        known = [name for name, _ in cls()._folders()]
        unknown = [name for name in folders if name not in known]
        if unknown:
            raise StageError(f"stage '{stage}' reads {', '.join(map(repr, unknown))}, which "
                             f"StageInputs has no folder for (it has {', '.join(known)})")
        given: dict[str, Any] = {f"{name}_dir": Path(folder) for name, folder in folders.items()}
        return cls(stage, **given)

    def given(self) -> dict[str, Path]:
        """``{stage: folder}`` for every folder given, in pipeline order."""
        return {name: folder for name, folder in self._folders() if folder is not None}

    def __repr__(self) -> str:  # the folders given only
        given = "".join(f", {name}_dir={str(folder)!r}" for name, folder in self.given().items())
        return f"StageInputs({self.stage!r}{given})"


@dataclass(frozen=True)
class Stage:
    """One pipeline stage: reads ``inputs`` (earlier stages) and writes its own folder.

    Attributes:
        name: The stage's name, its folder's name in the workspace.
        run: ``run(config, inputs, out, context)`` writes the stage's artefacts into ``out``.
        sections: The configuration sections it reads (they enter its key).
        inputs: The names of the earlier stages it reads (their keys enter its key).
        version: Its code's version: a new one makes every recorded run of it stale.
        fingerprint: What it reads from outside the workspace, as a string (a user's mesh
            folder's file sizes and times), or None.
        description: One line for ``rapomdp status`` and the docs.
    """

    name: str
    run: Callable[[Config, StageInputs, Path, RunContext], None]
    sections: Sequence[str] = ()
    inputs: Sequence[str] = ()
    version: str = "1"
    fingerprint: Callable[[Config], str] | None = None
    description: str = ""


def stage_key(stage: Stage, config: Config, upstream: Mapping[str, str],
              external: str | None) -> str:
    """The cache key of ``stage``: its name and version, the configuration sections it reads,
    its inputs' keys (``upstream``) and its external fingerprint.

    Args:
        stage: The stage.
        config: The configuration (only ``stage.sections`` are read).
        upstream: ``{input stage: its recorded key}``.
        external: The stage's fingerprint of its outside inputs, or None.

    Returns:
        A hex SHA-256 of the canonical JSON of those parts (64 characters).
    """
    return stable_hash(
        {
            "stage": stage.name,
            "version": stage.version,
            "config": {s: config.section(s) for s in stage.sections},
            "inputs": dict(upstream),
            "external": external,
        }
    )


@dataclass
class StageResult:
    """What running a stage did: ``cached`` (nothing to do), or done in ``seconds``;
    ``shared_from``: the workspace whose identical artefacts it took instead of running."""

    name: str
    key: str
    cached: bool
    seconds: float
    files: list[str] = field(default_factory=list)
    shared_from: str | None = None


@dataclass(frozen=True)
class StageStatus:
    """What a workspace holds of one stage (``rapomdp status``): ``state`` is ``current``,
    ``stale`` (``reasons`` say why) or ``not run``; the rest is the stage's manifest record
    (``seconds``: its run's wall time; ``finished``: when, as recorded)."""

    name: str
    state: str
    reasons: list[str] = field(default_factory=list)
    files: int | None = None
    key: str | None = None
    seconds: float | None = None
    finished: str | None = None
    shared_from: str | None = None



def _flatten(value: Any, prefix: str) -> dict[str, Any]:
    if isinstance(value, dict):
        flat: dict[str, Any] = {}
        for key, item in value.items():
            flat.update(_flatten(item, f"{prefix}.{key}"))
        return flat
    return {prefix: value}


def describe_change(section: str, old: Any, new: Any, limit: int = 3) -> str:
    """``train.epochs 25 -> 5, ...``: the keys of a section that differ, values bounded."""
    before, after = _flatten(old, section), _flatten(new, section)
    keys = [k for k in sorted(before.keys() | after.keys()) if before.get(k) != after.get(k)]

    def shown(value: Any) -> str:
        return json.dumps(value, default=str)[:40]

    parts = [f"{k} {shown(before.get(k))} -> {shown(after.get(k))}" for k in keys[:limit]]
    more = f", +{len(keys) - limit} more" if len(keys) > limit else ""
    return (", ".join(parts) + more) if parts else f"{section} changed"


def read_stage_record(path: Path) -> dict[str, Any]:
    try:
        return read_json(path / STAGE_RECORD)
    except ArtefactError as exc:
        raise StageError(str(exc)) from exc
