"""The costs a learned sampler is trained with, for any robot and task, from the native solver.

A task's constraint cost is the squared norm of its primary terms' weighted residuals (the
condition term and the joint limits left out: the first is the target cost, the second the
limits cost), evaluated by the native projector (``_core.Projector.primary_residuals``, Rust,
all cores) inside a torch autograd function: its backward multiplies the residuals' gradient by
the native Jacobian (tangent space, nv columns) and by the map from configuration coordinates to
the tangent space (:func:`tangent_map`). So no robot needs torch code of its own: what a task
constrains is what the GAN learns, whatever the robot. :class:`Constraints` gathers a batch's
costs (target, joint limits, the task's constraints) and the discriminator's features, for the
GAN and the flow alike.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from genplan import _core
from genplan import projection as P
from genplan.errors import GenplanError
from genplan.projection import condition_term, default_task_name, manifold_task
from genplan.robots import Robot
from genplan.torch_kinematics import TorchKinematics, quaternion_to_matrix

__all__ = ["Constraints", "NativeCost", "condition_term", "constraint_terms", "default_task_name", "manifold_task",
           "sampling_box", "tangent_map"]


def constraint_terms(task: P.Task, robot: Robot | None = None) -> tuple[P.Term, ...]:
    """The manifold task's primary terms a GAN's constraint cost holds (joint limits excluded:
    the GAN has a limits cost of its own)."""
    return tuple(t for t in manifold_task(task, robot).primary if not isinstance(t, P.JointLimits))


def tangent_map(robot: Robot, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """d v / d q at each row of ``q`` (n, nq): (n, nv, nq), the linear map from a change of the
    configuration's coordinates to the tangent (velocity) vector Pinocchio and the native solver
    differentiate in. Identity for 1-dof joints; a free-flyer's position change is rotated into the
    base frame (R^T) and its quaternion change maps to 2 vec(conj(q) * dq); a continuous joint's
    (cos, sin) change to its angle, c ds - s dc. Exact along the configuration manifold."""
    n = len(q)
    out = np.zeros((n, robot.nv, robot.nq))
    model = robot.model
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        iq, iv = int(j.idx_q), int(j.idx_v)
        if j.nq == j.nv:  # revolute, prismatic (1 dof) and other vector-space joints
            out[:, np.arange(iv, iv + j.nv), np.arange(iq, iq + j.nq)] = 1.0
        elif j.shortname() == "JointModelFreeFlyer":
            quat = q[:, iq + 3 : iq + 7]
            w = quat[:, 3]
            rot = quaternion_to_matrix(torch.from_numpy(quat)).numpy()  # every row at once: a training step's hot path
            out[:, iv : iv + 3, iq : iq + 3] = np.transpose(rot, (0, 2, 1))
            u = quat[:, :3]
            skew = np.zeros((n, 3, 3))
            skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
            skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = u[:, 2], -u[:, 1], u[:, 0]
            out[:, iv + 3 : iv + 6, iq + 3 : iq + 6] = 2.0 * (w[:, None, None] * np.eye(3) - skew)
            out[:, iv + 3 : iv + 6, iq + 6] = -2.0 * u
        elif j.nq == 2 and j.nv == 1:
            out[:, iv, iq] = -q[:, iq + 1]
            out[:, iv, iq + 1] = q[:, iq]
        else:
            raise GenplanError(f"joint {model.names[jid]} ({j.shortname()}) has no tangent map")
    return out


class NativeCost:
    """The constraint residuals of ``terms`` on ``robot`` as a differentiable torch function:
    ``cost(q)`` (B, nq) float32 or float64 -> residuals (B, m) of the same dtype, whose backward
    uses the native Jacobians. Rows are computed on all cores (GIL released)."""

    def __init__(self, robot: Robot, terms: tuple[P.Term, ...]) -> None:
        self.robot = robot
        self.terms = terms
        self.dim = 0
        self._native: _core.Projector | None = None
        if terms:
            self._native = _core.Projector(robot.kinematics, [t.to_native(robot) for t in terms])

    def __call__(self, q: torch.Tensor) -> torch.Tensor:
        if self._native is None:
            return q.new_zeros((q.shape[0], 0))
        out: torch.Tensor = _NativeResiduals.apply(q, self)
        return out

    def evaluate(self, q: NDArray[np.float64], jacobian: bool) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        assert self._native is not None
        return self._native.primary_residuals(np.ascontiguousarray(q, dtype=np.float64), jacobian)


class _NativeResiduals(torch.autograd.Function):
    @staticmethod
    def forward(ctx: Any, q: torch.Tensor, cost: NativeCost) -> torch.Tensor:  # type: ignore[override]
        qn = q.detach().double().numpy()
        r, jac = cost.evaluate(qn, jacobian=q.requires_grad)
        if jac is not None:
            # d r / d q = J (tangent) @ d v / d q, one (m, nq) matrix per row; with as many
            # coordinates as velocities every joint is a vector space and d v / d q the identity
            if cost.robot.nq != cost.robot.nv:
                jac = np.einsum("bmv,bvq->bmq", jac, tangent_map(cost.robot, qn))
            ctx.save_for_backward(torch.from_numpy(jac))
        return torch.from_numpy(r).to(q.dtype)

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, None]:  # type: ignore[override]
        (jq,) = ctx.saved_tensors
        return torch.einsum("bm,bmq->bq", grad.double(), jq).to(grad.dtype), None


def sampling_box(task: P.Task) -> NDArray[np.float64]:
    """Where a sampler draws its targets when a planner asks for configurations without one,
    [[low], [high]]: the condition's ``sample_low`` / ``sample_high`` when the task gives them
    (the paper's tuned regions of interest), else its ``low`` / ``high``."""
    condition_term(task)
    cond = task.condition
    assert cond is not None
    low = cond.low if cond.sample_low is None else cond.sample_low
    high = cond.high if cond.sample_high is None else cond.sample_high
    return np.array([low, high], dtype=np.float64)


class Constraints:
    """Differentiable costs of a configuration batch: target, limits, the task's constraints,
    and the discriminator's augmented features. Any robot and task: the target frame's placement
    and the centre of mass come from :class:`~genplan.torch_kinematics.TorchKinematics`, the
    constraint residuals from the native solver (:class:`NativeCost`). ``cfg``: the sampler's
    configuration (a GanConfig or FlowConfig: its ``target_frame``)."""

    def __init__(self, robot: Robot, cfg: Any, task: P.Task) -> None:
        self.robot = robot
        self.cfg = cfg
        self.kin = TorchKinematics(robot, dtype=torch.float32)
        lo, hi = robot.lower.copy(), robot.upper.copy()
        bounded = np.isfinite(lo) & np.isfinite(hi)
        self.bounded = torch.tensor(np.flatnonzero(bounded))
        self.lo = torch.tensor(lo[bounded], dtype=torch.float32)
        self.hi = torch.tensor(hi[bounded], dtype=torch.float32)
        # unweighted: each term in its own units (m, rad), as the paper's costs; the solver's
        # weights balance the terms of a Gauss-Newton step, not a loss
        self.native = NativeCost(robot, tuple(dataclasses.replace(t, weight=1.0) for t in constraint_terms(task, robot)))
        # a floating base's balance is part of what the discriminator compares
        self.with_com = robot.floating_base

    def evaluate(self, q: torch.Tensor, constraint: bool = True) -> dict[str, torch.Tensor]:
        """Per-sample quantities for q (B, nq): ee position/rotation, limit and (when
        ``constraint``) constraint costs, and the discriminator's augmented features."""
        # without the centre of mass, only the target frame's chain (one arm of a two-arm robot)
        joints = self.kin.joint_placements(q) if self.with_com else None
        rot, pos = self.kin.frame_placement(q, self.cfg.target_frame, joints)
        qb = q.index_select(1, self.bounded)
        limits = (torch.relu(self.lo - qb) ** 2 + torch.relu(qb - self.hi) ** 2).sum(-1)
        out = {"ee_pos": pos, "ee_rot": rot, "limits": limits}
        if constraint:
            out["constraint"] = (self.native(q) ** 2).sum(-1)
        aug = [pos, rot.reshape(-1, 9)]
        if self.with_com:
            aug.append(self.kin.center_of_mass(q, joints))
        out["augment"] = torch.cat(aug, -1)
        return out
