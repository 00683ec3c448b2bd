"""Input checks shared by the Python front ends: clear errors before anything runs."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.errors import GenplanError, NonFiniteError, ShapeError


def error_class(values: Any, shape_ok: bool) -> type[GenplanError]:
    """The class of a failed combined check: ShapeError if the shape is wrong, else NonFiniteError
    if ``values`` hold NaN or inf, else GenplanError (e.g. a box whose min exceeds its max)."""
    if not shape_ok:
        return ShapeError
    return GenplanError if np.all(np.isfinite(values)) else NonFiniteError


def as_configurations(q: Any, nq: int, what: str = "q") -> NDArray[np.float64]:
    """``q`` as a C-contiguous float64 array of shape (nq,) or (n, nq), finite.

    Raises :class:`~genplan.errors.ShapeError` (wrong shape, not numbers) or
    :class:`~genplan.errors.NonFiniteError` (the first non-finite element), naming ``what``.
    """
    try:
        arr = np.ascontiguousarray(q, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{what}: cannot be read as an array of floats ({exc})") from None
    if arr.ndim not in (1, 2) or arr.shape[-1] != nq:
        raise ShapeError(f"{what}: expected shape ({nq},) or (n, {nq}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise NonFiniteError(f"{what}: element {tuple(int(i) for i in bad)} is not finite ({arr[tuple(bad)]})")
    return arr


def as_box(value: Any, what: str = "box") -> NDArray[np.float64]:
    """``value`` as an axis-aligned box [[xmin, ymin, zmin], [xmax, ymax, zmax]]: shape (2, 3),
    finite, min <= max; else the :func:`error_class` of the failure."""
    b = np.asarray(value, dtype=np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[0] > b[1]):
        raise error_class(b, b.shape == (2, 3))(f"{what}: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]], got {b.tolist()}")
    return b
