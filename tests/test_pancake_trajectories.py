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
