"""genplan.cache: arrays written whole with their sha256, read back only when the bytes match it;
.npy files written with errors that carry their errno and path."""

from __future__ import annotations

import errno
import hashlib
import io

import numpy as np
import pytest

from genplan.cache import hash_path, load_array, read_npy, save_array, write_npy


@pytest.mark.parametrize("array", [np.arange(35.0).reshape(5, 7), np.zeros((0, 7)), np.array(3.0),
                                   np.ones((2, 3, 4), np.float32), np.asfortranarray(np.arange(12.0).reshape(3, 4)),
                                   np.arange(10)[::3]], ids=["2d", "empty", "0d", "float32", "fortran", "strided"])
def test_write_npy_writes_what_np_save_writes_and_returns_its_sha256(array, tmp_path) -> None:
    path = tmp_path / "a.npy"
    digest = write_npy(path, array)
    buf = io.BytesIO()
    np.save(buf, np.require(array, requirements="C"))
    assert path.read_bytes() == buf.getvalue() and digest == hashlib.sha256(buf.getvalue()).hexdigest()
    np.testing.assert_array_equal(np.load(path), array)
    assert [p.name for p in tmp_path.iterdir()] == ["a.npy"]


def test_a_cached_array_is_read_only_when_its_bytes_match_their_hash(tmp_path) -> None:
    path = tmp_path / "c.npy"
    data = np.linspace(0, 1, 21).reshape(3, 7)
    save_array(path, data)
    assert hash_path(path).read_text().strip() == hashlib.sha256(path.read_bytes()).hexdigest()
    np.testing.assert_array_equal(load_array(path, (3, 7)), data)
    assert load_array(path, (3, 8)) is None and load_array(path, (3, 7), np.float32) is None
    raw = bytearray(path.read_bytes())
    raw[-1] ^= 0x40  # one bit of the last number
    path.write_bytes(bytes(raw))
    with pytest.warns(RuntimeWarning, match="c.npy: its bytes do not match their sha256"):
        assert load_array(path, (3, 7)) is None
    hash_path(path).unlink()
    assert load_array(path, (3, 7)) is None  # no hash: regenerated, silently
    assert load_array(tmp_path / "missing.npy", (3, 7)) is None


def test_a_file_that_is_not_npy_is_a_value_error_naming_it(tmp_path) -> None:
    path = tmp_path / "x.npy"
    path.write_bytes(b"\x93NUMPY\x01\x00\x20\x00{'descr': '<f8', 'shape':[(4, 7), }   \n")
    with pytest.raises(ValueError, match="x.npy: not a .npy file"):
        read_npy(path)


def test_a_failed_write_names_the_file_and_keeps_its_errno(tmp_path) -> None:
    """Past the file size limit (ulimit -f; Python ignores SIGXFSZ) the write fails with EFBIG,
    which names the file asked for, not the temporary one, and leaves the old file in place
    (numpy's tofile would say "N requested and M written", without an errno)."""
    import resource

    path = tmp_path / "big.npy"
    path.write_bytes(b"old")
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, hard))
    try:
        with pytest.raises(OSError) as info:
            write_npy(path, np.zeros((100, 7)))
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert info.value.errno == errno.EFBIG and info.value.filename == str(path)
    assert path.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["big.npy"]
