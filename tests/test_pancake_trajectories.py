"""genplan.pancake.trajectories: S-curves, constant-velocity lines, the J1 problems, and phi's sign
convention."""

import math
import sys

import numpy as np
import pytest

from genplan.errors import NonFiniteError, SettingsError, ShapeError
from genplan.pancake.trajectories import DT, G, K, j1_problems, linear, phi, s_curve, s_curve_profile, wrap_angle


def test_importing_the_package_does_not_import_torch() -> None:
    import subprocess

    code = "import sys, genplan.pancake, genplan.pancake.trajectories; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_s_curve_starts_and_stops_at_rest_exactly_at_the_poses() -> None:
    a, b = np.array([0.01, -0.02, 0.1]), np.array([0.1, -0.1, -math.pi])
    x = s_curve(a, b)
    assert x.shape == (K, 3) and x.dtype == np.float64
    np.testing.assert_array_equal(x[0], a)
    np.testing.assert_array_equal(x[-1], b)
    v = np.diff(x, axis=0) / DT
    acc = np.diff(v, axis=0) / DT
    peak_v = np.abs(v).max(0)
    # smooth start and stop: velocity and acceleration vanish at both ends
    assert np.all(np.abs(v[0]) < 1e-4 * peak_v) and np.all(np.abs(v[-1]) < 1e-4 * peak_v)
    assert np.all(np.abs(acc[0]) < 0.02 * np.abs(acc).max(0)) and np.all(np.abs(acc[-1]) < 0.02 * np.abs(acc).max(0))
    # monotone, peak speed at mid-move: 2 x the average (cycloidal profile)
    d = np.sign(b - a)
    assert np.all(np.diff(x, axis=0) * d >= -1e-15)
    np.testing.assert_allclose(peak_v, 2 * np.abs(b - a) / ((K - 1) * DT), rtol=1e-4)
    s, ds, d2s = s_curve_profile(K)
    np.testing.assert_allclose(np.gradient(s, 1 / (K - 1)), ds, atol=1e-4)
    np.testing.assert_allclose(np.gradient(ds, 1 / (K - 1))[1:-1], d2s[1:-1], atol=1e-3)


def test_s_curve_and_linear_reject_bad_poses() -> None:
    with pytest.raises(ShapeError, match=r"p_end must be a pose .* shape \(3,\)"):
        s_curve(np.zeros(3), np.zeros(2))
    with pytest.raises(NonFiniteError, match="p_start must be finite"):
        s_curve([0.0, np.nan, 0.0], np.zeros(3))
    with pytest.raises(SettingsError, match="K must be at least 2"):
        s_curve(np.zeros(3), np.ones(3), K=1)
    with pytest.raises(SettingsError, match="dt must be positive"):
        s_curve(np.zeros(3), np.ones(3), dt=0.0)
    with pytest.raises(NonFiniteError, match="p_end"):
        linear(np.zeros(3), [1.0, np.inf, 0.0])


def test_linear_has_constant_velocity() -> None:
    x = linear(np.zeros(3), [0.0, 0.0, -0.75 * math.pi])
    v = np.diff(x, axis=0) / DT
    np.testing.assert_allclose(v, v[0][None].repeat(K - 1, 0), atol=1e-9)
    np.testing.assert_allclose(x[-1], [0, 0, -0.75 * math.pi])


def test_phi_sign_convention_of_design_md() -> None:
    # level spatula at rest: phi = 0
    assert phi(0.0, [0.0, 0.0]) == 0.0
    assert phi(0.0, [0.0, 0.0, 5.0]) == 0.0  # a_theta does not enter eq. 16
    # tilt theta at rest: |phi| = |theta| (phi = -theta)
    th = np.linspace(-3.0, 3.0, 61)
    p = phi(th, np.zeros((61, 2)))
    np.testing.assert_allclose(np.abs(p), np.abs(th), atol=1e-12)
    np.testing.assert_allclose(p, -th, atol=1e-12)
    # a level spatula accelerating sideways at mu g = g puts the pancake exactly on the cone edge
    np.testing.assert_allclose(np.abs(phi(0.0, [G, 0.0])), math.pi / 4, atol=1e-12)
    np.testing.assert_allclose(np.abs(phi(0.0, [-G, 0.0])), math.pi / 4, atol=1e-12)
    # accelerating along +y, tilting by -atan(a / g) (clockwise) keeps the resultant on the normal
    a = 3.0
    assert abs(phi(-math.atan2(a, G), [a, 0.0])) < 1e-12
    assert abs(phi(math.atan2(a, G), [a, 0.0])) > 0.5
    # accelerating upwards does not change the angle
    assert abs(phi(0.0, [0.0, 20.0])) < 1e-12
    # upside down (theta = pi) and pushed down faster than g: the pancake stays (phi = 0)
    assert abs(phi(math.pi, [0.0, -2 * G])) < 1e-12
    # upside down at rest: the pancake falls (|phi| = pi)
    assert abs(abs(phi(math.pi, [0.0, 0.0])) - math.pi) < 1e-12


def test_phi_is_vectorised_and_wrapped() -> None:
    rng = np.random.default_rng(0)
    th = rng.uniform(-10, 10, size=(4, 5))
    acc = rng.normal(scale=20, size=(4, 5, 3))
    p = phi(th, acc)
    assert p.shape == (4, 5)
    assert np.all(p > -math.pi) and np.all(p <= math.pi)
    np.testing.assert_allclose(p, phi(th, acc[..., :2]))
    # the definition, element by element
    ref = np.array([[math.atan2(-G - acc[i, j, 1], -acc[i, j, 0]) + math.pi / 2 - th[i, j]
                     for j in range(5)] for i in range(4)])
    np.testing.assert_allclose(np.cos(p), np.cos(ref), atol=1e-12)
    np.testing.assert_allclose(np.sin(p), np.sin(ref), atol=1e-12)
    with pytest.raises(ShapeError, match="last axis of 2"):
        phi(0.0, np.zeros(4))
    assert wrap_angle(-math.pi) == math.pi and wrap_angle(math.pi) == math.pi


