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


def test_damaged_archives_are_named(tmp_path: Path) -> None:
    save_npz(tmp_path / "a.npz", compressed=True, x=np.arange(1000.0))
    data = (tmp_path / "a.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "text.npz").write_bytes(b"not a zip at all" * 10)
    for name, message in (("cut", "damaged .npz archive"), ("empty", "empty file"),
                          ("text", "npz")):
        with pytest.raises(ArtefactError, match=message) as info:
            load_npz(tmp_path / f"{name}.npz")
        assert str(tmp_path / f"{name}.npz") in str(info.value)
        assert "\n" not in str(info.value)


def test_json_that_is_not_utf8_is_named(tmp_path: Path) -> None:
    (tmp_path / "m.json").write_bytes(b'{"caf\xe9": 1}')
    with pytest.raises(ArtefactError, match=r"m.json: not valid JSON \(byte 5 is not UTF-8\)"):
        read_json(tmp_path / "m.json")


def test_text_decoding_and_plain_names() -> None:
    from rapomdp.io import check_plain_name, decode_text, plain_name

    for encoding in ("utf-8", "utf-8-sig", "utf-16", "utf-32", "latin-1"):
        assert decode_text("# modèle\nv 0 0 0\n".encode(encoding), "f") == "# modèle\nv 0 0 0\n"
    with pytest.raises(ArtefactError, match="f: binary data"):
        decode_text(b"v 0\x00", "f")
    for good in ("cup", "trash can", "02691156", "é-class", "a&b"):
        assert check_plain_name(good, "class", "src") == good
    for bad in ("../../../x", "a/b", "..", ".hidden", "x\x00", "a\\b", "", "x" * 129, "x."):
        with pytest.raises(ArtefactError, match="not a plain name"):
            check_plain_name(bad, "class", "src")
    assert [plain_name(n) for n in ("..", "a/b", ".x", "m#1")] == ["model", "a_b", "x", "m#1"]


def test_os_errors_are_described_by_file_and_cause() -> None:
    import errno

    from rapomdp.io import describe_os_error

    full = OSError(errno.ENOSPC, "No space left on device", "/w/render/x.npz")
    assert describe_os_error(full) == "/w/render/x.npz: no space left on the device"
    read_only = OSError(errno.EROFS, "Read-only file system", "/w/.lock")
    assert describe_os_error(read_only) == "/w/.lock: the file system is read-only"


def test_outputs_replace_only_a_regular_file(tmp_path: Path, monkeypatch) -> None:
    """An output path may be new or a regular file; a folder, link, FIFO, socket or device is
    refused by name before any temporary file is made beside it."""
    import os
    import re
    import socket
    import stat

    from rapomdp.io import check_output_path, write_text_atomic

    write_text_atomic(tmp_path / "new" / "a.txt", "one")
    write_text_atomic(tmp_path / "new" / "a.txt", "two")  # a regular file is replaced
    assert (tmp_path / "new" / "a.txt").read_text() == "two"
    (tmp_path / "folder").mkdir()
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "new" / "a.txt")
    listener = socket.socket(socket.AF_UNIX)
    monkeypatch.chdir(tmp_path)
    listener.bind("sock")  # relative: socket paths are limited to 108 bytes
    try:
        for name, kind in (("folder", "a folder"), ("fifo", "a named pipe (FIFO)"),
                           ("link", "a symbolic link"), ("sock", "a socket")):
            with pytest.raises(ArtefactError, match=re.escape(f"{name}: {kind}, not a regular")):
                write_text_atomic(tmp_path / name, "x")
    finally:
        listener.close()
    assert (tmp_path / "new" / "a.txt").read_text() == "two", "not written through the link"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "folder", "link", "new",
                                                          "sock"], "no temporary left"
    real_lstat = os.lstat  # a device, without making one: lstat says what it is

    def device(path: object, *args: object, **kwargs: object) -> os.stat_result:
        result = real_lstat(path, *args, **kwargs)  # type: ignore[arg-type]
        if os.fspath(path).endswith("dev"):  # type: ignore[arg-type]
            return os.stat_result((stat.S_IFCHR | 0o666, *result[1:]))
        return result

    (tmp_path / "dev").write_text("")
    monkeypatch.setattr(os, "lstat", device)
    with pytest.raises(ArtefactError, match="dev: a character device, not a regular file"):
        check_output_path(tmp_path / "dev")


def test_atomic_temporary_in_a_given_folder(tmp_path: Path) -> None:
    from rapomdp.io import write_text_atomic

    (tmp_path / "scratch").mkdir()
    write_text_atomic(tmp_path / "f.txt", "x" * 10, tmp_dir=tmp_path / "scratch")
    write_text_atomic(tmp_path / ("n" * 250), "long names fit the temporary's name")
    assert (tmp_path / "f.txt").read_text() == "x" * 10
    assert list((tmp_path / "scratch").iterdir()) == []


def test_a_file_name_of_250_bytes_is_written_atomically(tmp_path: Path) -> None:
    from rapomdp.io import write_text_atomic

    save_npz(tmp_path / ("m" * 246 + ".npz"), a=np.zeros(3))
    write_text_atomic(tmp_path / ("é" * 127), "x")  # 254 bytes of UTF-8
    assert sorted(len(p.name.encode()) for p in tmp_path.iterdir()) == [250, 254]


def test_a_full_disk_inside_an_npz_names_the_file(tmp_path: Path, monkeypatch) -> None:
    import errno
    import zipfile

    from rapomdp.io import describe_os_error

    def full(self, data):  # as the kernel's write(2) fails: no file name on the error
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(zipfile._ZipWriteFile, "write", full)
    with pytest.raises(OSError) as info:
        save_npz(tmp_path / "views.npz", a=np.zeros(3))
    assert describe_os_error(info.value) == f"{tmp_path / 'views.npz'}: no space left on the device"
    assert list(tmp_path.iterdir()) == []
