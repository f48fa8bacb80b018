"""What a study runs: configurations (datasets) × seeds, and what a seed varies.

``vary: all`` gives each seed its own run seed (``seed``): another split and procedural models,
another classifier, other starts. ``vary: train`` keeps the run seed and varies the classifier's
own (``train.seed``): the same models and starts, another trained classifier — the variation
that another CPU brings to one seed. The study folder owns its specification
(``S/study.yaml``), as a workspace owns its configuration.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from rapomdp.config import Config, ConfigError, config_from_dict, parse_yaml, read_config_data
from rapomdp.io import check_plain_name, read_text, write_text_atomic

STUDY_FILE = "study.yaml"
VARIES = ("all", "train")
#: The name a study gives the embedded default configuration.
DEFAULT_DATASET = "default"


@dataclass(frozen=True)
class StudyDataset:
    """One configuration of a study, by name (its file's stem; ``default``), as read."""

    name: str
    data: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_file(cls, path: str | Path) -> StudyDataset:
        path = Path(path)
        return cls(path.stem, read_config_data(path))


@dataclass(frozen=True)
class StudySpec:
    """Configurations × seeds; ``vary``: ``all`` (the run seed) or ``train`` (the classifier's
    seed only).

    What ``rapomdp study`` runs, recorded as ``S/study.yaml``. Every seed's configuration is
    validated when the specification is made, before anything runs.

    Args:
        datasets: The configurations, each named (a file's stem; ``default``: the embedded one).
        seeds: The seeds, distinct integers in [0, 2^32).
        vary: ``all`` (a seed sets the run seed: split, models, classifier, starts) or
            ``train`` (only the classifier's seed: the same models and starts).

    Raises:
        ConfigError: No configuration or seed, repeated seeds or names, an unknown ``vary``,
            or an invalid configuration at a seed.

    Example:
        >>> from rapomdp.study.spec import StudySpec
        >>> spec = StudySpec(seeds=(3, 4), vary="train")
        >>> config = spec.config(spec.datasets[0], 4)
        >>> (config.seed, config.train.seed)  # vary train: the classifier's seed only
        (0, 4)
        >>> print(spec.to_yaml(), end="")
        seeds:
        - 3
        - 4
        vary: train
        datasets:
          default: {}
    """

    datasets: tuple[StudyDataset, ...] = (StudyDataset(DEFAULT_DATASET),)
    seeds: tuple[int, ...] = (0, 1, 2)
    vary: str = "all"

    def __post_init__(self) -> None:
        if not self.datasets:
            raise ConfigError("a study needs at least one configuration")
        if not self.seeds:
            raise ConfigError("a study needs at least one seed")
        if len(set(self.seeds)) != len(self.seeds):
            raise ConfigError(f"study seeds repeat: {list(self.seeds)}")
        if any(isinstance(s, bool) or not isinstance(s, int) or not 0 <= s < 2**32
               for s in self.seeds):
            raise ConfigError(f"study seeds must be integers in [0, 2^32), got {list(self.seeds)}")
        if self.vary not in VARIES:
            raise ConfigError(f"study vary must be one of {', '.join(VARIES)}, got {self.vary!r}")
        names = [d.name for d in self.datasets]
        for name in names:
            check_plain_name(name, "configuration name", STUDY_FILE)
        if len(set(names)) != len(names):
            raise ConfigError(f"two configurations of the study share a name: {names} (the "
                              "name is the file's stem; rename one)")
        for dataset in self.datasets:  # every seed's configuration is valid before any runs
            self.config(dataset, self.seeds[0])

    def config(self, dataset: StudyDataset, seed: int) -> Config:
        """The configuration of ``dataset`` at one seed of the study.

        Args:
            dataset: One of :attr:`datasets`.
            seed: The seed (``vary: all`` sets ``seed``, ``vary: train`` ``train.seed``).

        Returns:
            The validated configuration of that workspace.
        """
        data = copy.deepcopy(dataset.data)
        if self.vary == "all":
            data["seed"] = seed
        else:
            train = data.get("train")
            data["train"] = {**(train if isinstance(train, dict) else {}), "seed": seed}
        return config_from_dict(data, f"{STUDY_FILE}: configuration '{dataset.name}' at seed "
                                      f"{seed}")

    def to_yaml(self) -> str:
        return yaml.safe_dump({"seeds": list(self.seeds), "vary": self.vary,
                               "datasets": {d.name: d.data for d in self.datasets}},
                              sort_keys=False)

    @classmethod
    def from_yaml(cls, text: str, source: str = STUDY_FILE) -> StudySpec:
        data = parse_yaml(text, source)
        if not isinstance(data, dict) or not isinstance(data.get("datasets"), dict) \
                or not isinstance(data.get("seeds"), list):
            raise ConfigError(f"{source}: not a study (expected 'seeds', 'vary' and "
                              "'datasets')")
        unknown = set(data) - {"seeds", "vary", "datasets"}
        if unknown:
            raise ConfigError(f"{source}: unknown key(s) {sorted(unknown)}")
        datasets = []
        for name, config in data["datasets"].items():
            if config is not None and not isinstance(config, dict):
                raise ConfigError(f"{source}: configuration '{name}' is not a mapping")
            datasets.append(StudyDataset(str(name), config or {}))
        return cls(tuple(datasets), tuple(data["seeds"]), str(data.get("vary", "all")))


def study_file(root: str | Path) -> Path:
    return Path(root) / STUDY_FILE


def read_study(root: str | Path) -> StudySpec | None:
    """The specification a study folder holds, or None for a new study.

    Args:
        root: The study folder.

    Returns:
        The recorded ``S/study.yaml`` as a :class:`StudySpec`, or None when there is none.

    Raises:
        ConfigError: The file is not a study specification.
    """
    path = study_file(root)
    if not path.exists():
        return None
    return StudySpec.from_yaml(read_text(path), str(path))


def check_study_folder(root: str | Path) -> None:
    """Refuse, by name, a folder a study would write into that is neither a study (it holds
    ``study.yaml``) nor empty (or missing): a study never writes among a user's files."""
    root = Path(root)
    if not root.exists() or study_file(root).is_file():
        return
    if not root.is_dir():
        raise ConfigError(f"{root}: not a folder; give a study folder")
    if any(root.iterdir()):
        raise ConfigError(f"{root}: not a rapomdp study (no {STUDY_FILE}) and not empty; give "
                          f"a new folder, e.g. {root / 'study'}")


def write_study(root: str | Path, spec: StudySpec) -> Path:
    """Record ``spec`` as the study's own (atomically)."""
    return write_text_atomic(study_file(root), spec.to_yaml())
