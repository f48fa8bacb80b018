"""Configuration options that lost their decision, refused by name for one release.

An option a measured decision declined is removed from the configuration and its code. For one
release a configuration that still names it is handled as scikit-learn handles a deprecation:

- a retired key at the value every workspace had by default is dropped without a word, so
  the ``config.yaml`` and manifest records of workspaces made before the retirement still load
  and keep their cached stages;
- a retired key at any other value, or a retired value of a key that stays, is refused with one
  line naming the key, the value and the decision page that retired it.

Example:
    >>> from rapomdp.retired import drop_retired
    >>> drop_retired({"train": {"norm": "none", "epochs": 5}}, "my.yaml")
    {'train': {'epochs': 5}}
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

#: Where the decision pages live, relative to the repository (and the documentation site).
DECISIONS = "docs/decisions"


@dataclass(frozen=True)
class RetiredKey:
    """A key removed from the configuration.

    Attributes:
        default: the value it had by default, which every workspace made before the
            retirement recorded; at this value the key is dropped silently.
        page: the decision page (file name under ``docs/decisions/``) that retired it.
        keyed: the key was in its stage's cache key at ``default``; it stays there, so the
            workspaces and checkpoints made before the retirement keep their keys.
    """

    default: Any
    page: str
    keyed: bool = False


#: Keys removed from the configuration, by dotted path.
RETIRED_KEYS: dict[str, RetiredKey] = {
    "dataset.auto_volume_models": RetiredKey(3, "0002-auto-volume-models.md"),
    "train.norm": RetiredKey("none", "0013-batch-norm.md"),
    "train.lr_schedule": RetiredKey("constant", "0014-training-changes.md"),
    "train.keep": RetiredKey("last", "0014-training-changes.md"),
    "train.augment.flip": RetiredKey(False, "0014-training-changes.md"),
    "train.augment.aspect": RetiredKey(0.0, "0014-training-changes.md"),
    "observe.evidence": RetiredKey("volume", "0001-cross-fitted-evidence.md"),
    "observe.crossfit_folds": RetiredKey(3, "0001-cross-fitted-evidence.md"),
    "observe.crossfit_epochs": RetiredKey(6, "0001-cross-fitted-evidence.md"),
    "observe.belief": RetiredKey("naive", "0004-nuisance-and-similarity-beliefs.md"),
    "observe.discount_walks": RetiredKey("neighbours", "0004-nuisance-and-similarity-beliefs.md"),
    "observe.class_shrinkage": RetiredKey("none", "0007-class-shrinkage.md"),
    "observe.transfer_shrinkage": RetiredKey(False, "0008-transfer-shrinkage.md"),
    "observe.contrastive": RetiredKey(False, "0009-contrastive-model.md"),
    "evaluate.lookahead_depth": RetiredKey(1, "0010-lookahead-depth.md", keyed=True),
    "evaluate.lookahead_width": RetiredKey(4, "0010-lookahead-depth.md", keyed=True),
    "evaluate.declared_fit": RetiredKey("closed_loop", "0011-declared-fit.md", keyed=True),
    "evaluate.declared_form": RetiredKey("scalar", "0012-declared-form.md"),
    "observe.belief_correction": RetiredKey("temperature", "0003-belief-correction.md"),
    "vptree.belief_correction": RetiredKey("temperature", "0003-belief-correction.md"),
    "observe.wrong_labels": RetiredKey("auto", "0017-wrong-labels.md"),
    "train.input_features": RetiredKey("depth_normals", "0019-surface-normals.md", keyed=True),
    "evaluate.lookahead": RetiredKey(True, "0015-lookahead.md", keyed=True),
    "evaluate.declared_confidence": RetiredKey("calibrated", "0016-declared-confidence.md",
                                               keyed=True),
    "learn.declare": RetiredKey("map", "0018-learned-declaration.md", keyed=True),
}

#: Values removed from keys that stay, by dotted path: value -> decision page.
RETIRED_VALUES: dict[str, dict[Any, str]] = {
    "observe.ra_model": {"auto": "0006-ra-model-mixture.md",
                         "region": "0006-ra-model-mixture.md",
                         "contrastive": "0009-contrastive-model.md"},
}


class RetiredOptionError(ValueError):
    """A configuration names an option a decision retired (the message names its page)."""


def _page(name: str) -> str:
    return f"{DECISIONS}/{name}"


def drop_retired(data: dict[str, Any], source: str) -> dict[str, Any]:
    """``data`` without the retired keys that hold their former default (a new mapping).

    Args:
        data: a configuration mapping as read from YAML (sections of keys), unvalidated.
        source: where it came from, for the error message (a file name).

    Returns:
        The same mapping less every retired key at its former default.

    Raises:
        RetiredOptionError: a retired key at another value, or a retired value; the message
            names the key, the value and the decision page.
    """
    result = copy.deepcopy(data)
    for dotted, retired in RETIRED_KEYS.items():
        *parents, leaf = dotted.split(".")
        node: Any = result
        for part in parents:
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict) or leaf not in node:
            continue
        value = node[leaf]
        same_kind = isinstance(value, bool) == isinstance(retired.default, bool)
        if value == retired.default and same_kind:
            del node[leaf]
            continue
        raise RetiredOptionError(
            f"{source}: {dotted} was retired (set to {value!r}; its only behaviour now is "
            f"{retired.default!r}): see {_page(retired.page)}; remove the key")
    for dotted, values in RETIRED_VALUES.items():
        *parents, leaf = dotted.split(".")
        node = result
        for part in parents:
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict) or leaf not in node:
            continue
        value = node[leaf]
        if isinstance(value, str | bool | int | float) and value in values:
            raise RetiredOptionError(
                f"{source}: {dotted}: {value!r} was retired: see {_page(values[value])}; "
                "remove the key for the default")
    return result


def keyed_retired(section: str) -> dict[str, Any]:
    """The retired keys of a top-level section that stay in its stage keys, at their value.

    Args:
        section: a top-level section's name (``train``, ``evaluate`` ...).

    Returns:
        Key -> its one value, for every :attr:`RetiredKey.keyed` key of the section.

    Example:
        >>> keyed_retired("learn")
        {'declare': 'map'}
    """
    return {dotted.split(".", 1)[1]: retired.default for dotted, retired in RETIRED_KEYS.items()
            if retired.keyed and dotted.startswith(f"{section}.") and dotted.count(".") == 1}
