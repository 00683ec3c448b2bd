"""Objectives as data: weighted terms on decoded trajectories (the seq2seq paper's J, eqs. 17 and
24, for any family).

An :class:`Objective` is a list of terms; its value per problem is ``sum_i weight_i * term_i(r)``
for a batch of decoded trajectories ``r`` (a :class:`~genplan.seq2seq.plants.Rollout`). Every
term returns one differentiable value per problem, shape (B,). Targets that change from problem
to problem (an end position, a via point) are given to :func:`genplan.seq2seq.adjust` as
``targets={term name: array (B, ...)}``; a target written in the term (``target = [...]``) is
used for every problem.

Terms on the trajectory's own axes (any family):

* ``end_state``: ``||scale * (x[K-1] - target)||^2`` over ``axes`` (J1's first term);
* ``end_ball``: ``max(||x[K-1][axes] - center|| - radius, 0)`` (J2's position term);
* ``end_band``: ``max(|x[K-1][axis] - target| - half_width, 0)`` (J2's attitude term);
* ``via_point``: ``||scale * (x(time) - target)||^2`` at a normalised time in [0, 1]
  (linear between samples);
* ``velocity_limits``, ``acceleration_limits``: ``mean_k ||max(scale * (|v[k]| - limit), 0)||^2``
  (J2's velocity term; the plant's velocities, per second at its ``dt``);
* ``smoothness``: ``mean_k ||scale * (x[k+1] - 2 x[k] + x[k-1])||^2``;
* ``stay_near``: ``mean_k ||scale * (x[k] - x_in[k])||^2``, near the input trajectory.

Terms of a robot's joint-space family (the model's card names the robot; the robot, task and
scene are given to :func:`genplan.seq2seq.adjust`):

* ``end_position``: ``||p_frame(q[K-1]) - target||^2`` (m^2) for a frame (a role or link name);
* ``end_pose``: the position term plus ``rotation_weight * ||log(R_target^T R_frame)||^2``;
* ``via_position``: a frame's position at a normalised time;
* ``constraint``: ``mean_k ||r(q[k])||^2``, the task's constraint residuals along the trajectory
  (its primary terms but the condition and the joint limits, weighted as in the task; evaluated by
  the native solver, :class:`genplan.samplers.costs.NativeCost`);
* ``joint_limits``: ``mean_k ||max(q[k] - upper + margin, 0)||^2 + ||max(lower + margin - q[k], 0)||^2``;
* ``clearance``: ``mean_k sum_s max(margin - d_s(q[k]), 0)^2``, ``d_s`` the signed distance from
  each of the robot's collision spheres (:mod:`genplan.spheres`) to the scene's obstacles (the
  scene's native collision world: every shape, meshes as their convex hulls as every collision
  query sees them);
* ``avoid_spheres``: the same clearance from obstacle spheres given per problem (targets (B, m, 4):
  centre and radius), e.g. a new obstacle on each original path;
* ``self_clearance``: the robot's spheres on link pairs its self-collision check tests at least
  ``margin`` apart (an arm pushed by other terms does not fold onto itself).

A package may add kinds (the pancake: ``friction_cone``, ``normal_floor``, declared for
:mod:`genplan.seq2seq.plugins`); any Python callable ``f(rollout) -> (B,)`` is a term too (:class:`Callable`; in a
file ``kind = "python"`` with ``entry = "module:function"``, imported only with
``allow_python=True``).

Files (TOML)::

    [[term]]
    kind = "end_position"
    frame = "hand"
    weight = 1e4          # target per problem: targets={"end_position": (B, 3)}

    [[term]]
    kind = "constraint"
    weight = 100.0

    [[term]]
    kind = "clearance"
    margin = 0.03
    weight = 1e3
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Callable as CallableT
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from genplan._arrays import as_float_array
from genplan.errors import CallbackError, NonFiniteError, ObjectiveFileError, SettingsError, ShapeError, UnknownNameError
from genplan.seq2seq.plants import Rollout

__all__ = ["Context", "Term", "Objective", "KINDS", "register", "load_objective", "EndState", "EndBall", "EndBand",
           "ViaPoint", "VelocityLimits", "AccelerationLimits", "Smoothness", "StayNear", "EndPosition", "EndPose",
           "ViaPosition", "Constraint", "JointLimits", "Clearance", "AvoidSpheres", "SelfClearance", "Callable", "constraint_terms"]


@dataclass
class Context:
    """What an objective's terms are bound to before adjustment: the model's space and, for a
    robot's joint-space family, the robot, its task and a scene (any may be None when the
    objective does not need it); the input trajectories; the per-problem targets."""

    axes: tuple[str, ...]
    batch: int
    x_in: Tensor
    targets: Mapping[str, Any] = field(default_factory=dict)
    robot: Any = None
    task: Any = None
    scene: Any = None
    device: torch.device = field(default_factory=lambda: torch.device("cpu"))
    _kinematics: Any = None
    #: during one :meth:`Objective.values` call: (the rollout's positions, their spheres or None),
    #: what the clearance terms of that evaluation share
    _scope: Any = None

    @property
    def dim(self) -> int:
        return len(self.axes)

    def kinematics(self) -> Any:
        """The robot's differentiable forward kinematics (float32, on the context's device)."""
        if self._kinematics is None:
            from genplan.torch_kinematics import TorchKinematics

            self._kinematics = TorchKinematics(self.robot, dtype=torch.float32).to(self.device)
        return self._kinematics


def _as_vector(value: Any, n: int | None, what: str) -> NDArray[np.float64]:
    a = as_float_array(value, what)
    if a.ndim != 1 or (n is not None and len(a) != n):
        raise ShapeError(f"{what} must be {n if n is not None else 'a list of'} numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{what} contains NaN or inf")
    return a


def _real(value: Any, what: str, low: float = -math.inf, closed: bool = True) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{what} must be a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or not (x >= low if closed else x > low):
        raise SettingsError(f"{what} must be a finite number {'>=' if closed else '>'} {low}, got {value!r}")
    return x


class Term:
    """A term of an objective: ``term(rollout) -> (B,)``, weighted by ``weight``.

    ``name`` is the key of its per-problem target (default: its kind). :meth:`bind` checks the
    term against the context (axes, robot, targets) before any adjustment and keeps what it needs
    as tensors.
    """

    kind: ClassVar[str] = ""
    #: whether the term has a target (given in the term or per problem)
    has_target: ClassVar[bool] = False
    #: the target's shape per problem; "dim" stands for the number of selected axes
    target_shape: ClassVar[tuple[Any, ...]] = ()

    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None) -> None:
        self.weight = _real(weight, f"{self.kind}.weight", 0.0)
        self.name = self.kind if name is None else str(name)
        if not self.name:
            raise SettingsError(f"{self.kind}: a term's name must not be empty")
        self.target_raw = None if target is None else as_float_array(target, f"{self.name}.target")
        self._target: Tensor | None = None

    def bind(self, ctx: Context) -> None:
        """Check the term against ``ctx`` and take its target (SettingsError, ShapeError naming
        the term and the field)."""
        if self.has_target:
            self._target = self._bind_target(ctx)

    def _expected_target(self, ctx: Context) -> tuple[int, ...]:
        return tuple(int(s) for s in self.target_shape)

    def _bind_target(self, ctx: Context) -> Tensor:
        shape = self._expected_target(ctx)
        given = ctx.targets.get(self.name)
        raw = self.target_raw if given is None else given
        if raw is None:
            raise SettingsError(f"objective term {self.name!r} ({self.kind}) needs a target: write target = [...] in "
                                f"the term or give targets={{{self.name!r}: array of shape (batch, "
                                f"{', '.join(map(str, shape))})}}")
        a = as_float_array(raw, f"targets[{self.name!r}]")
        if a.shape == shape:
            a = np.broadcast_to(a, (ctx.batch,) + shape)
        if a.shape != (ctx.batch,) + shape:
            raise ShapeError(f"targets[{self.name!r}] must have shape {shape} or ({ctx.batch}, "
                             f"{', '.join(map(str, shape))}) for {ctx.batch} problem(s), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"targets[{self.name!r}] contains NaN or inf")
        return torch.tensor(np.ascontiguousarray(a), dtype=torch.float32, device=ctx.device)

    @property
    def target(self) -> Tensor:
        assert self._target is not None, f"term {self.name} is not bound"
        return self._target

    def __call__(self, r: Rollout) -> Tensor:
        raise NotImplementedError

    def params(self) -> dict[str, Any]:
        """The term's fields for a file (besides kind, name and weight)."""
        return {} if self.target_raw is None else {"target": self.target_raw.tolist()}

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": self.kind, "weight": self.weight}
        if self.name != self.kind:
            d["name"] = self.name
        d.update(self.params())
        return d

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, weight={self.weight:g})"