def test_the_papers_j1_problems() -> None:
    x_in, p_end = j1_problems()
    assert x_in.shape == (27, 500, 3) and p_end.shape == (27, 3)
    assert len({tuple(p) for p in p_end}) == 27
    np.testing.assert_allclose(np.unique(p_end[:, 0]), [-0.1, 0, 0.1])
    np.testing.assert_allclose(np.unique(p_end[:, 2]), [-math.pi, 0, math.pi])
    np.testing.assert_allclose(x_in[:, 0], 0.0)
    np.testing.assert_allclose(x_in[:, -1], p_end)


# ---------------------------------------------------------------------------------------------
# inputs (findings PY-2, PY-4, PY-6, PY-7, PY-9 of tests/test_fuzz_inputs.py)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("f", [s_curve, linear])
def test_the_last_sample_is_p_end_exactly(f) -> None:
    """PY-9: p_start + 1 * (p_end - p_start) rounds when |p_end| << |p_start|."""
    for b in ([1e-20, 0.0, 0.0], [2.2250738585e-313, -1e-300, 0.1]):
        x = f([1.0, 1.0, 1.0], b, 5)
        assert np.array_equal(x[-1], b) and np.array_equal(x[0], [1.0, 1.0, 1.0])


@pytest.mark.parametrize("f", [s_curve, linear])
def test_far_poses_do_not_overflow(f) -> None:
    """PY-6: from y = -1e308 to 1e308 the difference overflows; the move stays finite and between
    the poses, with the same shape as a near move scaled up."""
    big = np.finfo(np.float64).max
    x = f([-1e308, -big, big], [1e308, big, 0.9 * big], K)
    assert np.all(np.isfinite(x)) and np.array_equal(x[0], [-1e308, -big, big])
    assert np.array_equal(x[-1], [1e308, big, 0.9 * big])
    assert np.all(np.diff(x[:, :2], axis=0) >= 0) and np.all(np.diff(x[:, 2]) <= 0)
    near = f([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], K)
    np.testing.assert_allclose(x[:, 0] / 1e308, near[:, 0], rtol=1e-12, atol=1e-15)
    # near moves are unchanged by the far-pose path: a + s (b - a)
    a, b = np.array([0.01, -0.02, 0.1]), np.array([0.1, -0.1, -math.pi])
    s_, _, _ = s_curve_profile(K)
    np.testing.assert_array_equal(s_curve(a, b)[:-1], (a + s_[:, None] * (b - a))[:-1])


@pytest.mark.parametrize("bad, error, match", [
    ({"p_start": "abc"}, ShapeError, "^p_start: cannot be read"),
    ({"p_end": np.zeros(3) + 1j}, ShapeError, "^p_end: complex numbers"),
    ({"K": 2.0}, SettingsError, "^K must be an integer, got 2.0"),
    ({"K": "500"}, SettingsError, "^K must be an integer"),
    ({"K": 10**9}, SettingsError, "^K must be at most 10000000"),
    ({"dt": "x"}, SettingsError, "^dt: cannot be read"),
])
def test_bad_arguments_name_themselves(bad, error, match) -> None:
    """PY-2 / PY-4: strings and complex numbers leaked numpy's ValueError or lost their imaginary
    part; a float or huge K went to numpy as it was."""
    kwargs = {"p_start": np.zeros(3), "p_end": np.ones(3), **bad}
    with pytest.raises(error, match=match):
        s_curve(**kwargs)
    if "dt" not in bad:
        with pytest.raises(error, match=match):
            linear(**kwargs)


@pytest.mark.parametrize("theta, acc, g, error, match", [
    ([np.nan, 0.0], np.zeros((2, 2)), G, NonFiniteError, r"^theta: element \(0,\) is not finite"),
    (0.0, [[0.0, 0.0], [np.inf, 0.0]], G, NonFiniteError, r"^acc: element \(1, 0\) is not finite"),
    (0.0, [0.0, 0.0], np.nan, NonFiniteError, "^g must be finite"),
    (np.zeros(3), np.zeros((2, 2)), G, ShapeError, r"^theta of shape \(3,\) and acc of shape \(2, 2\) do not broadcast"),
    ("x", [0.0, 0.0], G, ShapeError, "^theta: cannot be read"),
    (0.0, ["a", "b"], G, ShapeError, "^acc: cannot be read"),
    (0.0, [0.0, 0.0], "g", ShapeError, "^g: cannot be read"),
    (1j, [0.0, 0.0], G, ShapeError, "^theta: complex numbers"),
])
def test_phi_refuses_what_it_cannot_compute(theta, acc, g, error, match) -> None:
    """PY-7: NaN in came out as NaN without an error; shapes that do not broadcast raised numpy's
    plain ValueError."""
    with pytest.raises(error, match=match):
        phi(theta, acc, g)


def test_phi_ignores_a_theta_and_takes_empty_batches() -> None:
    assert phi(0.0, [0.0, 0.0, np.nan]) == 0.0  # a_theta does not enter eq. 16
    assert phi(np.zeros(0), np.zeros((0, 3))).shape == (0,)
    assert phi(0.0, np.zeros((2, 0, 2))).shape == (2, 0)
