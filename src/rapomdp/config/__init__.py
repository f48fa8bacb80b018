"""The validated configuration: one YAML file, a default for every value, unknown keys refused.

The sections are in :mod:`rapomdp.config.sections`, the file handling in
:mod:`rapomdp.config.files`; this module validates a mapping into a :class:`Config` and names
every wrong key or value, and a retired option with its decision page (:mod:`rapomdp.retired`).

Example:
    >>> config = config_from_dict({"train": {"epochs": 5}}, "my settings")
    >>> config.train.epochs, config.seed
    (5, 0)
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from rapomdp.config.files import (
    MAX_ALIASES,
    MAX_CONFIG_BYTES,
    MAX_EXPANDED_NODES,
    UNIT_SUFFIXES,
    ConfigError,
    apply_overrides,
    parse_yaml,
    read_config_data,
)
from rapomdp.config.sections import (
    METHOD_NAMES,
    SCHEDULER_PATTERN,
    AugmentConfig,
    CameraConfig,
    Config,
    DatasetConfig,
    EnergyConfig,
    EvaluateConfig,
    LearnConfig,
    LimitsConfig,
    NoiseConfig,
    ObserveConfig,
    ParallelConfig,
    PreprocessConfig,
    RandomWalkConfig,
    RenderConfig,
    RobotConfig,
    SaliencyConfig,
    SolveConfig,
    SplitConfig,
    TrainConfig,
    Vector3,
    ViewpointsConfig,
    VolumeConfig,
    VPTreeConfig,
)
from rapomdp.retired import RetiredOptionError, drop_retired

__all__ = [
    "MAX_ALIASES", "MAX_CONFIG_BYTES", "MAX_EXPANDED_NODES", "METHOD_NAMES", "SCHEDULER_PATTERN",
    "UNIT_SUFFIXES", "AugmentConfig", "CameraConfig", "Config", "ConfigError", "DatasetConfig",
    "EnergyConfig", "EvaluateConfig", "LearnConfig", "LimitsConfig", "NoiseConfig",
    "ObserveConfig", "ParallelConfig", "PreprocessConfig", "RandomWalkConfig", "RenderConfig",
    "RobotConfig", "SaliencyConfig", "SolveConfig", "SplitConfig", "TrainConfig", "Vector3",
    "ViewpointsConfig", "VolumeConfig", "VPTreeConfig", "apply_overrides", "config_from_dict",
    "load_config", "parse_yaml", "read_config_data",
]


def _shown(value: Any) -> str:
    """A bounded description of a wrong value for an error message (never a full repr)."""
    if isinstance(value, dict | list | tuple | set):
        return f" (got a {type(value).__name__} of {len(value)} items)"
    if isinstance(value, str | bytes):
        text = repr(value[:60]) + ("..." if len(value) > 60 else "")
    else:
        text = repr(value) if isinstance(value, int | float | bool | None) else type(value).__name__
    return f" (got {text[:80]})"


def _section_of(annotation: Any) -> type[BaseModel] | None:
    """The section class a field's annotation holds (through Optional, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _section_of(arg)
        if found is not None:
            return found
    return None


def _near_key(loc: Sequence[Any]) -> str | None:
    """The known key of the same section closest to an unknown one (``epohcs``: ``epochs``)."""
    section: type[BaseModel] | None = Config
    for part in [p for p in loc if not str(p).startswith("<")][:-1]:
        field = section.model_fields.get(str(part)) if section is not None else None
        section = _section_of(field.annotation) if field is not None else None
    if section is None or not loc:
        return None
    close = difflib.get_close_matches(str(loc[-1]), list(section.model_fields), n=1, cutoff=0.6)
    return close[0] if close else None


def _describe(error: dict[str, Any]) -> str:
    parts = [str(part) for part in error["loc"] if not str(part).startswith("<")]
    where = ".".join(parts) or "(top level)"
    if error["type"] == "extra_forbidden":
        near = _near_key(error["loc"])
        hint = f" (did you mean {'.'.join([*parts[:-1], near])}?)" if near else ""
        return f"{where}: unknown key{hint}"
    shown = _shown(error["input"]) if "input" in error else ""
    message = error["msg"].removeprefix("Value error, ")
    return f"{where}: {message[:300]}{shown}"


def config_from_dict(data: dict[str, Any], source: str = "configuration") -> Config:
    """Validate a mapping; errors name every wrong key or value."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of sections, got {type(data).__name__}")
    try:
        data = drop_retired(data, source)
    except RetiredOptionError as exc:
        raise ConfigError(str(exc)) from None
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        lines = "\n".join(f"  {_describe(e)}" for e in exc.errors()[:20])
        raise ConfigError(f"{source}: invalid configuration\n{lines}") from None


def load_config(path: str | Path | None) -> Config:
    """Read a YAML configuration; ``None`` gives the default."""
    if path is None:
        return Config()
    return config_from_dict(read_config_data(path), str(path))