def _axes(ctx: Context, axes: Sequence[Any] | None, what: str) -> list[int]:
    """Axis indices of ``axes`` (names or indices; None: all) in the context's space."""
    if axes is None:
        return list(range(ctx.dim))
    out = []
    for a in axes:
        if isinstance(a, str):
            if a not in ctx.axes:
                raise UnknownNameError(f"{what}: unknown axis {a!r}; the model's axes: {list(ctx.axes)}")
            out.append(ctx.axes.index(a))
        elif isinstance(a, (int, np.integer)) and not isinstance(a, bool) and 0 <= a < ctx.dim:
            out.append(int(a))
        else:
            raise SettingsError(f"{what}: axis {a!r} is neither an axis name nor an index below {ctx.dim}")
    return out


class _AxesTerm(Term):
    """A term on some of the trajectory's axes, each scaled."""

    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None,
                 axes: Sequence[Any] | None = None, scale: ArrayLike | float = 1.0) -> None:
        super().__init__(weight, name, target)
        self.axes_raw = None if axes is None else list(axes)
        self.scale_raw = scale
        self._idx: list[int] = []
        self._scale: Tensor | None = None

    def _expected_target(self, ctx: Context) -> tuple[int, ...]:
        return (len(self._idx),)

    def bind(self, ctx: Context) -> None:
        self._idx = _axes(ctx, self.axes_raw, f"{self.name}.axes")
        s = np.broadcast_to(as_float_array(self.scale_raw, f"{self.name}.scale"), (len(self._idx),))
        self._scale = torch.tensor(np.array(s), dtype=torch.float32, device=ctx.device)
        super().bind(ctx)

    def select(self, x: Tensor) -> Tensor:
        return x if len(self._idx) == x.shape[-1] and self._idx == list(range(x.shape[-1])) else x[..., self._idx]

    def params(self) -> dict[str, Any]:
        d = super().params()
        if self.axes_raw is not None:
            d["axes"] = self.axes_raw
        if not (np.ndim(self.scale_raw) == 0 and float(self.scale_raw) == 1.0):  # type: ignore[arg-type]
            d["scale"] = np.asarray(self.scale_raw, dtype=float).tolist()
        return d


class EndState(_AxesTerm):
    """``||scale * (x[K-1] - target)||^2`` over ``axes``."""

    kind = "end_state"
    has_target = True

    def __call__(self, r: Rollout) -> Tensor:
        assert self._scale is not None
        err = (self.select(r.p[:, -1, :]) - self.target) * self._scale
        return (err ** 2).sum(-1)


