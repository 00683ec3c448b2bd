"""Spatula physics of the seq2seq paper (Section 4.1, eqs. 8-18) in torch, batched and
differentiable, with a float64 numpy twin that follows the equations literally.

State ``x = [y, z, theta, v_y, v_z, v_theta]`` (eq. 9), input ``u = [a_y, a_z, a_theta]``
(eq. 10), ``x[k+1] = A x[k] + B u[k]`` (eqs. 8, 11, 12) with ``dt = 1 ms``. A trajectory holds
``K`` samples ``x[0] ... x[K-1]``: ``x[0]`` is the initial state and ``u[k]`` is the acceleration
applied at sample ``k`` (so ``u[K-1]`` moves nothing but still counts in phi[K-1]).

The torch rollout is exact (no integration error against the recursion): positions are
``p[k] = p[0] + k dt v[0] + sum_{j<k} (k - j - 1/2) dt^2 u[j]``, evaluated as one matrix product
per batch, and the position variance of independent per-step acceleration noise
``var_u[j]`` is ``sum_{j<k} ((k - j - 1/2) dt^2)^2 var_u[j]`` (the diagonal of
``A S A^T + B diag(var_u) B^T`` propagated from ``S = 0``).

phi (eq. 16) and the cone (eq. 15) use the convention in :mod:`genplan.pancake.trajectories`.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from genplan._arrays import as_float_array, as_real
from genplan.errors import SettingsError, ShapeError
from genplan.pancake.config import D_SCALE
from genplan.pancake.trajectories import DT, G, K, MU_MAX
from genplan.pancake.trajectories import phi as phi_np
from genplan.seq2seq import plants
from genplan.seq2seq.plants import integrate, integrate_variance


__all__ = [
    "DT", "K", "G", "MU_MAX", "D_SCALE", "Rollout", "transition_matrices", "rollout", "rollout_variance",
    "phi", "f_dyn", "cone_limit", "simulate", "SpatulaPlant", "rollout_np", "rollout_variance_np", "phi_np", "f_dyn_np",
]


def cone_limit(mu_max: float = MU_MAX) -> float:
    """``arctan(mu_max)``: the largest admissible ``|phi|`` (eq. 15)."""
    return math.atan(mu_max)


def transition_matrices(dt: float = DT) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``A`` (6x6) and ``B`` (6x3) of eqs. 11-12."""
    dt = as_real(dt, "dt", error=SettingsError)
    if not (math.isfinite(dt) and dt > 0):
        raise SettingsError(f"dt must be positive, got {dt}")
    eye = np.eye(3)
    A = np.block([[eye, dt * eye], [np.zeros((3, 3)), eye]])
    B = np.vstack([0.5 * dt * dt * eye, dt * eye])
    return A, B


def _check_u(u: Tensor) -> None:
    if u.ndim != 3 or u.shape[-1] != 3:
        raise ShapeError(f"u must have shape (batch, K, 3) [a_y, a_z, a_theta], got {tuple(u.shape)}")


def rollout(u: Tensor, x0: Tensor | None = None, dt: float = DT) -> tuple[Tensor, Tensor]:
    """Positions and velocities ``(p, v)``, each (B, K, 3), of eq. 8 from ``x[0] = x0``.

    ``u``: (B, K, 3) accelerations; ``x0``: (B, 6) or (6,) initial states (default: rest at the
    origin). Exact, differentiable in ``u`` and ``x0`` (:func:`genplan.seq2seq.plants.integrate`).
    """
    _check_u(u)
    b = u.shape[0]
    if x0 is None:
        x0 = u.new_zeros(6)
    if x0.shape[-1] != 6 or x0.ndim > 2:
        raise ShapeError(f"x0 must have shape (6,) or (batch, 6), got {tuple(x0.shape)}")
    x0 = x0.to(u.dtype).expand(b, 6)
    return integrate(u, x0[:, :3], x0[:, 3:], dt)


def rollout_variance(var_u: Tensor, dt: float = DT) -> Tensor:
    """Position variances (B, K, 3) from independent per-step acceleration variances (B, K, 3)."""
    _check_u(var_u)
    return integrate_variance(var_u, dt)


def phi(theta: Tensor, u: Tensor, g: float = G) -> Tensor:
    """eq. 16 in torch: ``wrap(atan2(-g - a_z, -a_y) + pi/2 - theta)`` in (-pi, pi].

    ``theta`` has shape S and ``u`` S + (2,) or S + (3,). Differentiable everywhere except
    where the resultant vanishes and at the wrap point +-pi.
    """
    if u.shape[-1] not in (2, 3):
        raise ShapeError(f"u must have a last axis of 2 or 3, got shape {tuple(u.shape)}")
    a = torch.atan2(-g - u[..., 1], -u[..., 0]) + 0.5 * math.pi - theta
    return torch.atan2(torch.sin(a), torch.cos(a))


