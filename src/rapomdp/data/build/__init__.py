"""The dataset builders: the mesh folders behind the claims beyond the embedded dataset, each
written in the ``generic`` folder layout that ``dataset: {source: folder}`` reads.

- ``real-cad`` (:mod:`rapomdp.data.build.real_cad`): electronic components from Debian's
  ``kicad-packages3d``; ``set="first"`` or ``"second"`` (12 disjoint classes).
- ``mesh-set`` (:mod:`rapomdp.data.build.mesh_set`): 11 classes composed of primitives.

This module imports no builder until one is asked for (``rapomdp --help`` stays fast).

Example:
    >>> from rapomdp.data.build import BUILDERS
    >>> sorted(BUILDERS)
    ['mesh-set', 'real-cad']
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rapomdp.data.build.common import HELD_BACK, DatasetBuildError, refuse_held_back

__all__ = ["BUILDERS", "HELD_BACK", "Builder", "DatasetBuildError", "build", "refuse_held_back"]


@dataclass(frozen=True)
class Builder:
    """What a builder makes and needs.

    Attributes:
        summary: what it writes.
        needs: what it needs from the system.
        duration: how long it takes.
        options: the options of :func:`build` it takes.
        config: the configuration that reads its default folder.
    """

    summary: str
    needs: str
    duration: str
    options: tuple[str, ...]
    config: str


BUILDERS: dict[str, Builder] = {
    "real-cad": Builder(
        summary="electronic components from Debian's kicad-packages3d (resistor, capacitor, "
                "inductor, crystal, led, transistor, dip_ic, relay, potentiometer, dsub, "
                "transformer, battery), 16 models a class; --set second gives as many other "
                "classes (pin header, QFN, SOIC, connectors ...)",
        needs="apt-get and dpkg-deb (Debian or Ubuntu; 'apt-get update' once; a 379 MB "
              "download, about 240 MB unpacked into --cache), or --deb FILE, or --source DIR "
              "(the package unpacked)",
        duration="about a minute a set, most of it the download",
        options=("which", "cache", "deb", "source", "max_per_class"),
        config="configs/real-cad-dev.yaml (--set second: configs/real-cad-dev-2.yaml)",
    ),
    "mesh-set": Builder(
        summary="objects composed of primitives (lamp, mushroom, rocket, stool, bench, "
                "snowman, dumbbell, arch, gate, goblet, ring stand), 11 models a class",
        needs="nothing beyond this package",
        duration="seconds",
        options=("models_per_class", "seed"),
        config="configs/mesh-set.yaml",
    ),
}


#: The command line's flag of each option of :func:`build`.
FLAGS = {"which": "--set", "cache": "--cache", "deb": "--deb", "source": "--source",
         "max_per_class": "--max-per-class", "models_per_class": "--models", "seed": "--seed"}


def describe() -> str:
    """Every builder, what it writes, needs and takes, one paragraph each (the CLI's help)."""
    return "\n\n".join(f"`{name}`: {b.summary}. Needs {b.needs}. Takes {b.duration}. "
                       f"Read by {b.config}." for name, b in BUILDERS.items())


def build(name: str, out: Path | None = None, **options: object) -> str:
    """Build the dataset ``name`` into ``out``.

    Args:
        name: a key of :data:`BUILDERS`.
        out: the mesh folder (default: the one its configuration reads).
        **options: the builder's options (``Builder.options``); None means its default.

    Returns:
        A summary of what was written (counts per class).

    Raises:
        DatasetBuildError: an unknown builder, an option it does not take, a held-back source,
            or a failure the message explains.
    """
    if name not in BUILDERS:
        raise DatasetBuildError(f"no dataset builder {name!r}; the builders: "
                                f"{', '.join(BUILDERS)}")
    given = {key: value for key, value in options.items() if value is not None}
    foreign = sorted(set(given) - set(BUILDERS[name].options))
    if foreign:
        flags = ", ".join(FLAGS.get(key, key) for key in foreign)
        raise DatasetBuildError(f"{name} does not take {flags}")
    if name == "real-cad":
        from rapomdp.data.build.real_cad import build_real_cad

        result = build_real_cad(out, **given)  # type: ignore[arg-type]
        return result.summary()
    from rapomdp.data.build.mesh_set import build_mesh_set

    counts = build_mesh_set(out, **given)  # type: ignore[arg-type]
    target = out if out is not None else Path("runs/mesh-set/meshes")
    return (f"wrote {sum(counts.values())} meshes of {len(counts)} classes to {target}: "
            + ", ".join(f"{c} {n}" for c, n in counts.items()))