class EndBall(_AxesTerm):
    """``max(||x[K-1][axes] - center|| - radius, 0)``: the end inside a ball."""

    kind = "end_ball"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, radius: float, center: ArrayLike | None = None,
                 axes: Sequence[Any] | None = None) -> None:
        super().__init__(weight, name, None, axes)
        self.radius = _real(radius, f"{self.name}.radius", 0.0)
        self.center_raw = None if center is None else _as_vector(center, None, f"{self.name}.center")
        self._center: Tensor | None = None

    def bind(self, ctx: Context) -> None:
        super().bind(ctx)
        c = np.zeros(len(self._idx)) if self.center_raw is None else self.center_raw
        if len(c) != len(self._idx):
            raise ShapeError(f"{self.name}.center must have {len(self._idx)} values (one per axis), got {len(c)}")
        self._center = torch.tensor(tuple(float(v) for v in c), dtype=torch.float32, device=ctx.device)

    def __call__(self, r: Rollout) -> Tensor:
        end = self.select(r.p[:, -1, :])
        dist = torch.sqrt(((end - self._center) ** 2).sum(-1) + 1e-12)
        return torch.relu(dist - self.radius)

    def params(self) -> dict[str, Any]:
        d = super().params()
        d["radius"] = self.radius
        if self.center_raw is not None:
            d["center"] = self.center_raw.tolist()
        return d


class EndBand(Term):
    """``max(|x[K-1][axis] - target| - half_width, 0)``: one axis's end inside a band."""

    kind = "end_band"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, axis: Any, target: float,
                 half_width: float) -> None:
        super().__init__(weight, name)
        self.axis_raw = axis
        self.value = _real(target, f"{self.name}.target")
        self.half_width = _real(half_width, f"{self.name}.half_width", 0.0)
        self._axis = 0

    def bind(self, ctx: Context) -> None:
        (self._axis,) = _axes(ctx, [self.axis_raw], f"{self.name}.axis")

    def __call__(self, r: Rollout) -> Tensor:
        return torch.relu((r.p[:, -1, self._axis] - self.value).abs() - self.half_width)

    def params(self) -> dict[str, Any]:
        return {"axis": self.axis_raw, "target": self.value, "half_width": self.half_width}


def _at_time(x: Tensor, time: float) -> Tensor:
    """``x`` (B, K, ...) at normalised time ``time`` in [0, 1], linear between samples."""
    s = time * (x.shape[1] - 1)
    i = min(int(math.floor(s)), x.shape[1] - 2)
    f = s - i
    return x[:, i] * (1.0 - f) + x[:, i + 1] * f


def _time(value: Any, what: str) -> float:
    t = _real(value, what, 0.0)
    if t > 1.0:
        raise SettingsError(f"{what} is a normalised time in [0, 1], got {value!r}")
    return t


class ViaPoint(_AxesTerm):
    """``||scale * (x(time) - target)||^2`` at a normalised time."""

    kind = "via_point"
    has_target = True

    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None, *,
                 time: float, axes: Sequence[Any] | None = None, scale: ArrayLike | float = 1.0) -> None:
        super().__init__(weight, name, target, axes, scale)
        self.time = _time(time, f"{self.name}.time")

    def __call__(self, r: Rollout) -> Tensor:
        err = (self.select(_at_time(r.p, self.time)) - self.target) * self._scale
        return (err ** 2).sum(-1)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "time": self.time}


class VelocityLimits(_AxesTerm):
    """``mean_k ||max(scale * (|v[k]| - limit), 0)||^2`` (J2's velocity term)."""

    kind = "velocity_limits"
    quantity = "v"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, limit: ArrayLike,
                 axes: Sequence[Any] | None = None, scale: ArrayLike | float = 1.0) -> None:
        super().__init__(weight, name, None, axes, scale)
        self.limit_raw = as_float_array(limit, f"{self.name}.limit")
        self._limit: Tensor | None = None

    def bind(self, ctx: Context) -> None:
        super().bind(ctx)
        lim = np.broadcast_to(self.limit_raw, (len(self._idx),))
        if np.any(~np.isfinite(lim)) or np.any(lim < 0):
            raise SettingsError(f"{self.name}.limit must be finite and >= 0, got {self.limit_raw.tolist()}")
        self._limit = torch.tensor(np.array(lim), dtype=torch.float32, device=ctx.device)

    def _values(self, r: Rollout) -> Tensor:
        return r.v

    def __call__(self, r: Rollout) -> Tensor:
        x = self.select(self._values(r))
        return (torch.relu(self._scale * (x.abs() - self._limit)) ** 2).sum(-1).mean(-1)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "limit": self.limit_raw.tolist()}


class AccelerationLimits(VelocityLimits):
    """``mean_k ||max(scale * (|a[k]| - limit), 0)||^2``, accelerations by differences of v."""

    kind = "acceleration_limits"

    def _values(self, r: Rollout) -> Tensor:
        a = (r.v[:, 1:] - r.v[:, :-1]) / r.dt
        return torch.cat([a, a[:, -1:]], 1)


class Smoothness(_AxesTerm):
    """``mean_k ||scale * (x[k+1] - 2 x[k] + x[k-1])||^2``."""

    kind = "smoothness"

    def __call__(self, r: Rollout) -> Tensor:
        x = self.select(r.p)
        dd = (x[:, 2:] - 2.0 * x[:, 1:-1] + x[:, :-2]) * self._scale
        return (dd ** 2).sum(-1).mean(-1)


class StayNear(_AxesTerm):
    """``mean_k ||scale * (x[k] - x_in[k])||^2``: near the input trajectory."""

    kind = "stay_near"

    def bind(self, ctx: Context) -> None:
        super().bind(ctx)
        self._ref = self.select(ctx.x_in.to(ctx.device, torch.float32))

    def __call__(self, r: Rollout) -> Tensor:
        return (((self.select(r.p) - self._ref) * self._scale) ** 2).sum(-1).mean(-1)


# ------------------------------------------------------------------ terms of a robot's joints


