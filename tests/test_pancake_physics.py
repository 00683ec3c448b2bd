"""genplan.pancake.physics: the torch physics against its literal numpy twin, and gradients."""

import math

import numpy as np
import pytest
import torch

from genplan.errors import ShapeError
from genplan.pancake import physics as ph
from genplan.pancake.trajectories import phi as phi_np


def _random(b: int, k: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.normal(scale=[8.0, 8.0, 40.0], size=(b, k, 3))
    x0 = np.concatenate([rng.uniform(-0.1, 0.1, (b, 3)), rng.normal(scale=0.5, size=(b, 3))], 1)
    return u, x0


def test_transition_matrices_are_eqs_11_12() -> None:
    A, B = ph.transition_matrices(1e-3)
    assert A.shape == (6, 6) and B.shape == (6, 3)
    np.testing.assert_array_equal(A[:3, 3:], 1e-3 * np.eye(3))
    np.testing.assert_array_equal(B[:3], 0.5e-6 * np.eye(3))
    np.testing.assert_array_equal(B[3:], 1e-3 * np.eye(3))


def test_torch_rollout_matches_the_literal_recursion() -> None:
    u, x0 = _random(4, ph.K, 1)
    x = np.stack([ph.rollout_np(u[i], x0[i]) for i in range(4)])
    p, v = ph.rollout(torch.tensor(u), torch.tensor(x0))
    np.testing.assert_allclose(p.numpy(), x[..., :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v.numpy(), x[..., 3:], rtol=0, atol=1e-10)
    # float32 (what the model uses) stays within 1e-6 m over the K = 500 samples
    p32, _ = ph.rollout(torch.tensor(u, dtype=torch.float32), torch.tensor(x0, dtype=torch.float32))
    assert np.abs(p32.double().numpy() - x[..., :3]).max() < 2e-6
    # default start: rest at the origin
    p0, v0 = ph.rollout(torch.tensor(u[:1]))
    np.testing.assert_allclose(p0[0].numpy(), ph.rollout_np(u[0])[:, :3], atol=1e-12)


def test_variance_propagation_matches_the_covariance_recursion() -> None:
    rng = np.random.default_rng(2)
    var_u = rng.uniform(0.1, 4.0, size=(ph.K, 3))
    ref = ph.rollout_variance_np(var_u)
    got = ph.rollout_variance(torch.tensor(var_u)[None])[0].numpy()
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-20)
    assert got[0].max() == 0.0 and np.all(np.diff(got, axis=0) >= 0)


def test_phi_and_f_dyn_match_the_native_definition() -> None:
    """The torch twin (differentiable) against the one definition of eq. 16, the 1 kHz loop's (Rust)."""
    u, x0 = _random(3, 200, 3)
    x = np.stack([ph.rollout_np(u[i], x0[i]) for i in range(3)])
    th = x[..., 2] * 20  # many turns: exercise the wrap
    t = ph.phi(torch.tensor(th), torch.tensor(u)).numpy()
    n = phi_np(th, u)
    # the same angle (the two wraps may disagree only exactly at +-pi)
    np.testing.assert_allclose(np.cos(t), np.cos(n), atol=1e-12)
    np.testing.assert_allclose(np.sin(t), np.sin(n), atol=1e-12)
    np.testing.assert_allclose(t, n, atol=1e-9)
    fd = ph.f_dyn(torch.tensor(n)).numpy()
    np.testing.assert_allclose(fd, ph.f_dyn_np(n), rtol=1e-12)
    assert np.all(fd > 0)
    expected = np.maximum(np.abs(n) - math.atan(1.0), 0).sum(-1)
    np.testing.assert_allclose(ph.f_dyn_np(n), expected)
    # the margin tightens the cone
    assert np.all(ph.f_dyn_np(n, margin=0.1) > ph.f_dyn_np(n))
    r = ph.simulate(torch.tensor(u), torch.tensor(x0))
    np.testing.assert_allclose(r.phi.numpy(), phi_np(x[..., 2], u), atol=1e-9)


def test_gradients_are_exact() -> None:
    u, x0 = _random(2, 12, 4)
    ut = torch.tensor(u, requires_grad=True)
    xt = torch.tensor(x0, requires_grad=True)

    def f(u_: torch.Tensor, x_: torch.Tensor) -> torch.Tensor:
        r = ph.simulate(u_, x_, var_u=u_ ** 2)
        return (r.p ** 2).sum() + r.v.sum() + torch.cos(r.phi).sum() + r.var_p.sum()

    assert torch.autograd.gradcheck(f, (ut, xt))


def test_shape_errors_are_clear() -> None:
    with pytest.raises(ShapeError, match=r"u must have shape \(batch, K, 3\)"):
        ph.rollout(torch.zeros(10, 3))
    with pytest.raises(ShapeError, match="x0 must have shape"):
        ph.rollout(torch.zeros(1, 10, 3), torch.zeros(5))
    with pytest.raises(ShapeError, match="u must have shape"):
        ph.rollout_np(np.zeros(10))
    with pytest.raises(ShapeError, match="var_u must have shape"):
        ph.rollout_variance_np(np.zeros((10, 2)))
    with pytest.raises(ShapeError, match="last axis of 2 or 3"):
        ph.phi(torch.zeros(3), torch.zeros(3, 4))
