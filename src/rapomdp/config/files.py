"""The configuration's files: YAML read safely and bounded, ``KEY=VALUE`` overrides, and the
commented YAML ``rapomdp config`` prints.

Nothing here knows the sections (:mod:`rapomdp.config.sections`); it reads and writes the
mappings they are validated from.

Example:
    >>> apply_overrides({"train": {"epochs": 25}}, ["train.epochs=5", "seed=3"])
    {'train': {'epochs': 5}, 'seed': 3}
"""

from __future__ import annotations

import copy
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel

from rapomdp.io import ArtefactError, decode_text


class ConfigError(ValueError):
    """The configuration file is unreadable or holds a wrong key or value (named)."""



#: Units by name suffix (the configuration's naming convention).
UNIT_SUFFIXES = {"_m_per_rad": "metres per radian", "_m": "metres", "_deg": "degrees",
                 "_rad": "radians", "_s": "seconds", "_px": "pixels"}


def _field_comment(name: str, description: str | None) -> str:
    unit = next((u for suffix, u in UNIT_SUFFIXES.items() if name.endswith(suffix)), None)
    parts = [description] if description else []
    if unit and not (description and unit in description):
        parts.append(f"unit: {unit}")
    return "; ".join(parts)


def _flow(value: Any) -> str:
    """One value as a YAML flow scalar or collection (on one line)."""
    text = yaml.safe_dump(value, default_flow_style=True, width=10**9, sort_keys=False)
    return text.removesuffix("...\n").strip()


def commented_lines(model: BaseModel, indent: int) -> list[str]:
    pad = " " * indent
    lines = []
    dumped = model.model_dump(mode="json")
    for name, field in type(model).model_fields.items():
        value = getattr(model, name)
        if isinstance(value, BaseModel):
            paragraph = " ".join((type(value).__doc__ or "").strip().split("\n\n")[0].split())
            if paragraph:
                lines.append(f"{pad}# {paragraph.replace('``', '')}")
            lines.append(f"{pad}{name}:")
            lines.extend(commented_lines(value, indent + 2))
            continue
        comment = _field_comment(name, field.description)
        line = f"{pad}{name}: {_flow(dumped[name])}"
        lines.append(f"{line}  # {comment}" if comment else line)
    return lines


#: Bounds of a configuration document: bytes, YAML aliases, and nodes once aliases are expanded
#: (a "billion laughs" document is a few hundred bytes that expand to 10^9 nodes).
MAX_CONFIG_BYTES = 1 << 20
MAX_ALIASES = 32
MAX_EXPANDED_NODES = 100_000


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing documents with many aliases or a huge expansion."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.aliases = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        if self.check_event(yaml.AliasEvent):
            self.aliases += 1
            if self.aliases > MAX_ALIASES:
                raise yaml.YAMLError(f"more than {MAX_ALIASES} aliases (*name); write the "
                                     "values out")
        return super().compose_node(parent, index)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        """A mapping whose keys are unique: a key given twice (a second ``train:`` section,
        ``seed: 1`` then ``seed: 2``) is an error naming it and both lines, not the last one
        silently winning. Keys merged in by ``<<: *alias`` may still be overridden."""
        first: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                line = first.get(key)
            except TypeError:  # an unhashable key: the constructor names it
                continue
            if line is not None:
                raise yaml.constructor.ConstructorError(
                    None, None, f"the key {str(key)[:60]!r} is given twice (lines {line + 1} "
                    f"and {key_node.start_mark.line + 1})", key_node.start_mark)
            first[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep)

    def construct_unordered_set(self, node: yaml.Node) -> None:
        """``!!set``: refused, its order would follow the process's hash seed."""
        raise yaml.constructor.ConstructorError(
            None, None, "a !!set has no order (it would follow the process's hash seed); "
            "write a list, e.g. [cup, mug]", node.start_mark)


_BoundedLoader.add_constructor("tag:yaml.org,2002:set", _BoundedLoader.construct_unordered_set)


def _expanded_size(node: yaml.Node, memo: dict[int, int]) -> int:
    """Nodes in ``node`` with every alias expanded (memoised: linear in the document)."""
    if id(node) in memo:
        return memo[id(node)]
    memo[id(node)] = 1  # a recursive alias counts once; the constructor handles the cycle
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, memo) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    else:
        size = 1
    memo[id(node)] = min(size, MAX_EXPANDED_NODES + 1)
    return memo[id(node)]


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """One line: where and what (PyYAML's own message spans several lines)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return (where + " ".join(str(problem).split()))[:300]


def parse_yaml(text: str, source: str) -> Any:
    """A YAML document's data, bounded in aliases and expanded size (named ConfigError)."""
    loader = _BoundedLoader(text)
    try:
        node = loader.get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_EXPANDED_NODES:
            raise yaml.YAMLError(f"more than {MAX_EXPANDED_NODES} values once aliases are "
                                 "expanded")
        return None if node is None else loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: not valid YAML ({_yaml_problem(exc)})") from None
    except RecursionError:
        raise ConfigError(f"{source}: not valid YAML (nested too deeply)") from None
    finally:
        loader.dispose()


def read_config_data(path: str | Path) -> dict[str, Any]:
    """The mapping a YAML configuration file holds (any common text encoding), unvalidated."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            raw = handle.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{path}: larger than {MAX_CONFIG_BYTES >> 20} MiB; not a "
                          "configuration")
    try:
        text = decode_text(raw, path)
    except ArtefactError as exc:
        raise ConfigError(str(exc)) from None
    data = parse_yaml(text, str(path))
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    return data



_OVERRIDE_KEY = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


def apply_overrides(data: dict[str, Any], overrides: Sequence[str]) -> dict[str, Any]:
    """``data`` with command-line overrides ``section.key=value`` applied (a new mapping).

    The value is read as YAML (``5``, ``0.5``, ``true``, ``null``, ``[cup, mug]``), so it is
    typed as in the file and validated with it.
    """
    result = copy.deepcopy(data)
    for item in overrides:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not _OVERRIDE_KEY.fullmatch(key):
            raise ConfigError(f"override {item[:80]!r}: expected section.key=value "
                              "(e.g. train.epochs=5)")
        value = parse_yaml(text, f"override {key}") if text.strip() else None
        parts = key.split(".")
        node = result
        for depth, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f"override {key}: {'.'.join(parts[:depth + 1])} is a value, "
                                  "not a section")
            node = child
        node[parts[-1]] = value
    return result
