"""Input checks shared by the Python front ends: clear errors before anything runs.

Every public entry point reads its numeric arguments through the helpers here, so that a
caller's bad input gets one answer whichever function it was passed to:

* :func:`as_float_array` -- anything array-like as float64. A value that cannot be read as real
  numbers (a string that does not parse, ``None``, an object, a ragged list) or that holds
  complex numbers (numpy would drop the imaginary part with only a ``ComplexWarning``) raises
  :class:`~genplan.errors.ShapeError` (or the class the caller asks for) naming the argument;
* :func:`as_real` -- one real number, the same way;
* :func:`as_count` -- a whole number (an ``int`` or a numpy integer, not a bool) within bounds,
  else :class:`~genplan.errors.SettingsError` naming the argument;
* :func:`as_configurations`, :func:`as_box` -- the shapes genplan's configurations and boxes
  take, on top of :func:`as_float_array`.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError


def error_class(values: Any, shape_ok: bool) -> type[GenplanError]:
    """The class of a failed combined check: ShapeError if the shape is wrong, else NonFiniteError
    if ``values`` hold NaN or inf, else GenplanError (e.g. a box whose min exceeds its max)."""
    if not shape_ok:
        return ShapeError
    return GenplanError if np.all(np.isfinite(values)) else NonFiniteError


def _brief(value: Any) -> str:
    """A short description of a caller's value for an error message."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:57]}..."


def as_float_array(value: Any, what: str, *, error: type[GenplanError] = ShapeError) -> NDArray[np.float64]:
    """``value`` as a float64 array of any shape (no copy when it already is one).

    Real numbers of any numpy dtype (ints, bools, float16/32, objects holding real numbers) and
    nested lists of them are read as numpy reads them, strings that parse as numbers included.
    Refused with ``error`` (default :class:`~genplan.errors.ShapeError`) naming ``what``: a
    value that is not readable as real numbers (``None``, which numpy would read as NaN, a
    string that does not parse, a dict, a ragged list) and complex numbers, even with a zero imaginary part (the dtype is named).
    No check of shape or finiteness: that is the caller's.
    """
    return _read(value, what, error, "an array of numbers")


def _read(value: Any, what: str, error: type[GenplanError], noun: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise error(f"{what}: cannot be read as {noun} ({exc})") from None
    if arr.dtype.kind == "c":
        raise error(f"{what}: complex numbers (dtype {arr.dtype}) are not accepted; pass real numbers "
                    "(e.g. the real part, .real, if that is what is meant)")
    if arr.dtype == np.float64:
        return arr
    if arr.dtype == object and any(v is None for v in arr.flat):
        # numpy would read None as NaN
        raise error(f"{what}: cannot be read as {noun} (got {_brief(arr)}: None is not a number)")
    try:
        with warnings.catch_warnings():
            # an object array holding numpy complex scalars: numpy would drop the imaginary part
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            return arr.astype(np.float64)
    except np.exceptions.ComplexWarning:
        raise error(f"{what}: complex numbers (in an array of dtype {arr.dtype}) are not accepted") from None
    except (TypeError, ValueError) as exc:
        raise error(f"{what}: cannot be read as {noun} (got {_brief(arr)}: {exc})") from None


def as_real(value: Any, what: str, *, error: type[GenplanError] = ShapeError) -> float:
    """``value`` as one real number (a Python or numpy number, a 0-d array, a numeric string);
    else ``error`` naming ``what`` (see :func:`as_float_array`). NaN and inf pass: the caller
    checks the range."""
    arr = _read(value, what, error, "a real number")
    if arr.ndim != 0:
        raise error(f"{what}: expected one number, got an array of shape {arr.shape}")
    return float(arr)


def as_count(value: Any, what: str, *, minimum: int = 0, maximum: int | None = None) -> int:
    """``value`` as a whole number in ``[minimum, maximum]``: an ``int`` or a numpy integer (not a
    bool, not a float such as 2.0); else :class:`~genplan.errors.SettingsError` naming ``what``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise SettingsError(f"{what} must be an integer, got {_brief(value)} ({type(value).__name__})")
    n = int(value)
    if n < minimum:
        raise SettingsError(f"{what} must be at least {minimum}, got {n}")
    if maximum is not None and n > maximum:
        raise SettingsError(f"{what} must be at most {maximum}, got {n}")
    return n


def as_configurations(q: Any, nq: int, what: str = "q") -> NDArray[np.float64]:
    """``q`` as a C-contiguous float64 array of shape (nq,) or (n, nq), finite.

    Raises :class:`~genplan.errors.ShapeError` (wrong shape, not real numbers, complex) or
    :class:`~genplan.errors.NonFiniteError` (the first non-finite element), naming ``what``.
    """
    arr = np.ascontiguousarray(as_float_array(q, what))
    if arr.ndim not in (1, 2) or arr.shape[-1] != nq:
        raise ShapeError(f"{what}: expected shape ({nq},) or (n, {nq}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise NonFiniteError(f"{what}: element {tuple(int(i) for i in bad)} is not finite ({arr[tuple(bad)]})")
    return arr


def as_box(value: Any, what: str = "box") -> NDArray[np.float64]:
    """``value`` as an axis-aligned box [[xmin, ymin, zmin], [xmax, ymax, zmax]]: shape (2, 3),
    finite, min <= max; else the :func:`error_class` of the failure."""
    b = as_float_array(value, what)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[0] > b[1]):
        raise error_class(b, b.shape == (2, 3))(f"{what}: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]], got {b.tolist()}")
    return b
