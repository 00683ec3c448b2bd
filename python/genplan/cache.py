"""The on-disk cache of generated data sets (``$GENPLAN_CACHE``, default ``~/.cache/genplan``).

Arrays are ``.npy`` files (read with ``allow_pickle=False``), written atomically, each with the
sha256 of its bytes beside it (``<name>.npy.sha256``, written after the array); text files (the
self-collision pairs of :mod:`genplan.robots`) likewise (:func:`save_text`, :func:`load_text`).
A file that is missing, unreadable, without its hash, of another shape or dtype, or holding NaN
reads as absent, so the caller regenerates it; one whose bytes no longer match its hash (a flipped bit, a
file edited or replaced) reads as absent too, with a warning.
"""

from __future__ import annotations

import hashlib
import io
import os
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import DTypeLike, NDArray

from genplan._files import atomic_path, write_text

__all__ = ["cache_dir", "hash_path", "load_array", "load_text", "read_npy", "save_array", "save_text", "sha256_file",
           "write_npy"]


def cache_dir() -> Path:
    return Path(os.environ.get("GENPLAN_CACHE", Path.home() / ".cache" / "genplan"))


def hash_path(path: Path) -> Path:
    """Where the sha256 of the cached array ``path`` is kept."""
    path = Path(path)
    return path.with_name(path.name + ".sha256")


def _hash_matches(path: Path, data: bytes | None = None) -> bool:
    """Whether the cached file ``path`` (its bytes ``data`` when already read) matches the sha256
    kept beside it (:func:`hash_path`): False when either is missing or unreadable (written
    without its hash: regenerated), False with a RuntimeWarning naming the file when they differ."""
    try:
        expected = hash_path(path).read_text().strip()
        actual = sha256_file(path) if data is None else hashlib.sha256(data).hexdigest()
    except (OSError, UnicodeDecodeError):
        return False
    if actual != expected:
        warnings.warn(f"{path}: its bytes do not match their sha256 ({hash_path(path).name}): the file changed after "
                      "it was written; regenerating it", RuntimeWarning, stacklevel=3)
        return False
    return True


def load_array(path: Path, shape: tuple[int, ...], dtype: DTypeLike | None = None) -> NDArray | None:
    """The cached array at ``path`` if its bytes match their sha256 and it has ``shape`` (and
    ``dtype``) and is finite, else None (a RuntimeWarning when the bytes do not match)."""
    path = Path(path)
    if not _hash_matches(path):
        return None
    try:
        data = read_npy(path)
    except (OSError, ValueError):
        return None  # a broken cache file is regenerated
    if data.shape != shape or (dtype is not None and data.dtype != np.dtype(dtype)) or not np.all(np.isfinite(data)):
        return None
    return data


def load_text(path: Path) -> str | None:
    """The cached text file at ``path`` (UTF-8) if its bytes match their sha256, else None (a
    RuntimeWarning when the bytes do not match): what the caller reads from it, it still checks."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not _hash_matches(path, data):
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def save_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8), then its sha256 (:func:`hash_path`)."""
    path = Path(path)
    write_text(path, text)
    write_text(hash_path(path), hashlib.sha256(text.encode("utf-8")).hexdigest() + "\n")


def save_array(path: Path, data: NDArray) -> None:
    """Write ``data`` to ``path`` atomically (:func:`write_npy`), then its sha256
    (:func:`hash_path`)."""
    path = Path(path)
    digest = write_npy(path, data)
    write_text(hash_path(path), digest + "\n")


def write_npy(path: Path, data: NDArray) -> str:
    """Write ``data`` as a ``.npy`` file at ``path`` (the bytes ``np.save`` writes), atomically
    (:func:`genplan._files.atomic_path`); returns the file's sha256. Written with Python's file
    writes, not numpy's ``tofile``, whose failed writes carry no errno: a full disk, a quota or a
    file size limit is an OSError naming ``path``."""
    arr = np.require(data, requirements="C")
    if arr.dtype.hasobject:
        raise ValueError(f"{path}: an array of Python objects has no .npy form without pickle")
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, np.lib.format.header_data_from_array_1_0(arr))
    body = arr.reshape(-1).view(np.uint8).data  # the bytes in place, no copy
    digest = hashlib.sha256(head.getvalue())
    digest.update(body)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(head.getvalue())
        f.write(body)
    return digest.hexdigest()


def read_npy(path: Path) -> NDArray:
    """The array of the ``.npy`` file at ``path`` (``allow_pickle=False``); ValueError naming it
    when it is not one (numpy's header parser raises SyntaxError, tokenize.TokenError, EOFError,
    ... on a corrupt header), OSError when it cannot be read."""
    try:
        return np.load(path, allow_pickle=False)
    except OSError:
        raise
    except Exception as exc:  # noqa: BLE001 -- whatever numpy's parser raises on a corrupt file
        raise ValueError(f"{path}: not a .npy file ({type(exc).__name__}: {exc})") from None


def sha256_file(path: Path) -> str:
    """The sha256 of the file at ``path``, read in blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