def _need_robot(term: Term, ctx: Context) -> Any:
    if ctx.robot is None:
        raise SettingsError(f"objective term {term.name!r} ({term.kind}) needs the robot: adjust a model of a robot's "
                            "joint-space family (its card names the robot) or pass robot=")
    if list(ctx.axes) != list(ctx.robot.joint_names) or ctx.robot.nq != ctx.dim:
        raise SettingsError(f"objective term {term.name!r} ({term.kind}) works on the joint positions of "
                            f"{ctx.robot.name}; the model's axes are {list(ctx.axes)}")
    return ctx.robot


class _FrameTerm(Term):
    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None, *,
                 frame: str) -> None:
        super().__init__(weight, name, target)
        if not isinstance(frame, str) or not frame:
            raise SettingsError(f"{self.name}.frame must be a frame name (a role or a link), got {frame!r}")
        self.frame = frame

    def bind(self, ctx: Context) -> None:
        robot = _need_robot(self, ctx)
        try:
            robot.frame_id(self.frame)
        except UnknownNameError as exc:
            raise UnknownNameError(f"objective term {self.name!r}: unknown frame {self.frame!r}: {exc}") from None
        self._kin = ctx.kinematics()
        super().bind(ctx)

    def placement(self, q: Tensor) -> tuple[Tensor, Tensor]:
        b, k = q.shape[0], q.shape[1] if q.ndim == 3 else 1
        rot, pos = self._kin.frame_placement(q.reshape(-1, q.shape[-1]), self.frame)
        return rot.reshape(b, k, 3, 3), pos.reshape(b, k, 3)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "frame": self.frame}


class EndPosition(_FrameTerm):
    """``||p_frame(q[K-1]) - target||^2`` (m^2)."""

    kind = "end_position"
    has_target = True
    target_shape = (3,)

    def __call__(self, r: Rollout) -> Tensor:
        _, pos = self.placement(r.p[:, -1:])
        return ((pos[:, 0] - self.target) ** 2).sum(-1)


def _log3(r: Tensor) -> Tensor:
    """The rotation vectors (B, 3) of rotation matrices (B, 3, 3) (SO(3) log), differentiable
    away from a half turn."""
    cos = ((r.diagonal(dim1=-2, dim2=-1).sum(-1) - 1.0) * 0.5).clamp(-1.0 + 1e-7, 1.0 - 1e-7)
    angle = torch.acos(cos)
    w = torch.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], -1)
    factor = torch.where(angle < 1e-4, 0.5 + angle ** 2 / 12.0, angle / (2.0 * torch.sin(angle)))
    return w * factor[:, None]


class EndPose(_FrameTerm):
    """``||p_frame - target_p||^2 + rotation_weight * ||log(R_target^T R_frame)||^2`` at the end;
    targets are 4x4 homogeneous matrices."""

    kind = "end_pose"
    has_target = True
    target_shape = (4, 4)

    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None, *,
                 frame: str, rotation_weight: float = 0.1) -> None:
        super().__init__(weight, name, target, frame=frame)
        self.rotation_weight = _real(rotation_weight, f"{self.name}.rotation_weight", 0.0)

    def __call__(self, r: Rollout) -> Tensor:
        rot, pos = self.placement(r.p[:, -1:])
        t = self.target
        err_p = ((pos[:, 0] - t[:, :3, 3]) ** 2).sum(-1)
        rel = t[:, :3, :3].transpose(-1, -2) @ rot[:, 0]
        return err_p + self.rotation_weight * (_log3(rel) ** 2).sum(-1)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "rotation_weight": self.rotation_weight}


class ViaPosition(_FrameTerm):
    """``||p_frame(q(time)) - target||^2`` at a normalised time (m^2)."""

    kind = "via_position"
    has_target = True
    target_shape = (3,)

    def __init__(self, weight: float = 1.0, name: str | None = None, target: ArrayLike | None = None, *,
                 frame: str, time: float) -> None:
        super().__init__(weight, name, target, frame=frame)
        self.time = _time(time, f"{self.name}.time")

    def __call__(self, r: Rollout) -> Tensor:
        _, pos = self.placement(_at_time(r.p, self.time)[:, None])
        return ((pos[:, 0] - self.target) ** 2).sum(-1)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "time": self.time}


def constraint_terms(task: Any, robot: Any) -> tuple[Any, ...]:
    """The primary terms of ``task``'s manifold a trajectory is held to: the task without its
    condition term (or the manifold its condition names), joint limits left out (a term of
    their own)."""
    from genplan.projection import JointLimits as LimitsTerm
    from genplan.projection import manifold_task

    manifold = manifold_task(task, robot) if task.condition is not None else task
    return tuple(t for t in manifold.primary if not isinstance(t, LimitsTerm))


class Constraint(Term):
    """``mean_k ||r(q[k])||^2``: the task's constraint residuals along the trajectory."""

    kind = "constraint"

    def bind(self, ctx: Context) -> None:
        robot = _need_robot(self, ctx)
        if ctx.task is None:
            raise SettingsError(f"objective term {self.name!r} (constraint) needs the task: adjust a model whose card "
                                "names its task, or pass task=")
        from genplan.samplers.costs import NativeCost

        self._cost = NativeCost(robot, constraint_terms(ctx.task, robot))

    def __call__(self, r: Rollout) -> Tensor:
        b, k, n = r.p.shape
        res = self._cost(r.p.reshape(b * k, n))
        return (res ** 2).sum(-1).reshape(b, k).mean(-1)


