from pathlib import Path

import numpy as np
import pytest

from rapomdp.io import ArtefactError, load_npz, read_json, save_npz, write_json_atomic


@pytest.mark.parametrize("compressed", [False, True])
def test_npz_round_trip_is_exact(tmp_path: Path, compressed: bool) -> None:
    arrays = {"depth": np.random.default_rng(0).random((3, 4, 5)).astype(np.float32),
              "labels": np.arange(7, dtype=np.int64), "flag": np.array(True)}
    save_npz(tmp_path / "a.npz", compressed=compressed, **arrays)
    back = load_npz(tmp_path / "a.npz")
    assert back.keys() == arrays.keys()
    for key, value in arrays.items():
        assert back[key].dtype == value.dtype
        np.testing.assert_array_equal(back[key], value)
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"], "no temporary file left behind"


def test_object_arrays_and_pickles_are_refused(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="dtype object"):
        save_npz(tmp_path / "b.npz", bad=np.array([{"a": 1}], dtype=object))
    assert not (tmp_path / "b.npz").exists()
    np.savez(tmp_path / "pickled.npz", bad=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ArtefactError, match="not a plain .npz archive"):
        load_npz(tmp_path / "pickled.npz")


def test_json_atomic_and_named_errors(tmp_path: Path) -> None:
    write_json_atomic(tmp_path / "x.json", {"b": 1, "a": [1, 2]})
    assert read_json(tmp_path / "x.json") == {"a": [1, 2], "b": 1}
    (tmp_path / "bad.json").write_text("{oops")
    with pytest.raises(ArtefactError, match="bad.json: not valid JSON"):
        read_json(tmp_path / "bad.json")
    with pytest.raises(ArtefactError, match="missing.json: not found"):
        read_json(tmp_path / "missing.json")