def f_dyn(phi_: Tensor, mu_max: float = MU_MAX, margin: float = 0.0) -> Tensor:
    """eq. 18: ``sum_k max(|phi[k]| - arctan(mu_max) + margin, 0)`` over the last axis.

    ``margin`` (radians, default 0 = the paper) tightens the cone for the penalty only.
    """
    return torch.relu(phi_.abs() - cone_limit(mu_max) + margin).sum(-1)


class Rollout(plants.Rollout):
    """A spatula trajectory and its inputs, batched: what the pancake's objectives see.

    ``p``, ``v``, ``u``: (B, K, 3) positions, velocities, accelerations; ``phi``: (B, K), the
    friction-cone angle (eq. 16); ``var_p``: (B, K, 3) position variances, or None when not
    modelled.
    """

    def __init__(self, p: Tensor, v: Tensor, u: Tensor, phi: Tensor, var_p: Tensor | None = None,
                 dt: float = DT) -> None:
        super().__init__(p=p, v=v, u=u, var_p=var_p, dt=dt)
        self.phi = phi


class SpatulaPlant(plants.Integrator):
    """The seq2seq plant of the pancake task: accelerations of the spatula's ``[y, z, theta]``
    rolled out by eq. 8, with phi (eq. 16) along the trajectory."""

    name = "spatula"

    def rollout(self, out: Tensor, var_out: Tensor | None, x0: Tensor) -> Rollout:
        p, v, var_p = self.states(out, var_out, x0)
        return Rollout(p=p, v=v, u=out, phi=phi(p[..., 2], out), var_p=var_p, dt=self.dt)

    @staticmethod
    def penalty(r: Rollout, margin: float) -> Tensor:
        """The training penalty (eq. 4's L2): f_dyn with the cone tightened by ``margin``."""
        return f_dyn(r.phi, margin=margin)


def simulate(u: Tensor, x0: Tensor | None = None, var_u: Tensor | None = None, dt: float = DT) -> Rollout:
    """Roll ``u`` out from ``x0`` and compute phi (and the position variance if ``var_u``)."""
    p, v = rollout(u, x0, dt)
    var_p = None if var_u is None else rollout_variance(var_u, dt)
    return Rollout(p=p, v=v, u=u, phi=phi(p[..., 2], u), var_p=var_p, dt=dt)


# ----------------------------------------------------------------------------- numpy twin


def rollout_np(u: ArrayLike, x0: ArrayLike | None = None, dt: float = DT) -> NDArray[np.float64]:
    """States (..., K, 6) by the literal recursion ``x[k+1] = A x[k] + B u[k]`` (float64)."""
    uu = as_float_array(u, "u")
    if uu.ndim < 2 or uu.shape[-1] != 3:
        raise ShapeError(f"u must have shape (..., K, 3), got {uu.shape}")
    A, B = transition_matrices(dt)
    lead, k = uu.shape[:-2], uu.shape[-2]
    x = np.zeros(lead + (k, 6))
    x[..., 0, :] = np.zeros(6) if x0 is None else as_float_array(x0, "x0")
    for i in range(k - 1):
        x[..., i + 1, :] = x[..., i, :] @ A.T + uu[..., i, :] @ B.T
    return x


def rollout_variance_np(var_u: ArrayLike, dt: float = DT) -> NDArray[np.float64]:
    """Position variances (K, 3) by the covariance recursion ``S' = A S A^T + B diag(var_u) B^T``."""
    vu = as_float_array(var_u, "var_u")
    if vu.ndim != 2 or vu.shape[-1] != 3:
        raise ShapeError(f"var_u must have shape (K, 3), got {vu.shape}")
    A, B = transition_matrices(dt)
    s = np.zeros((6, 6))
    out = np.zeros_like(vu)
    for i in range(len(vu) - 1):
        s = A @ s @ A.T + B @ np.diag(vu[i]) @ B.T
        out[i + 1] = np.diag(s)[:3]
    return out


def f_dyn_np(phi_: ArrayLike, mu_max: float = MU_MAX, margin: float = 0.0) -> NDArray[np.float64]:
    """eq. 18 in numpy, summed over the last axis."""
    return np.maximum(np.abs(as_float_array(phi_, "phi")) - math.atan(as_real(mu_max, "mu_max"))
                      + as_real(margin, "margin"), 0.0).sum(-1)
