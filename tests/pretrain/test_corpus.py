"""The pretraining corpus: no evaluation class, no held-back source, reproducible families."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from rapomdp.data.build.common import DatasetBuildError
from rapomdp.data.procedural.abstract import (
    PRIMITIVES,
    abstract_family,
    generate_abstract,
    unit_primitive,
)
from rapomdp.data.procedural.classes import PROCEDURAL_CLASSES
from rapomdp.pretrain.corpus import (
    EVALUATION_CLASSES,
    KICAD_CORPUS,
    build_corpus,
    check_corpus_class,
)


def test_evaluation_classes_cover_every_evaluation_set() -> None:
    assert {"mug", "snowman", "resistor", "pin_header", "resistor_tht",
            "connector_pinheader_2.54mm"} <= EVALUATION_CLASSES
    # 35 + 11 + 24 classes + 24 folders, less stool (default and mesh set) and the folders
    # named as their class (Crystal, Battery, Varistor)
    assert len(EVALUATION_CLASSES) == len(PROCEDURAL_CLASSES) + 11 + 24 + 24 - 4


def test_kicad_corpus_holds_no_evaluation_class() -> None:
    names = {n.lower().replace("-", "_") for n in [*KICAD_CORPUS, *KICAD_CORPUS.values()]}
    assert not names & EVALUATION_CLASSES
    assert len(KICAD_CORPUS) == 12


@pytest.mark.parametrize("name", ["Mug", "bicycle", "Resistor_THT", "ring-stand", "dsub"])
def test_an_evaluation_class_is_refused_by_name(name: str) -> None:
    with pytest.raises(DatasetBuildError, match=f"class '{name}' is an evaluation class"):
        check_corpus_class(name, "--extra folder")


def test_a_held_back_source_is_refused(tmp_path: Path) -> None:
    with pytest.raises(DatasetBuildError, match="'sweethome3d-furniture' is held back"):
        check_corpus_class("sweethome3d-furniture", "--extra folder")
    held = tmp_path / "sweethome3d-models"
    (held / "lamp_post").mkdir(parents=True)
    with pytest.raises(DatasetBuildError, match="held back"):
        build_corpus(tmp_path / "corpus", families=2, models_per_family=1, kicad=False,
                     extra=[held])
    with pytest.raises(DatasetBuildError, match="held back"):
        build_corpus(tmp_path / "corpus", families=2, models_per_family=1,
                     deb=tmp_path / "sweethome3d_6.4_all.deb")
    assert not (tmp_path / "corpus").exists()


def test_an_extra_folder_with_an_evaluation_class_is_refused_and_nothing_is_left(
        tmp_path: Path) -> None:
    extra = tmp_path / "mine"
    (extra / "chair").mkdir(parents=True)
    trimesh.creation.box().export(extra / "chair" / "a.stl")
    with pytest.raises(DatasetBuildError, match="class 'chair' is an evaluation class"):
        build_corpus(tmp_path / "corpus", families=2, models_per_family=1, kicad=False,
                     extra=[extra])
    assert not (tmp_path / "corpus").exists()
    assert not list(tmp_path.glob(".corpus.building-*"))


def test_build_writes_every_class_and_its_sources(tmp_path: Path) -> None:
    extra = tmp_path / "mine"
    (extra / "widget").mkdir(parents=True)
    for k in range(2):
        trimesh.creation.box(extents=(1, 1 + k, 2)).export(extra / "widget" / f"w{k}.stl")
    build = build_corpus(tmp_path / "corpus", families=3, models_per_family=2, kicad=False,
                         extra=[extra])
    assert build.classes == {"abstract_000": 2, "abstract_001": 2, "abstract_002": 2,
                             "widget": 2}
    source = json.loads((build.out / "SOURCE.json").read_text())
    assert [s["models"] for s in source["sources"]] == [6, 2]
    assert sorted(p.name for p in (build.out / "widget").iterdir()) == ["w0.ply", "w1.ply"]
    assert "total: 4 classes, 8 models" in build.summary()


def test_families_are_reproducible_and_differ() -> None:
    a, b = generate_abstract(abstract_family(5), 0, 1), generate_abstract(abstract_family(5), 0, 1)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    other = generate_abstract(abstract_family(5), 0, 2)
    assert a.vertices.shape != other.vertices.shape or not np.allclose(a.vertices,
                                                                       other.vertices)
    assert abstract_family(5) != abstract_family(6)
    assert a.vertices[:, 2].min() == 0.0
    assert {abstract_family(i).body for i in range(60)} == set(PRIMITIVES)


@pytest.mark.parametrize("kind", PRIMITIVES)
def test_unit_primitives_fill_the_unit_cube(kind: str) -> None:
    bounds = unit_primitive(kind).bounds
    extents = bounds[1] - bounds[0]
    assert np.all(extents <= 1.0 + 1e-9) and np.all(extents >= 0.74)  # a prism: 0.75 deep
    np.testing.assert_allclose(bounds.mean(axis=0), 0.0, atol=0.13)


def test_unknown_primitive_is_named() -> None:
    with pytest.raises(ValueError, match="unknown primitive 'blob'"):
        unit_primitive("blob")
