"""The on-disk cache of generated data sets (``$GENPLAN_CACHE``, default ``~/.cache/genplan``).

Arrays are ``.npy`` files (read with ``allow_pickle=False``), written atomically; a file that is
missing, unreadable, of another shape or dtype, or holding NaN reads as absent, so the caller
regenerates it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import DTypeLike, NDArray

from genplan._files import atomic_path

__all__ = ["cache_dir", "load_array", "save_array"]


def cache_dir() -> Path:
    return Path(os.environ.get("GENPLAN_CACHE", Path.home() / ".cache" / "genplan"))


def load_array(path: Path, shape: tuple[int, ...], dtype: DTypeLike | None = None) -> NDArray | None:
    """The cached array at ``path`` if it has ``shape`` (and ``dtype``) and is finite, else None."""
    if not path.is_file():
        return None
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None  # a broken cache file is regenerated
    if data.shape != shape or (dtype is not None and data.dtype != np.dtype(dtype)) or not np.all(np.isfinite(data)):
        return None
    return data


def save_array(path: Path, data: NDArray) -> None:
    """Write ``data`` to ``path`` atomically (a temporary file beside it, then a rename)."""
    with atomic_path(path) as tmp:  # the suffix stays .npy: np.save adds none
        np.save(tmp, data)
