"""A workspace's manifest: the stage records, the configuration they were made with, and
which stages are current under a configuration (their keys)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rapomdp.config import Config, ConfigError, config_from_dict, read_config_data
from rapomdp.io import ArtefactError, read_json
from rapomdp.workspace.folder import WorkspaceFolder
from rapomdp.workspace.layout import CONFIG_FILE, StageError
from rapomdp.workspace.stages import (
    Stage,
    StageInputs,
    StageStatus,
    describe_change,
    stage_key,
)


class WorkspaceManifest(WorkspaceFolder):
    """The manifest and the stages' keys (a base of :class:`Workspace`)."""

    def manifest(self) -> dict[str, Any]:
        """``manifest.json`` checked for its shape.

        Returns:
            ``{"stages": {name: record}}``, each record with at least ``key`` and ``files``
            (``{"stages": {}}`` for a workspace with none).

        Raises:
            ArtefactError: The file is not a rapomdp manifest, or a record is damaged.
        """
        if not self.manifest_path.exists():
            return {"stages": {}}
        data = read_json(self.manifest_path)
        stages = data.get("stages") if isinstance(data, dict) else None
        if not isinstance(stages, dict):
            got = "a mapping without it" if isinstance(data, dict) else type(data).__name__
            raise ArtefactError(
                f"{self.manifest_path}: not a rapomdp manifest (expected a mapping with "
                f"'stages', got {got}); move it away and rerun the stages")
        for name, record in stages.items():
            if (not isinstance(record, dict) or not isinstance(record.get("key"), str)
                    or not isinstance(record.get("files"), list)):
                raise ArtefactError(f"{self.manifest_path}: the record of stage {str(name)[:40]!r}"
                                    " is damaged (no key or files); rerun it with --force")
        return data

    def recorded_config(self) -> Config | None:
        """The configuration the workspace's artefacts were made with (``W/config.yaml``; when
        it is missing, the one the stage records hold, :meth:`records_config_data`), or None
        for a new workspace.

        Raises:
            ConfigError: The recorded configuration is not valid (named, with its key).
        """
        if self.config_path.exists():
            return config_from_dict(read_config_data(self.config_path), str(self.config_path))
        data = self.records_config_data()
        return None if data is None else config_from_dict(data, self.records_source())

    def records_config_data(self) -> dict[str, Any] | None:
        """The configuration sections the manifest's stage records hold, merged (where two
        disagree, the stage that finished last wins; a section no stage read is left out, so
        it is the default), or None when no stage is recorded."""
        records = [record for record in self.manifest()["stages"].values()
                   if isinstance(record.get("config"), dict)]
        if not records:
            return None
        data: dict[str, Any] = {}
        for record in sorted(records, key=lambda r: str(r.get("finished", ""))):  # stable
            data.update(record["config"])
        return data

    def records_source(self) -> str:
        """How a configuration rebuilt from the stage records is named in messages."""
        return f"the stage records of {self.manifest_path} ({CONFIG_FILE} is missing)"

    def record_config(self, config: Config) -> None:
        """Write ``W/config.yaml`` (skipped when unchanged, so a read-only cached run works)."""
        text = config.to_yaml()
        try:
            if self.config_path.exists() and self.config_path.read_text("utf-8") == text:
                return
        except (OSError, UnicodeDecodeError):
            pass
        self._write_file(self.config_path, text)

    def config(self, default: Config | None = None) -> Config:
        """The configuration the workspace was run with: ``W/config.yaml``, validated.

        Args:
            default: What to return when the workspace records no configuration.

        Returns:
            The recorded configuration (rebuilt from the stage records when ``config.yaml``
            is missing, :meth:`recorded_config`), else ``default``.

        Raises:
            StageError: Nothing is recorded and no ``default`` was given.
        """
        recorded = self.recorded_config()
        if recorded is not None:
            return recorded
        if default is not None:
            return default
        raise StageError(f"{self.config_path}: not found; a workspace made by `rapomdp` "
                         f"holds the configuration it ran with")

    def inputs(self, stage: Stage) -> StageInputs:
        """The folders of ``stage``'s inputs here, each a finished stage (:meth:`require`).

        Args:
            stage: The stage about to run.

        Returns:
            One folder per stage of ``stage.inputs``, named after it.
        """
        return StageInputs.of(stage.name, {name: self.require(name) for name in stage.inputs})

    def require(self, name: str) -> Path:
        """The folder of a finished stage, or an error saying how to make it.

        Args:
            name: The stage's name (``"dataset"``, ``"train"``, ...).

        Returns:
            ``W/name``, recorded in the manifest.

        Raises:
            StageError: The stage has not run here (the message names the command that
                runs it).
        """
        record = self.manifest()["stages"].get(name)
        path = self.stage_dir(name)
        if record is None or not path.is_dir():
            raise StageError(
                f"{self.root}: stage '{name}' has not been run here; "
                f"run `rapomdp run --workspace {self.root} --until {name}` first"
            )
        return path

    def _key_parts(self, stage: Stage, config: Config) -> tuple[str, dict[str, str], str | None]:
        """The stage's key, its inputs' keys and its external fingerprint."""
        stages = self.manifest()["stages"]
        upstream = {}
        for name in stage.inputs:
            if name not in stages:
                raise StageError(f"stage '{stage.name}' needs stage '{name}', which has not run")
            upstream[name] = stages[name]["key"]
        external = stage.fingerprint(config) if stage.fingerprint else None
        return stage_key(stage, config, upstream, external), upstream, external

    def key_of(self, stage: Stage, config: Config) -> str:
        """The key ``stage`` would be recorded under here with ``config`` (its inputs' keys
        from the manifest, :func:`~rapomdp.workspace.stage_key`): a hex SHA-256 string."""
        return self._key_parts(stage, config)[0]

    def staleness(self, stages: Sequence[Stage], config: Config,
                  external: bool = True) -> dict[str, list[str]]:
        """Why each recorded stage's artefacts would not be reused under ``config``.

        ``stages`` in pipeline order; a stage is stale when a section it reads changed, its
        code version changed, an input stage is stale or was redone since, or (``external``)
        the files it reads from outside changed. Stages without a record are left out.

        Args:
            stages: The stages to judge, in pipeline order.
            config: The configuration a run would use.
            external: Also read the fingerprints of the files each stage reads from outside
                the workspace (a user's meshes).

        Returns:
            ``{stage: [reason, ...]}`` for the stale stages only, e.g.
            ``{"train": ["train.epochs 25 -> 5"]}``.
        """
        records = self.manifest()["stages"]
        stale: dict[str, list[str]] = {}
        for stage in stages:
            record = records.get(stage.name)
            if record is None:
                continue
            reasons = []
            if not self.stage_dir(stage.name).is_dir():
                reasons.append("its folder is missing")
            if str(record.get("version")) != stage.version:
                reasons.append(f"stage version {record.get('version')} -> {stage.version}")
            recorded = record.get("config") if isinstance(record.get("config"), dict) else {}
            for section in stage.sections:
                if recorded.get(section) != config.section(section):
                    reasons.append(describe_change(section, recorded.get(section),
                                                   config.section(section)))
            input_keys = record.get("input_keys")
            for name in stage.inputs:
                if name in stale:
                    reasons.append(f"input {name} is stale")
                elif name not in records:
                    reasons.append(f"input {name} has no record")
                elif isinstance(input_keys, dict) and input_keys.get(name) != records[name]["key"]:
                    reasons.append(f"input {name} was redone since")
            if external and not reasons:
                try:
                    if self.key_of(stage, config) != record["key"]:
                        reasons.append("its input files changed" if stage.fingerprint
                                       else "its inputs changed")
                except (StageError, ArtefactError, ConfigError, OSError) as exc:
                    reasons.append(f"its inputs cannot be read ({str(exc)[:120]})")
            if reasons:
                stale[stage.name] = reasons
        return stale

    def status(self, stages: Sequence[Stage], config: Config) -> list[StageStatus]:
        """One :class:`StageStatus` per stage of ``stages`` (pipeline order), from the manifest
        and :meth:`staleness` under ``config`` (input files included): what ``rapomdp status``
        shows.

        Args:
            stages: The stages, in pipeline order.
            config: The configuration to judge staleness against.

        Returns:
            One row per stage: ``current``, ``stale`` (with its reasons) or ``not run``.
        """
        records = self.manifest()["stages"]
        stale = self.staleness(stages, config)
        rows = []
        for stage in stages:
            record = records.get(stage.name)
            if record is None:
                rows.append(StageStatus(stage.name, "not run"))
                continue
            seconds = record.get("seconds")
            rows.append(StageStatus(
                stage.name, "stale" if stage.name in stale else "current",
                stale.get(stage.name, []), len(record["files"]), record["key"],
                float(seconds) if isinstance(seconds, int | float) else None,
                str(record["finished"]) if record.get("finished") is not None else None,
                record.get("shared_from")))
        return rows

    def is_current(self, stage: Stage, config: Config) -> bool:
        """Whether ``stage``'s folder is here and recorded under the key ``config`` gives it
        (a run would skip it)."""
        record = self.manifest()["stages"].get(stage.name)
        return (
            record is not None
            and self.stage_dir(stage.name).is_dir()
            and record["key"] == self.key_of(stage, config)
        )

