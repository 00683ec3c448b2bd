"""genplan._files: files written whole or not at all, and write errors that name the path the
caller gave, never the temporary name the write went through."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from genplan._files import atomic_path, write_text


def test_a_write_replaces_the_file_whole(tmp_path) -> None:
    path = tmp_path / "sub" / "a.txt"
    write_text(path, "one")
    write_text(path, "two")
    assert path.read_text() == "two" and sorted(p.name for p in path.parent.iterdir()) == ["a.txt"]


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path) -> None:
    path = tmp_path / "a.txt"
    path.write_text("old")
    with pytest.raises(RuntimeError, match="cut short"):
        with atomic_path(path) as tmp:
            tmp.write_text("half")
            raise RuntimeError("cut short")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_integrity_8_writing_over_a_folder_names_the_folder_not_a_temporary(tmp_path) -> None:
    """Before: os.replace's error named '.x.PID-hex.tmp.npz' (and the folder second)."""
    folder = tmp_path / "x.npz"
    folder.mkdir()
    for write in (lambda: write_text(folder, "a"), lambda: _save_npz(folder)):
        with pytest.raises(IsADirectoryError) as info:
            write()
        assert info.value.filename == str(folder) and ".tmp" not in str(info.value), str(info.value)
        assert "is a folder" in str(info.value)
    assert [p.name for p in tmp_path.iterdir()] == ["x.npz"] and not list(folder.iterdir())


def _save_npz(path: Path) -> None:
    with atomic_path(path) as tmp:
        np.savez(tmp, a=np.zeros(2))


def test_integrity_8_an_unwritable_place_names_the_path_given(tmp_path) -> None:
    """/proc takes no new files, even from root: the error names /proc/x.json, not the
    temporary '/proc/.x.PID-hex.tmp.json'."""
    with pytest.raises(OSError) as info:
        write_text("/proc/genplan-x.json", "a")
    assert info.value.filename == "/proc/genplan-x.json" and ".tmp" not in str(info.value), str(info.value)


def test_integrity_8_a_full_disk_names_the_path_given(tmp_path) -> None:
    """An error while writing the temporary file (no file name of its own, as ENOSPC from a write
    has none, or the temporary's) is reported on the path given, with its errno kept."""
    path = tmp_path / "m.bin"
    path.write_text("old")
    for exc in (OSError(errno.ENOSPC, "No space left on device"),
                OSError(errno.EDQUOT, "Disk quota exceeded", "ignored: replaced below")):
        with pytest.raises(OSError) as info:
            with atomic_path(path) as tmp:
                tmp.write_text("partial")
                if exc.filename is not None:
                    exc.filename = str(tmp)
                raise exc
        assert info.value.errno == exc.errno and info.value.filename == str(path), str(info.value)
        assert ".tmp" not in str(info.value)
        assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["m.bin"]


def test_an_error_about_another_file_is_left_as_it_is(tmp_path) -> None:
    """Only errors on the write itself are renamed: a missing input read inside the block keeps
    its own file name."""
    with pytest.raises(FileNotFoundError) as info:
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text((tmp_path / "missing-input.txt").read_text())
    assert info.value.filename == str(tmp_path / "missing-input.txt")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("spelling", ["absolute", "bytes", "resolved"])
def test_integrity_rerun_messages_name_the_path_given(tmp_path, monkeypatch, spelling) -> None:
    """An OSError on the temporary file, however the writer spelled its name (absolute, bytes,
    the folder's symlinks resolved), is reported on the path the caller gave; and every writer of
    trajectories and models, on a place that takes no file (/proc, even for root), names the path
    given."""
    from genplan.trajectory import Trajectory

    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    monkeypatch.chdir(tmp_path)
    path = Path("link") / "t.npz"
    with pytest.raises(OSError) as info:
        with atomic_path(path) as tmp:
            name = {"absolute": str(tmp.absolute()), "bytes": os.fsencode(tmp),
                    "resolved": str(tmp.parent.resolve() / tmp.name)}[spelling]
            raise PermissionError(errno.EACCES, "Permission denied", name)
    assert isinstance(info.value, PermissionError) and info.value.filename == str(path), str(info.value)
    assert ".tmp" not in str(info.value) and not list(real.iterdir())

    z = np.zeros((2, 2))
    traj = Trajectory(t=np.array([0.0, 1.0]), q=z, qd=z, qdd=z, joint_names=("a", "b"), rate_hz=1.0)
    for suffix in (".npz", ".csv", ".json"):
        with pytest.raises(OSError) as info:
            traj.save(f"/proc/genplan-t{suffix}")
        assert info.value.filename == f"/proc/genplan-t{suffix}" and ".tmp" not in str(info.value), str(info.value)