class JointLimits(Term):
    """``mean_k ||max(q - upper + margin, 0)||^2 + ||max(lower + margin - q, 0)||^2``."""

    kind = "joint_limits"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, margin: float = 0.0) -> None:
        super().__init__(weight, name)
        self.margin = _real(margin, f"{self.name}.margin", 0.0)

    def bind(self, ctx: Context) -> None:
        robot = _need_robot(self, ctx)
        lo, hi = np.asarray(robot.lower, dtype=float), np.asarray(robot.upper, dtype=float)
        finite = np.isfinite(lo) & np.isfinite(hi)
        self._lo = torch.tensor(np.where(finite, lo + self.margin, -1e9), dtype=torch.float32, device=ctx.device)
        self._hi = torch.tensor(np.where(finite, hi - self.margin, 1e9), dtype=torch.float32, device=ctx.device)

    def __call__(self, r: Rollout) -> Tensor:
        over = torch.relu(r.p - self._hi) ** 2 + torch.relu(self._lo - r.p) ** 2
        return over.sum(-1).mean(-1)

    def params(self) -> dict[str, Any]:
        return {"margin": self.margin}


class _WorldDistance(torch.autograd.Function):
    """Signed distances of points (M, 3) to a collision world's obstacles, natively
    (:meth:`genplan.collision.CollisionWorld.point_distances`), with their gradients."""

    @staticmethod
    def forward(ctx: Any, points: Tensor, world: Any, cutoff: float) -> Tensor:  # type: ignore[override]
        d, g = world.point_distances(points.detach().double().cpu().numpy(), cutoff)
        ctx.save_for_backward(torch.from_numpy(g).to(points))
        return torch.from_numpy(d).to(points)

    @staticmethod
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor, None, None]:  # type: ignore[override]
        (g,) = ctx.saved_tensors
        return grad[..., None] * g, None, None


class _Spheres:
    """The robot's collision spheres at a batch of configurations ``q`` (N, nq): their world
    centres natively for every configuration (float64, no gradient: for screening) and through
    the torch kinematics (differentiable) for the configurations a term asks for, each
    configuration's once. The clearance terms of one objective evaluation share one
    (:meth:`Objective.values`): the screening's kinematics and the differentiable kinematics of a
    configuration that several terms need run once."""

    def __init__(self, term: Clearance, q: Tensor) -> None:
        self.q = q
        self.np = term.centers_np(q.detach().double().cpu().numpy())  # (N, S, 3)
        self._term = term
        self._slot = torch.full((len(q),), -1, dtype=torch.long, device=q.device)
        self._done: Tensor | None = None

    def centers(self, rows: Tensor) -> Tensor:
        """World centres (R, S, 3) of every sphere at the configurations ``rows`` (R,), differentiable."""
        new = torch.unique(rows[self._slot[rows] < 0])
        if len(new):
            c = self._term.sphere_centers(self.q[new])
            base = 0 if self._done is None else len(self._done)
            self._slot[new] = torch.arange(base, base + len(new), device=rows.device)
            self._done = c if self._done is None else torch.cat([self._done, c])
        assert self._done is not None
        return self._done[self._slot[rows]]


