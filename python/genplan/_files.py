"""Files written whole or not at all: a temporary name beside the target, then a rename (the
library's and the experiments' one definition of an atomic write); and the data files (robot,
task, scene: TOML; arrays: ``.npz``) read with errors that name the file."""

from __future__ import annotations

import errno
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = ["atomic_path", "read_npz", "read_toml", "write_text"]


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary name beside ``path`` (same suffix) to write to; renamed to ``path`` when the
    block ends without an error, removed otherwise. A reader never sees half a file, and a failed
    write leaves the old file in place. The folder is created if missing.

    Errors name ``path``, the file the caller asked for, never the temporary one: ``path`` being
    a folder is an IsADirectoryError before anything is written, and an OSError of the write
    (permission, read-only file system, disk full, quota), raised inside the block on the
    temporary file or by the rename, is re-raised with ``path`` as its file name (same errno,
    hence the same OSError subclass). Other errors of the block pass unchanged."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}-{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        if exc.errno is None or not (exc.filename is None or _is_temporary(exc.filename, tmp)):
            raise
        raise OSError(exc.errno, exc.strerror or os.strerror(exc.errno), str(path)) from None
    finally:
        tmp.unlink(missing_ok=True)


def _is_temporary(filename: Any, tmp: Path) -> bool:
    """``filename`` (an OSError's: str, bytes or path-like, relative or absolute, as the writer
    spelled it) names the temporary file ``tmp``: its name, unique to this write (process id and
    random hex), is ``tmp``'s."""
    try:
        return Path(os.fsdecode(filename)).name == tmp.name
    except TypeError:  # a file descriptor
        return False


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def read_toml(path: str | os.PathLike[str], kind: str, error: type[Exception]) -> dict[str, Any]:
    """A ``kind`` file (e.g. "task", "scene") as TOML data, its ``name`` defaulting to the file's
    stem: FileNotFoundError when it does not exist, ``error`` naming the file when it is not
    TOML (or not text)."""
    import tomllib

    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{kind} file {path} does not exist") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{kind} file {path}: {exc}") from None
    data.setdefault("name", path.stem)
    return data


def read_npz(path: str | os.PathLike[str], what: str = "file") -> dict[str, Any]:
    """Every array of the ``.npz`` file ``path``, read whole (no pickles): the one reader of the
    ``.npz`` files a user gives (trajectories, inputs, targets, recordings). FileNotFoundError
    when it does not exist; :class:`~genplan.errors.DataFileError` naming ``what`` and ``path``
    when it cannot be read: not a zip file, a member failing its CRC (one flipped bit), truncated,
    a member that is no array (or a pickle), an array too large to allocate, a folder, no
    permission."""
    import zipfile
    import zlib

    import numpy as np

    from genplan.errors import DataFileError

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} {path} does not exist")
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError("a single .npy array, not an .npz file of named arrays")
        with z:
            return {k: np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, MemoryError, zipfile.BadZipFile, zlib.error) as exc:
        reason = " ".join((str(exc) or type(exc).__name__).split())
        raise DataFileError(f"{what} {path}: not a readable .npz file ({type(exc).__name__}: {reason})") from None


def missing_folders(path: str | os.PathLike[str]) -> list[Path]:
    """The folders of ``path`` (itself included) that do not exist, deepest first: those a
    ``mkdir(parents=True)`` of it creates."""
    missing = []
    folder = Path(path).absolute()
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def remove_empty_folders(folders: list[Path]) -> None:
    """Remove each of ``folders`` (deepest first) that is empty, keep the others: the folders a
    run that failed created (:func:`missing_folders`), when it left nothing in them."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            pass
