"""genplan._arrays: the one reading of numeric arguments every public entry point shares (findings
PY-2 and PY-4 of tests/test_fuzz_inputs.py)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from genplan._arrays import as_box, as_configurations, as_count, as_float_array, as_real
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError


@pytest.mark.parametrize("value, expected", [
    ([1, 2], [1.0, 2.0]), (np.arange(3, dtype=np.int8), [0.0, 1.0, 2.0]), (np.array([True, False]), [1.0, 0.0]),
    (np.array([0.5], dtype=np.float16), [0.5]), (np.array([1.5, 2], dtype=object), [1.5, 2.0]),
    (["1.5", "2"], [1.5, 2.0]),  # numpy parses numeric strings; so does genplan
    (np.zeros((0, 3)), np.zeros((0, 3))),
])
def test_real_numbers_of_any_dtype_are_read_as_float64(value: Any, expected: Any) -> None:
    a = as_float_array(value, "x")
    assert a.dtype == np.float64 and np.array_equal(a, expected) and a.shape == np.shape(expected)


def test_a_float64_array_is_not_copied() -> None:
    a = np.zeros(4)
    assert as_float_array(a, "x") is a


@pytest.mark.parametrize("value", [
    "abc", ["a", "b"], [1, "x"], None, [None, 1.0], {"x": 1}, object(), [[1, 2], [3]],
], ids=["string", "strings", "mixed", "None", "None-in-list", "dict", "object", "ragged"])
def test_what_is_not_numbers_is_a_shape_error_naming_the_argument(value: Any) -> None:
    """Finding PY-2: numpy's plain ValueError ('could not convert string to float') or TypeError
    leaked; None was read as NaN."""
    with pytest.raises(ShapeError, match=r"^thing: cannot be read as an array of numbers"):
        as_float_array(value, "thing")
    with pytest.raises(ShapeError, match=r"^thing: cannot be read as a real number"):
        as_real(value, "thing")
    with pytest.raises(SettingsError, match=r"^thing: cannot be read"):
        as_real(value, "thing", error=SettingsError)


@pytest.mark.parametrize("value, dtype", [
    (np.zeros(3) + 1j, "complex128"), (np.zeros(3, dtype=np.complex64), "complex64"), ([1j, 2.0], "complex128"),
    (1 + 0j, "complex128"), (np.array([np.complex128(1), 2.0], dtype=object), "object"),
], ids=["complex128", "zero-imaginary", "list", "scalar", "object"])
def test_complex_numbers_are_refused_naming_the_dtype(value: Any, dtype: str) -> None:
    """Finding PY-4: numpy dropped the imaginary part with only a ComplexWarning."""
    with pytest.raises(ShapeError, match=rf"^thing: complex numbers .*{dtype}"):
        as_float_array(value, "thing")
    with pytest.raises(ShapeError, match=r"^q: complex numbers"):
        as_configurations(np.resize(np.asarray(value), 7), 7)


def test_as_real() -> None:
    assert as_real(2, "x") == 2.0 and as_real(np.float32(0.5), "x") == 0.5 and as_real("1e-3", "x") == 1e-3
    assert np.isnan(as_real(np.nan, "x"))  # the range is the caller's to check
    with pytest.raises(ShapeError, match=r"^x: expected one number, got an array of shape \(2,\)"):
        as_real([1.0, 2.0], "x")


@pytest.mark.parametrize("value, message", [
    (2.0, "must be an integer, got 2.0 (float)"), (True, "must be an integer, got True (bool)"),
    ("3", "must be an integer, got '3' (str)"), (None, "must be an integer"), (-1, "must be at least 0, got -1"),
    (11, "must be at most 10, got 11"),
])
def test_as_count(value: Any, message: str) -> None:
    assert as_count(3, "n", maximum=10) == 3 and as_count(np.int8(3), "n") == 3 and type(as_count(np.int64(3), "n")) is int
    with pytest.raises(SettingsError, match=rf"^n {message}".replace("(", r"\(").replace(")", r"\)")):
        as_count(value, "n", maximum=10)


def test_configurations_and_boxes() -> None:
    assert as_configurations([[0] * 7], 7).flags.c_contiguous
    with pytest.raises(ShapeError, match=r"^q0: expected shape \(7,\) or \(n, 7\), got \(3,\)"):
        as_configurations([0, 0, 0], 7, "q0")
    with pytest.raises(NonFiniteError, match=r"^q: element \(1,\) is not finite"):
        as_configurations([0, np.inf, 0, 0, 0, 0, 0], 7)
    assert as_box([[0, 0, 0], [1, 1, 1]]).shape == (2, 3)
    with pytest.raises(ShapeError, match="^box: cannot be read"):
        as_box("abc")
    with pytest.raises(GenplanError, match="^box: expected"):
        as_box([[1, 1, 1], [0, 0, 0]])