class Clearance(Term):
    """``mean_k sum_s max(margin - d_s(q[k]), 0)^2``: each collision sphere of the robot
    (:mod:`genplan.spheres`) at least ``margin`` from the scene's obstacles, ``d_s`` its signed
    distance to the nearest one (the scene's native collision world: meshes as their convex
    hulls, as every collision query sees them).

    The spheres nearer than ``margin`` (those whose term is not zero) are found first without
    gradients (native forward kinematics and distances for every sample, in float64); only their
    configurations go through the differentiable kinematics: most of a trajectory is clear of
    every obstacle, and a sphere at least ``margin`` away adds nothing to the value or the
    gradient. The terms of one objective share the kinematics of a sample (:class:`_Spheres`)."""

    kind = "clearance"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, margin: float = 0.02) -> None:
        super().__init__(weight, name)
        self.margin = _real(margin, f"{self.name}.margin", 0.0)

    def _bind_spheres(self, ctx: Context) -> Any:
        robot = _need_robot(self, ctx)
        from genplan.spheres import robot_spheres

        self._robot = robot
        self._ctx = ctx
        self._kin = ctx.kinematics()
        self._spheres = robot_spheres(robot)
        self._links = sorted(set(self._spheres.links))
        link_of = [self._links.index(n) for n in self._spheres.links]
        self._link_of = torch.tensor(link_of, device=ctx.device)
        self._centers = torch.tensor(self._spheres.centers, dtype=torch.float32, device=ctx.device)
        self._radii_np = np.asarray(self._spheres.radii, dtype=np.float64)
        self._radii = torch.tensor(self._spheres.radii, dtype=torch.float32, device=ctx.device)
        return robot

    def bind(self, ctx: Context) -> None:
        robot = self._bind_spheres(ctx)
        if ctx.scene is None:
            raise SettingsError(f"objective term {self.name!r} (clearance) needs a scene: pass scene= (a scene, a "
                                "shipped scene's name or a scene file)")
        world = robot.collision_world()
        world.add_scene(ctx.scene)
        self._world = world
        # a sphere with no obstacle within the cutoff gets the cutoff as its distance: 1 mm more
        # than margin + the largest radius screens it out whatever the rounding
        self._cutoff = self.margin + float(self._radii_np.max(initial=0.0)) + 1e-3

    def centers_np(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """World centres (N, S, 3) of the spheres at configurations ``q`` (N, nq), natively."""
        return self._spheres.world_centers(self._robot, q)

    def sphere_centers(self, q: Tensor) -> Tensor:
        """World centres (N, S, 3) of the robot's spheres at configurations ``q`` (N, nq), in
        torch (differentiable)."""
        rots, poss = [], []
        joints = self._kin.joint_placements(q)
        for link in self._links:
            rot, pos = self._kin.frame_placement(q, link, joints)
            rots.append(rot)
            poss.append(pos)
        rot = torch.stack(rots, 1)[:, self._link_of]  # (N, S, 3, 3)
        pos = torch.stack(poss, 1)[:, self._link_of]
        return pos + (rot @ self._centers[None, :, :, None]).squeeze(-1)

    def spheres_at(self, r: Rollout) -> _Spheres:
        """The spheres at the rollout's samples (B * K configurations): those of the objective
        evaluation in progress when it is one of ``r`` (shared by its terms), else new ones."""
        b, k, n = r.p.shape
        scope = self._ctx._scope
        if scope is not None and scope[0] is r.p:
            if scope[1] is None:
                self._ctx._scope = (r.p, _Spheres(self, r.p.reshape(b * k, n)))
            return self._ctx._scope[1]
        return _Spheres(self, r.p.reshape(b * k, n))

    def _near(self, c: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(N, S): the spheres at centres ``c`` (N, S, 3) nearer than margin to an obstacle."""
        d, _ = self._world.point_distances(c, self._cutoff)
        return (d - self._radii_np) < self.margin

    def _gaps(self, centers: Tensor, rows: Tensor, spheres: Tensor) -> Tensor:
        """Clearance (M,) of the spheres ``spheres`` whose centres are ``centers`` (M, 3), of the
        configurations ``rows`` of the batch."""
        return _WorldDistance.apply(centers, self._world, self._cutoff) - self._radii[spheres]

    def __call__(self, r: Rollout) -> Tensor:
        b, k, _ = r.p.shape
        spheres = self.spheres_at(r)
        near = self._near(spheres.np)
        out = r.p.new_zeros(b * k)
        rows_np = np.flatnonzero(near.any(-1))
        if len(rows_np):
            r_np, s_np = np.nonzero(near[rows_np])  # (M,) each
            rows = torch.as_tensor(rows_np, device=r.p.device)
            r_idx = torch.as_tensor(r_np, device=r.p.device)
            s_idx = torch.as_tensor(s_np, device=r.p.device)
            centers = spheres.centers(rows)[r_idx, s_idx]  # (M, 3)
            gap = self._gaps(centers, rows[r_idx], s_idx)
            out = out.index_add(0, rows[r_idx], torch.relu(self.margin - gap) ** 2)
        return out.reshape(b, k).mean(-1)

    def params(self) -> dict[str, Any]:
        return {"margin": self.margin}


class AvoidSpheres(Clearance):
    """``mean_k sum_s sum_o max(margin - (|c_s - c_o| - r_s - r_o), 0)^2``: the robot's spheres
    clear of obstacle spheres given per problem (target (B, m, 4): centre and radius of each of
    m spheres; e.g. a new obstacle on the path), no scene needed."""

    kind = "avoid_spheres"
    has_target = True

    def _expected_target(self, ctx: Context) -> tuple[int, ...]:
        given = ctx.targets.get(self.name, self.target_raw)
        m = np.shape(given)[-2] if given is not None and np.ndim(given) >= 2 else 1
        return (int(m), 4)

    def bind(self, ctx: Context) -> None:
        self._bind_spheres(ctx)
        Term.bind(self, ctx)
        if bool((self.target[..., 3] < 0).any()):
            raise SettingsError(f"targets[{self.name!r}]: a sphere's radius (the 4th value) must be >= 0")
        self._target_np = self.target.double().cpu().numpy()

    def _near(self, c: NDArray[np.float64]) -> NDArray[np.bool_]:
        obs = self._target_np[np.arange(len(c)) // self._k]  # (N, m, 4)
        gap = np.linalg.norm(c[:, :, None, :] - obs[:, None, :, :3], axis=-1) - self._radii_np[None, :, None] - obs[:, None, :, 3]
        return gap.min(-1) < self.margin

    def _gaps(self, centers: Tensor, rows: Tensor, spheres: Tensor) -> Tensor:
        obs = self.target[rows // self._k]  # (M, m, 4)
        gap = torch.linalg.norm(centers[:, None, :] - obs[..., :3], dim=-1) - self._radii[spheres][:, None] - obs[..., 3]
        return gap.min(-1).values

    def __call__(self, r: Rollout) -> Tensor:
        self._k = r.p.shape[1]
        return super().__call__(r)


class SelfClearance(Clearance):
    """``mean_k sum_(s,t) max(margin - (|c_s - c_t| - r_s - r_t), 0)^2``: the robot's spheres on
    link pairs its self-collision check tests (links that differ and are not a disabled pair of
    the robot's SRDF or computed pairs) at least ``margin`` apart. A pair of spheres closer than
    ``margin`` at the robot's default configuration is left out (its spheres' padding overlaps
    where the links' solids do not; :attr:`dropped` counts them): the term keeps an arm from
    folding onto itself when other terms push it, no scene needed.

    Screened by link pair first: each link's spheres lie inside one bounding sphere (centred at
    the centre of its first sphere, which moves with the link), and a link pair whose bounding
    spheres are ``margin`` apart has no sphere pair nearer; only the other link pairs' sphere
    pairs are measured."""

    kind = "self_clearance"

    def bind(self, ctx: Context) -> None:
        robot = self._bind_spheres(ctx)
        links = np.asarray(self._spheres.links)
        skip = {frozenset(p) for p in robot.disabled_pairs}
        s, t = np.triu_indices(len(links), 1)
        keep = np.array([links[a] != links[b] and frozenset((links[a], links[b])) not in skip for a, b in zip(s, t)],
                        dtype=bool)
        s, t = s[keep], t[keep]
        gap0 = self._pair_gaps_np(self.centers_np(np.asarray(robot.q_default, dtype=np.float64)[None]), s, t)[0]
        ok = gap0 >= self.margin
        self.dropped = int((~ok).sum())
        self._s_np, self._t_np = s[ok], t[ok]
        self._s = torch.as_tensor(self._s_np, device=ctx.device)
        self._t = torch.as_tensor(self._t_np, device=ctx.device)
        # each link's bounding sphere (centred at its first sphere's centre) and the sphere
        # pairs of each link pair
        link_of = self._link_of.cpu().numpy()
        n_links = len(self._links)
        self._link_first = np.array([np.flatnonzero(link_of == i)[0] for i in range(n_links)])
        local = np.asarray(self._spheres.centers, dtype=np.float64)
        reach = np.linalg.norm(local - local[self._link_first][link_of], axis=-1) + self._radii_np
        self._link_radius = np.array([reach[link_of == i].max() for i in range(n_links)])
        pair_links = link_of[self._s_np] * n_links + link_of[self._t_np]
        self._groups = [(int(key) // n_links, int(key) % n_links, np.flatnonzero(pair_links == key))
                        for key in np.unique(pair_links)]

    def _pair_gaps_np(self, c: NDArray[np.float64], s: NDArray[np.int64], t: NDArray[np.int64]) -> NDArray[np.float64]:
        return np.linalg.norm(c[:, s] - c[:, t], axis=-1) - self._radii_np[s] - self._radii_np[t]

    def _near_pairs(self, c: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(rows, pairs): the sphere pairs (indices into the kept pairs) nearer than margin at
        the configurations whose sphere centres are ``c`` (N, S, 3)."""
        link_c = c[:, self._link_first]  # (N, L, 3) the links' bounding spheres' centres
        rows: list[NDArray[np.int64]] = []
        pairs: list[NDArray[np.int64]] = []
        for a, b, group in self._groups:
            gap = np.linalg.norm(link_c[:, a] - link_c[:, b], axis=-1) - self._link_radius[a] - self._link_radius[b]
            cand = np.flatnonzero(gap < self.margin)
            if len(cand):
                near = self._pair_gaps_np(c[cand], self._s_np[group], self._t_np[group]) < self.margin
                r_idx, p_idx = np.nonzero(near)
                rows.append(cand[r_idx])
                pairs.append(group[p_idx])
        if not rows:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        return np.concatenate(rows), np.concatenate(pairs)

    def __call__(self, r: Rollout) -> Tensor:
        b, k, _ = r.p.shape
        out = r.p.new_zeros(b * k)
        if not len(self._s_np):
            return out.reshape(b, k).mean(-1)
        spheres = self.spheres_at(r)
        rows_np, pairs_np = self._near_pairs(spheres.np)
        if len(rows_np):
            uniq, r_np = np.unique(rows_np, return_inverse=True)
            dev = r.p.device
            c = spheres.centers(torch.as_tensor(uniq, device=dev))  # (R, S, 3)
            ri, pi = torch.as_tensor(r_np.reshape(-1), device=dev), torch.as_tensor(pairs_np, device=dev)
            s, t = self._s[pi], self._t[pi]
            gap = torch.linalg.norm(c[ri, s] - c[ri, t], dim=-1) - self._radii[s] - self._radii[t]
            out = out.index_add(0, torch.as_tensor(rows_np, device=dev), torch.relu(self.margin - gap) ** 2)
        return out.reshape(b, k).mean(-1)


class Callable(Term):
    """Any Python callable ``f(rollout) -> (B,)`` as a term (``entry``: its importable name,
    ``module:function``, for files)."""

    kind = "python"

    def __init__(self, fn: CallableT[[Rollout], Tensor], weight: float = 1.0, name: str | None = None,
                 entry: str | None = None) -> None:
        if not callable(fn):
            raise SettingsError(f"a python term needs a callable, got {type(fn).__name__}")
        super().__init__(weight, name or getattr(fn, "__name__", "python"))
        self.fn = fn
        self.entry = entry

    def __call__(self, r: Rollout) -> Tensor:
        return self.fn(r)

    def params(self) -> dict[str, Any]:
        if self.entry is None:
            raise ObjectiveFileError(f"objective term {self.name!r} is a Python callable without an importable "
                                     "name: give entry='module:function' to write it to a file")
        return {"entry": self.entry}


#: kind -> term class (a plant's kinds are added by :func:`register`)
KINDS: dict[str, type[Term]] = {c.kind: c for c in (
    EndState, EndBall, EndBand, ViaPoint, VelocityLimits, AccelerationLimits, Smoothness, StayNear, EndPosition,
    EndPose, ViaPosition, Constraint, JointLimits, Clearance, AvoidSpheres, SelfClearance)}
def register(cls: type[Term]) -> type[Term]:
    """Make a term class's ``kind`` known to objective files (a class decorator; a package that
    ships kinds also declares them, :mod:`genplan.seq2seq.plugins`, so files find them unloaded)."""
    KINDS[cls.kind] = cls
    return cls


def _kind(name: str) -> type[Term] | None:
    from genplan.seq2seq import plugins

    if name not in KINDS and plugins.find("objective", name) is not None:
        register(plugins.find("objective", name))
    return KINDS.get(name)


def _known_kinds() -> list[str]:
    from genplan.seq2seq import plugins

    return sorted(set(KINDS) | set(plugins.names("objective")) | {"python"})


class Objective:
    """A weighted sum of terms, one value per problem: ``sum_i weight_i * term_i(r)`` (in order)."""

    def __init__(self, terms: Sequence[Term | CallableT[[Rollout], Tensor]], name: str = "objective") -> None:
        made: list[Term] = []
        for t in terms:
            made.append(t if isinstance(t, Term) else Callable(t))
        names = [t.name for t in made]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise SettingsError(f"objective {name!r}: term names must differ (targets are keyed by them), "
                                f"repeated: {dup}; give each a name")
        if not made:
            raise SettingsError(f"objective {name!r} has no term")
        self.terms = made
        self.name = name
        self._ctx: Context | None = None  # what bind() was given

    @property
    def target_names(self) -> list[str]:
        """The terms that take a target (given per problem unless written in the term)."""
        return [t.name for t in self.terms if t.has_target]

    def bind(self, ctx: Context) -> None:
        """Check every term against ``ctx`` (targets keyed by an unknown term are refused)."""
        unknown = sorted(set(ctx.targets) - {t.name for t in self.terms})
        if unknown:
            raise UnknownNameError(f"targets {unknown} name no term of objective {self.name!r}; its terms: "
                                   f"{[t.name for t in self.terms]}")
        for t in self.terms:
            t.bind(ctx)
        self._ctx = ctx

    def values(self, r: Rollout) -> dict[str, Tensor]:
        """Each term's unweighted value per problem (the clearance terms share the robot's
        spheres at the rollout's samples during the call)."""
        ctx = self._ctx
        if ctx is None:
            return {t.name: _checked(t, t(r), r.batch) for t in self.terms}
        ctx._scope = (r.p, None)
        try:
            return {t.name: _checked(t, t(r), r.batch) for t in self.terms}
        finally:
            ctx._scope = None

    def combine(self, values: Mapping[str, Tensor]) -> Tensor:
        """The weighted sum of :meth:`values`, in the terms' order."""
        total: Tensor | None = None
        for t in self.terms:
            v = values[t.name] if t.weight == 1.0 else t.weight * values[t.name]
            total = v if total is None else total + v
        assert total is not None
        return total

    def __call__(self, r: Rollout) -> Tensor:
        return self.combine(self.values(r))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "term": [t.to_dict() for t in self.terms]}

    def to_file(self, path: str | os.PathLike[str]) -> Path:
        """Write the objective as TOML (atomically)."""
        from genplan._files import write_text
        from genplan._toml import dumps

        path = Path(path)
        write_text(path, dumps(self.to_dict(), ObjectiveFileError))
        return path

    def __repr__(self) -> str:
        return f"Objective({self.name!r}, {self.terms})"


def _checked(term: Term, value: Any, b: int) -> Tensor:
    if not isinstance(value, Tensor):
        raise CallbackError(f"objective term {term.name!r} must return a torch.Tensor, got {type(value).__name__}")
    if value.ndim == 0 and b == 1:
        value = value.reshape(1)
    if value.shape != (b,):
        raise CallbackError(f"objective term {term.name!r} must return one value per problem, shape ({b},), got "
                            f"shape {tuple(value.shape)}")
    return value


def _import_entry(entry: str, where: str) -> Any:
    from genplan._entries import import_entry

    return import_entry(entry, where, ObjectiveFileError, "module:function")


def objective_from_dict(data: Mapping[str, Any], origin: str = "objective", *, allow_python: bool = False) -> Objective:
    """An objective from its dict form (``name``, ``[[term]]`` tables), refusing unknown kinds and
    keys with :class:`~genplan.errors.ObjectiveFileError` naming ``origin``, the term and the key."""
    import inspect

    unknown_top = sorted(set(data) - {"name", "description", "term"})
    if unknown_top:
        raise ObjectiveFileError(f"{origin}: unknown key(s) {unknown_top}; an objective file holds name, description "
                                 "and [[term]] tables")
    rows = data.get("term")
    if not isinstance(rows, list) or not rows:
        raise ObjectiveFileError(f"{origin}: no [[term]] table (an objective needs at least one term)")
    terms: list[Term] = []
    for i, row in enumerate(rows):
        where = f"{origin}: term {i + 1}"
        if not isinstance(row, Mapping):
            raise ObjectiveFileError(f"{where} is not a table")
        kind = row.get("kind")
        if not isinstance(kind, str):
            raise ObjectiveFileError(f"{where}: no kind (one of {_known_kinds()})")
        where = f"{where} ({kind})"
        params = {k: v for k, v in row.items() if k != "kind"}
        if kind == "python":
            if not allow_python:
                raise ObjectiveFileError(f"{where}: a python term runs code from {params.get('entry')!r}; load the file "
                                         "with allow_python=True (genplan adjust --allow-python) to run it")
            entry = params.pop("entry", None)
            extra = sorted(set(params) - {"weight", "name"})
            if extra:
                raise ObjectiveFileError(f"{where}: unknown key(s) {extra}; a python term holds entry, weight, name")
            try:
                terms.append(Callable(_import_entry(entry, where), entry=entry, **params))
            except (SettingsError, TypeError) as exc:
                raise ObjectiveFileError(f"{where}: {exc}") from None
            continue
        cls = _kind(kind)
        if cls is None:
            raise ObjectiveFileError(f"{where}: unknown kind {kind!r}; known: {_known_kinds()}")
        accepted = set(inspect.signature(cls.__init__).parameters) - {"self"}
        extra = sorted(set(params) - accepted)
        if extra:
            raise ObjectiveFileError(f"{where}: unknown key(s) {extra}; a {kind} term holds {sorted(accepted)}")
        try:
            terms.append(cls(**params))
        except TypeError as exc:
            raise ObjectiveFileError(f"{where}: {exc}") from None
        except (SettingsError, ShapeError, NonFiniteError, UnknownNameError) as exc:
            raise ObjectiveFileError(f"{where}: {exc}") from None
    try:
        return Objective(terms, name=str(data.get("name", Path(origin).stem)))
    except SettingsError as exc:
        raise ObjectiveFileError(f"{origin}: {exc}") from None


def load_objective(objective: "str | os.PathLike[str] | Objective | Mapping[str, Any]", *,
                   allow_python: bool = False) -> Objective:
    """An objective from a file (TOML), its dict form, or as given."""
    if isinstance(objective, Objective):
        return objective
    if isinstance(objective, Mapping):
        return objective_from_dict(objective, allow_python=allow_python)
    path = Path(objective)
    if not path.is_file():
        raise FileNotFoundError(f"objective file {path} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ObjectiveFileError(f"{path}: not a TOML file ({exc})") from None
    return objective_from_dict(data, str(path), allow_python=allow_python)
