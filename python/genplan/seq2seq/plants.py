"""Plants: how a seq2seq decoder's output becomes a trajectory (the paper's "physics model",
Section 2.2: the decoder emits control inputs U_out, the plant turns them into X_out).

* ``"position"`` -- the output is the trajectory's displacement from its start:
  ``p[k] = x0 + u[k] - u[0]`` (so every decoded trajectory starts where its input does). The
  family a planner or a recording gives (a robot's joint positions in normalised time).
* ``"integrator"`` -- the output is accelerations, rolled out exactly (eq. 8, any dimension)
  from the start at rest every ``dt`` seconds; the position variance follows from independent
  per-sample acceleration noise.
* ``"spatula"`` -- the integrator in the spatula's ``[y, z, theta]`` plus the pancake's
  friction-cone angle phi (:mod:`genplan.pancake.physics` defines it and declares it:
  :mod:`genplan.seq2seq.plugins`).

Every plant returns a :class:`Rollout`, what objectives see.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import torch
from torch import Tensor

from genplan.errors import ShapeError, UnknownNameError

__all__ = ["Rollout", "Plant", "PLANTS", "PositionPlant", "Integrator", "plant", "integrate", "integrate_variance"]


@dataclass(eq=False)
class Rollout:
    """Decoded trajectories, batched: what objectives see.

    ``p``: (B, K, d) positions; ``v``: (B, K, d) velocities (per second at the plant's ``dt``:
    exact for the integrator, forward differences for the position plant); ``u``: (B, K, d) the
    decoder's output in the plant's units (accelerations, or displacements); ``var_p``: (B, K, d)
    position variances, or None when not modelled; ``dt``: seconds between samples.
    """

    p: Tensor
    v: Tensor
    u: Tensor
    var_p: Tensor | None = None
    dt: float = 1e-3

    @property
    def batch(self) -> int:
        return int(self.p.shape[0])


class Plant(Protocol):
    """What a plant does: ``rollout(out, var_out, x0)`` -> :class:`Rollout` from the decoder's
    output (B, K, d), its variances (or None) and the start positions (B, d)."""

    name: str

    def rollout(self, out: Tensor, var_out: Tensor | None, x0: Tensor) -> Rollout: ...


@lru_cache(maxsize=16)
def _kernels(k: int, dt: float, dtype: torch.dtype, device: str) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    idx = torch.arange(k, dtype=torch.float64)
    diff = idx[:, None] - idx[None, :]  # k - j
    lower = diff > 0
    mp = torch.where(lower, (diff - 0.5) * dt * dt, torch.zeros(()))
    mv = torch.where(lower, torch.full_like(diff, dt), torch.zeros(()))
    t = idx * dt
    return (mp.to(dtype=dtype, device=device), mv.to(dtype=dtype, device=device),
            (mp * mp).to(dtype=dtype, device=device), t.to(dtype=dtype, device=device))


def _lower_apply(m: Tensor, u: Tensor) -> Tensor:
    """``m @ u[b]`` for every batch element, as one matrix product: (K, K) x (B, K, C)."""
    b, k, c = u.shape
    out = torch.mm(m, u.transpose(0, 1).reshape(k, b * c))
    return out.reshape(k, b, c).transpose(0, 1)


def integrate(u: Tensor, p0: Tensor, v0: Tensor, dt: float) -> tuple[Tensor, Tensor]:
    """Positions and velocities (B, K, d) of ``x[k+1] = A x[k] + B u[k]`` (eq. 8 in d dimensions)
    from ``p0``, ``v0`` (B, d), exactly: ``p[k] = p0 + k dt v0 + sum_{j<k} (k - j - 1/2) dt^2 u[j]``,
    one matrix product per batch. Differentiable in ``u``, ``p0`` and ``v0``."""
    if u.ndim != 3:
        raise ShapeError(f"u must have shape (batch, K, d), got {tuple(u.shape)}")
    mp, mv, _, t = _kernels(u.shape[1], float(dt), u.dtype, str(u.device))
    p = p0[:, None, :] + t[None, :, None] * v0[:, None, :] + _lower_apply(mp, u)
    v = v0[:, None, :] + _lower_apply(mv, u)
    return p, v


def integrate_variance(var_u: Tensor, dt: float) -> Tensor:
    """Position variances (B, K, d) from independent per-sample acceleration variances (B, K, d)
    (the diagonal of ``A S A^T + B diag(var_u) B^T`` propagated from ``S = 0``)."""
    if var_u.ndim != 3:
        raise ShapeError(f"var_u must have shape (batch, K, d), got {tuple(var_u.shape)}")
    _, _, mp2, _ = _kernels(var_u.shape[1], float(dt), var_u.dtype, str(var_u.device))
    return _lower_apply(mp2, var_u)


class PositionPlant:
    """The output is the displacement from the start: ``p[k] = x0 + u[k] - u[0]``; velocities
    are forward differences over ``dt`` (the last repeats the one before)."""

    name = "position"

    def __init__(self, dt: float) -> None:
        self.dt = float(dt)

    def inputs(self, x: Tensor, x0: Tensor) -> Tensor:
        """The output that gives the trajectories ``x`` (B, K, d) from ``x0``: their displacements."""
        return x - x0[:, None, :]

    def rollout(self, out: Tensor, var_out: Tensor | None, x0: Tensor) -> Rollout:
        p = x0[:, None, :] + (out - out[:, :1, :])
        dp = (p[:, 1:] - p[:, :-1]) / self.dt
        v = torch.cat([dp, dp[:, -1:]], 1)
        return Rollout(p=p, v=v, u=out, var_p=var_out, dt=self.dt)


class Integrator:
    """The output is accelerations, rolled out exactly (eq. 8) from the start (at rest unless a
    start velocity is given)."""

    name = "integrator"

    def __init__(self, dt: float) -> None:
        self.dt = float(dt)

    def states(self, out: Tensor, var_out: Tensor | None, x0: Tensor) -> tuple[Tensor, Tensor, Tensor | None]:
        """Positions, velocities and position variances from start positions (B, d), at rest, or
        start states (B, 2d): positions and velocities."""
        d = out.shape[-1]
        if x0.shape[-1] == 2 * d:
            p0, v0 = x0[:, :d], x0[:, d:]
        else:
            p0, v0 = x0, torch.zeros_like(x0)
        p, v = integrate(out, p0, v0, self.dt)
        return p, v, None if var_out is None else integrate_variance(var_out, self.dt)

    def rollout(self, out: Tensor, var_out: Tensor | None, x0: Tensor) -> Rollout:
        p, v, var_p = self.states(out, var_out, x0)
        return Rollout(p=p, v=v, u=out, var_p=var_p, dt=self.dt)


#: the generic plants, by name; others are declared by the packages that provide them
#: (genplan.seq2seq.plugins: the pancake's "spatula")
PLANTS: dict[str, type] = {"position": PositionPlant, "integrator": Integrator}


def plant(name: str, dt: float) -> Plant:
    """The plant called ``name`` (constructed with the config's ``dt``)."""
    from genplan.seq2seq import plugins

    cls = PLANTS.get(name) or plugins.find("plant", name)
    if cls is None:
        raise UnknownNameError(f"unknown plant {name!r}; known: {sorted(set(PLANTS) | set(plugins.names('plant')))}")
    made: Plant = cls(dt)
    return made
