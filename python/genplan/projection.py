"""Constraint projection and inverse kinematics: damped Gauss-Newton with a task hierarchy.

The GAN paper's Section III-B: residual terms with analytic Jacobians from Pinocchio, stacked
into a primary task; a secondary posture task runs in the null space of the primary (eq. 3);
damping lambda = mu r^T r + mu_bar (eq. 4); Armijo backtracking; clipping to the joint limits
after every step. A task succeeds when every primary term's residual is below its tolerance
(max absolute component of the unweighted residual, as in the authors' code).

Tasks are data: a list of terms. The paper's tasks are built by :func:`panda_task` and
:func:`talos_task`; a user task is any list of :class:`Term` objects::

    task = Task(primary=[FramePosition("hand", target=[0.5, 0, 0.6], weight=50),
                         JointLimits(weight=30)],
                secondary=[Posture()])
    result = GaussNewtonProjector(genplan.load("panda"), task).solve(q0)
"""

from __future__ import annotations

import dataclasses
import fnmatch
import json
import os
import time
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, error_class
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, TaskFileError, UnknownNameError
from genplan.robots import Robot

Array = NDArray[np.float64]


# --------------------------------------------------------------------------------------------
# Kinematic state shared by the terms of one evaluation
# --------------------------------------------------------------------------------------------


class _State:
    """Pinocchio quantities at one q, computed once and shared by all terms."""

    __slots__ = ("robot", "q", "with_jacobians", "_com", "_jcom", "_frame_jac")

    def __init__(self, robot: Robot, q: Array, with_jacobians: bool) -> None:
        self.robot = robot
        self.q = q
        self.with_jacobians = with_jacobians
        self._com: Array | None = None
        self._jcom: Array | None = None
        self._frame_jac: dict[int, Array] = {}
        if with_jacobians:
            pin.computeJointJacobians(robot.model, robot.data, q)
            pin.updateFramePlacements(robot.model, robot.data)
        else:
            pin.framesForwardKinematics(robot.model, robot.data, q)

    def placement(self, fid: int) -> pin.SE3:
        return self.robot.data.oMf[fid]

    def frame_jacobian_local(self, fid: int) -> Array:
        jac = self._frame_jac.get(fid)
        if jac is None:
            jac = pin.getFrameJacobian(self.robot.model, self.robot.data, fid, pin.LOCAL)
            self._frame_jac[fid] = jac
        return jac

    def com(self) -> Array:
        if self._com is None:
            if self.with_jacobians:
                self._jcom = pin.jacobianCenterOfMass(self.robot.model, self.robot.data, self.q, False)
            else:
                pin.centerOfMass(self.robot.model, self.robot.data, self.q, False)
            self._com = np.array(self.robot.data.com[0])
        return self._com

    def com_jacobian(self) -> Array:
        self.com()
        assert self._jcom is not None
        return self._jcom


# --------------------------------------------------------------------------------------------
# Residual terms
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Term:
    """A residual r(q) with its Jacobian dr/dv (v: tangent space, size nv).

    ``weight`` scales the term in the least-squares cost; ``tolerance`` is the largest absolute
    component of the unweighted residual for the term to count as satisfied.
    """

    weight: float = 1.0
    tolerance: float = 1e-3
    name: str = ""

    def label(self) -> str:
        return self.name or type(self).__name__

    def bind(self, robot: Robot) -> "_BoundTerm":
        raise NotImplementedError

    def to_native(self, robot: Robot) -> dict[str, Any]:
        """The term as the native solver's description (built-in terms only)."""
        raise NotImplementedError(
            f"term '{self.label()}' ({type(self).__name__}) has no native form; use backend='pinocchio'"
        )

    def _native(self, kind: str, **fields: Any) -> dict[str, Any]:
        return {"type": kind, "name": self.label(), "weight": float(self.weight), "tolerance": float(self.tolerance), **fields}


def _native_link(robot: Robot, frame: str) -> str:
    name = robot.frames.get(frame, frame)
    if name not in robot.kinematics.link_names:
        raise UnknownNameError(f"frame '{frame}' is not a link of robot '{robot.name}': the native solver needs a URDF link")
    return name


class _BoundTerm:
    """A term resolved against a robot (frame ids, index sets), ready to evaluate."""

    term: Term

    def residual(self, s: _State) -> Array:
        raise NotImplementedError

    def jacobian(self, s: _State) -> Array:
        raise NotImplementedError


def _target(target: Any, what: str) -> Any:
    """``target``, or SettingsError naming ``what`` when it is not set."""
    if target is None:
        raise SettingsError(f"{what}: not set (only a task's [condition] term may leave its target out: each query "
                            "sets it)")
    return target


def _se3(target: Any, what: str) -> pin.SE3:
    if isinstance(target, pin.SE3):
        return target.copy()
    m = as_float_array(target, what)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise error_class(m, m.shape == (4, 4))(f"{what}: expected a pinocchio.SE3 or a finite 4x4 matrix, got shape {m.shape}")
    return pin.SE3(m[:3, :3], m[:3, 3])


def _vector(v: Any, n: int, what: str) -> Array:
    a = as_float_array(v, what).reshape(-1)
    if a.shape != (n,):
        raise ShapeError(f"{what}: expected {n} numbers, got shape {np.shape(v)}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{what}: must be finite, got {a}")
    return a


def _rotation(m: Any, what: str) -> Array:
    r = as_float_array(m, what)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)) or np.abs(r.T @ r - np.eye(3)).max() > 1e-6:
        raise error_class(r, r.shape == (3, 3))(f"{what}: expected a 3x3 rotation matrix")
    return r


@dataclass(frozen=True)
class FramePose(Term):
    """Full pose of a frame: r = w_c * log6(T_ref^-1 T(q)) (6 components: linear, angular)."""

    frame: str = ""
    target: Any = None  # pin.SE3 or 4x4
    components: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _FramePoseBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        return self._native("frame_pose", link=_native_link(robot, self.frame),
                            target=_se3(_target(self.target, f"FramePose({self.frame}).target"),
                                        f"FramePose({self.frame}).target").homogeneous.tolist(),
                            mask=_vector(self.components, 6, "FramePose.components").tolist())


class _FramePoseBound(_BoundTerm):
    def __init__(self, term: FramePose, robot: Robot) -> None:
        self.term = term
        self.fid = robot.frame_id(term.frame)
        what = f"FramePose({term.frame}).target"
        self.target_inv = _se3(_target(term.target, what), what).inverse()
        self.mask = _vector(term.components, 6, "FramePose.components")

    def residual(self, s: _State) -> Array:
        return self.mask * pin.log6(self.target_inv * s.placement(self.fid)).vector

    def jacobian(self, s: _State) -> Array:
        rel = self.target_inv * s.placement(self.fid)
        return self.mask[:, None] * (pin.Jlog6(rel) @ s.frame_jacobian_local(self.fid))


@dataclass(frozen=True)
class FramePosition(Term):
    """Position of a frame in the world: r = axes * (p(q) - p_ref)."""

    frame: str = ""
    target: Any = None  # 3 numbers
    axes: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _FramePositionBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        return self._native("frame_position", link=_native_link(robot, self.frame),
                            target=_vector(_target(self.target, f"FramePosition({self.frame}).target"), 3,
                                           f"FramePosition({self.frame}).target").tolist(),
                            mask=_vector(self.axes, 3, "FramePosition.axes").tolist())


class _FramePositionBound(_BoundTerm):
    def __init__(self, term: FramePosition, robot: Robot) -> None:
        self.term = term
        self.fid = robot.frame_id(term.frame)
        what = f"FramePosition({term.frame}).target"
        self.target = _vector(_target(term.target, what), 3, what)
        self.mask = _vector(term.axes, 3, "FramePosition.axes")

    def residual(self, s: _State) -> Array:
        return self.mask * (s.placement(self.fid).translation - self.target)

    def jacobian(self, s: _State) -> Array:
        rot = s.placement(self.fid).rotation
        return self.mask[:, None] * (rot @ s.frame_jacobian_local(self.fid)[:3])


@dataclass(frozen=True)
class FrameOrientation(Term):
    """Orientation of a frame: r = axes * log3(R_ref^T R(q) R_offset).

    With ``axes = (1, 1, 0)`` the rotation about the target's z axis is free: the Panda's
    "gripper horizontal, yaw free" constraint uses R_offset = Ry(-pi/2) on the hand frame.
    """

    frame: str = ""
    target: Any = None  # 3x3 rotation; None: identity
    axes: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset: Any = None  # 3x3 rotation applied in the frame; None: identity

    def bind(self, robot: Robot) -> _BoundTerm:
        return _FrameOrientationBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        b = _FrameOrientationBound(self, robot)
        return self._native("frame_orientation", link=_native_link(robot, self.frame),
                            target=b.target_t.T.tolist(), offset=b.offset.tolist(), mask=b.mask.tolist())


class _FrameOrientationBound(_BoundTerm):
    def __init__(self, term: FrameOrientation, robot: Robot) -> None:
        self.term = term
        self.fid = robot.frame_id(term.frame)
        self.target_t = (np.eye(3) if term.target is None else _rotation(term.target, "FrameOrientation.target")).T
        self.offset = np.eye(3) if term.offset is None else _rotation(term.offset, "FrameOrientation.offset")
        self.mask = _vector(term.axes, 3, "FrameOrientation.axes")

    def _rel(self, s: _State) -> Array:
        return self.target_t @ s.placement(self.fid).rotation @ self.offset

    def residual(self, s: _State) -> Array:
        return self.mask * pin.log3(self._rel(s))

    def jacobian(self, s: _State) -> Array:
        # angular velocity of the offset frame, in its own axes: offset^T * omega_local
        jw = self.offset.T @ s.frame_jacobian_local(self.fid)[3:]
        return self.mask[:, None] * (pin.Jlog3(self._rel(s)) @ jw)


@dataclass(frozen=True)
class Posture(Term):
    """r = joint_weights * (q (-) q_nom), in the tangent space (pin.difference).

    ``q_nom=None``: the solver's nominal posture (by default the initial guess). ``overrides``
    maps joint names to fixed nominal values (Talos: the left arm at its default posture).
    """

    q_nom: Any = None
    joint_weights: Any = None  # nv numbers; None: ones
    overrides: Mapping[str, float] = field(default_factory=dict)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _PostureBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        b = _PostureBound(self, robot)
        return self._native("posture", q_nom=None if b.q_nom is None else b.q_nom.tolist(),
                            weights=b.w.tolist(), overrides=b.override_q)


class _PostureBound(_BoundTerm):
    def __init__(self, term: Posture, robot: Robot) -> None:
        self.term = term
        self.model = robot.model
        self.q_nom: Array | None = None if term.q_nom is None else as_configurations(term.q_nom, robot.nq, "Posture.q_nom")
        self.w = np.ones(robot.nv) if term.joint_weights is None else _vector(term.joint_weights, robot.nv, "Posture.joint_weights")
        self.override_q: list[tuple[int, float]] = []
        for joint, value in term.overrides.items():
            if joint not in robot.joint_names:
                raise UnknownNameError(f"Posture.overrides: unknown joint '{joint}'")
            self.override_q.append((robot.model.joints[robot.model.getJointId(joint)].idx_q, float(value)))
        self.floating = robot.floating_base

    def set_nominal(self, q_nom: Array) -> None:
        if self.term.q_nom is None:
            q = q_nom.copy()
            for iq, value in self.override_q:
                q[iq] = value
            self.q_nom = q

    def residual(self, s: _State) -> Array:
        assert self.q_nom is not None
        return self.w * pin.difference(self.model, self.q_nom, s.q)

    def jacobian(self, s: _State) -> Array:
        assert self.q_nom is not None
        if not self.floating:
            return np.diag(self.w)
        return self.w[:, None] * pin.dDifference(self.model, self.q_nom, s.q, pin.ARG1)


@dataclass(frozen=True)
class JointLimits(Term):
    """Distance outside the joint limits: r = min(q - lower, 0) + max(q - upper, 0), per bounded
    joint. Rows within ``margin`` of a limit keep their Jacobian (so steps do not push past it)."""

    margin: float = 1e-3

    def bind(self, robot: Robot) -> _BoundTerm:
        return _JointLimitsBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        return self._native("joint_limits", margin=float(self.margin))


class _JointLimitsBound(_BoundTerm):
    def __init__(self, term: JointLimits, robot: Robot) -> None:
        self.term = term
        iq, iv = [], []
        for jid in range(1, robot.model.njoints):
            j = robot.model.joints[jid]
            if j.nq == 1 and j.nv == 1 and np.isfinite(robot.lower[j.idx_q]) and np.isfinite(robot.upper[j.idx_q]):
                iq.append(j.idx_q)
                iv.append(j.idx_v)
        self.iq = np.array(iq, dtype=int)
        self.iv = np.array(iv, dtype=int)
        self.lo = robot.lower[self.iq]
        self.hi = robot.upper[self.iq]
        self.nv = robot.nv

    def residual(self, s: _State) -> Array:
        x = s.q[self.iq]
        return np.minimum(x - self.lo, 0.0) + np.maximum(x - self.hi, 0.0)

    def jacobian(self, s: _State) -> Array:
        x = s.q[self.iq]
        m = self.term.margin
        near = (x - m < self.lo) | (x + m > self.hi)
        jac = np.zeros((len(self.iq), self.nv))
        jac[np.arange(len(self.iq))[near], self.iv[near]] = 1.0
        return jac


@dataclass(frozen=True)
class ComBox(Term):
    """Static stability: the centre of mass inside an axis-aligned box (the support rectangle of
    the feet in x-y, a height range in z): r = min(c - lower, 0) + max(c - upper, 0)."""

    lower: Any = (-0.1, -0.1, 0.6)
    upper: Any = (0.1, 0.1, 1.1)
    margin: float = 1e-3

    def bind(self, robot: Robot) -> _BoundTerm:
        return _ComBoxBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        b = _ComBoxBound(self, robot)
        return self._native("com_box", lower=b.lo.tolist(), upper=b.hi.tolist(), margin=float(self.margin))


class _ComBoxBound(_BoundTerm):
    def __init__(self, term: ComBox, robot: Robot) -> None:
        self.term = term
        self.lo = _vector(term.lower, 3, "ComBox.lower")
        self.hi = _vector(term.upper, 3, "ComBox.upper")
        if np.any(self.lo > self.hi):
            raise GenplanError(f"ComBox: lower {self.lo} exceeds upper {self.hi}")

    def residual(self, s: _State) -> Array:
        c = s.com()
        return np.minimum(c - self.lo, 0.0) + np.maximum(c - self.hi, 0.0)

    def jacobian(self, s: _State) -> Array:
        c = s.com()
        m = self.term.margin
        near = ((c - m < self.lo) | (c + m > self.hi)).astype(np.float64)
        return near[:, None] * s.com_jacobian()


@dataclass(frozen=True)
class CustomTerm(Term):
    """A term of your own, run inside the native solver (and by ``backend="pinocchio"`` alike).

    Subclass it as a frozen dataclass (its fields are the term's parameters, e.g. the robot and a
    frame) and give it:

    - ``dim``: the residual's length (a class attribute, a field or a property; at least 1);
    - ``residual(q)``: q of shape (n, nq) -> (n, dim), the unweighted residual of each row;
    - ``jacobian(q)``: q of shape (n, nq) -> (n, dim, nv), d residual / d v in the tangent space
      (the same ``v`` as the built-in terms and ``pinocchio.integrate``: for a free-flyer base,
      its twist in its own frame);
    - optionally ``residual_and_jacobian(q)`` returning both, when they share work (the solver
      calls it where it needs both; the default calls the two methods).

    ``weight``, ``tolerance`` and ``name`` work as for the built-in terms. The native solver calls
    the methods with one configuration at a time (n = 1), each call holding the GIL, and solves
    the rows of a batch one after the other (faster than threads contending for the GIL); outputs of
    another shape raise :class:`~genplan.errors.ShapeError`, non-finite ones
    :class:`~genplan.errors.NonFiniteError` (both naming the term), and an exception the methods
    raise reaches the caller of ``solve`` / ``solve_batch`` unchanged. A task holding such a term
    cannot be written to a task file (it is Python code): build it in Python. See docs/TASKS.md.
    """

    @property
    def dim(self) -> int:
        """The residual's length; a subclass sets it."""
        raise NotImplementedError(f"custom term '{self.label()}' ({type(self).__name__}): set dim, the residual's length")

    def residual(self, q: Array) -> Array:
        """The unweighted residual of each row of ``q`` (n, nq): shape (n, dim)."""
        raise NotImplementedError(f"custom term '{self.label()}' ({type(self).__name__}): define residual(q)")

    def jacobian(self, q: Array) -> Array:
        """The residual's Jacobian at each row of ``q`` (n, nq): shape (n, dim, nv), tangent space."""
        raise NotImplementedError(f"custom term '{self.label()}' ({type(self).__name__}): define jacobian(q)")

    def residual_and_jacobian(self, q: Array) -> tuple[Array, Array]:
        """``(residual(q), jacobian(q))``; override when the two share work."""
        return self.residual(q), self.jacobian(q)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _CustomBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        _custom_dim(self)
        # one call for both where the subclass computes them together; else the two methods
        combined = type(self).residual_and_jacobian is not CustomTerm.residual_and_jacobian
        return self._native("custom", term=self, combined=combined)


def _custom_dim(term: CustomTerm) -> int:
    dim = term.dim
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1:
        raise GenplanError(f"custom term '{term.label()}': dim must be a positive int, got {dim!r}")
    return int(dim)


def _custom_output(term: CustomTerm, call: str, value: Any, shape: tuple[int, ...], nq: int) -> Array:
    """A custom term's output checked as the native adapter checks it (rust/python/src/lib.rs,
    ``PyCustomTerm``): float64 numbers of ``shape``, finite; errors name the term."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"term '{term.label()}': {call} must return an array of shape {shape} for q of shape "
                         f"(1, {nq}), got {type(value).__name__} ({exc})") from None
    if a.shape != shape:
        raise ShapeError(f"term '{term.label()}': {call} must return an array of shape {shape} for q of shape "
                         f"(1, {nq}), got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        what = "residual" if len(shape) == 2 else "Jacobian (row-major)"
        raise NonFiniteError(f"term '{term.label()}' {what}: element {bad[0]} is not finite ({a.reshape(-1)[bad[0]]})")
    return a


class _CustomBound(_BoundTerm):
    """A :class:`CustomTerm` in the Python solver: called with n = 1, like the native adapter."""

    def __init__(self, term: CustomTerm, robot: Robot) -> None:
        self.term: CustomTerm = term
        self.dim = _custom_dim(term)
        self.nq, self.nv = robot.nq, robot.nv

    def residual(self, s: _State) -> Array:
        r = self.term.residual(s.q[None].copy())
        return _custom_output(self.term, "residual(q)", r, (1, self.dim), self.nq)[0]

    def jacobian(self, s: _State) -> Array:
        j = self.term.jacobian(s.q[None].copy())
        return _custom_output(self.term, "jacobian(q)", j, (1, self.dim, self.nv), self.nq)[0]


# --------------------------------------------------------------------------------------------
# Tasks and the solver
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Task:
    """A primary list of terms (all must be satisfied) and an optional secondary list solved in
    the primary's null space (typically a :class:`Posture`)."""

    primary: Sequence[Term]
    secondary: Sequence[Term] = ()
    name: str = "task"
    #: The term whose target a sampler is conditioned on, and the box its targets are drawn from
    #: (training data is projected without that term; IK sets its target per query).
    condition: "Condition | None" = None

    def to_dict(self) -> dict[str, Any]:
        """The task as plain data (the task file's tables; see docs/TASKS.md)."""
        out: dict[str, Any] = {"name": self.name}
        out["primary"] = [_term_to_dict(t) for t in self.primary]
        if self.secondary:
            out["secondary"] = [_term_to_dict(t) for t in self.secondary]
        if self.condition is not None:
            c = self.condition
            out["condition"] = {"term": c.term, "low": [float(x) for x in c.low], "high": [float(x) for x in c.high]}
            if c.sample_low is not None and c.sample_high is not None:
                out["condition"]["sample_low"] = [float(x) for x in c.sample_low]
                out["condition"]["sample_high"] = [float(x) for x in c.sample_high]
            if c.manifold is not None:
                out["condition"]["manifold"] = c.manifold
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], robot: Robot | None = None, origin: str = "task") -> "Task":
        """A task from plain data (:meth:`to_dict`'s form); ``robot`` resolves values given as
        ``"default"`` (a frame's placement or the posture at the robot's default configuration)
        and joint-name patterns (``joint_weights = {"arm_left_*" = 1.0}``)."""
        return _task_from_dict(data, robot, origin)

    def to_file(self, path: str | os.PathLike[str]) -> Path:
        """Write the task as a task file (TOML), atomically; :meth:`from_file` reads it back."""
        from genplan._files import write_text

        return write_text(path, _toml(self.to_dict()))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], robot: Robot | None = None) -> "Task":
        """Read a task file (TOML); errors name the file, the table and the key."""
        from genplan._files import read_toml

        path = Path(path)
        data = read_toml(path, "task", TaskFileError)
        task = _task_from_dict(data, robot, f"task file {path}")
        c = task.condition
        if c is not None and c.manifold is not None and c.manifold not in task_names() and not Path(c.manifold).is_absolute():
            # a manifold task given as a file: relative to this task file
            task = dataclasses.replace(task, condition=dataclasses.replace(c, manifold=str(path.parent / c.manifold)))
        return task

    def with_targets(self, **targets: Any) -> "Task":
        """A copy whose terms named in ``targets`` get that ``target`` (e.g. ``hand_position=p``)."""
        names = {t.name for t in [*self.primary, *self.secondary]}
        unknown = set(targets) - names
        if unknown:
            raise UnknownNameError(f"task '{self.name}' has no term named {sorted(unknown)} (terms: {sorted(n for n in names if n)})")

        def swap(terms: Sequence[Term]) -> tuple[Term, ...]:
            return tuple(dataclasses.replace(t, target=targets[t.name]) if t.name in targets else t for t in terms)

        return dataclasses.replace(self, primary=swap(self.primary), secondary=swap(self.secondary))

    def with_tolerances_scaled(self, factor: float) -> "Task":
        """A copy whose primary terms' tolerances are multiplied by ``factor`` (e.g. 0.1: project
        ten times tighter than the constraint, so the straight chord between two nearby projected
        states still satisfies it)."""
        if not (np.isfinite(factor) and factor > 0):
            raise SettingsError(f"factor must be positive, got {factor}")
        return dataclasses.replace(
            self, primary=tuple(dataclasses.replace(t, tolerance=t.tolerance * factor) for t in self.primary))


@dataclass(frozen=True)
class Condition:
    """The term a sampler is conditioned on (its ``target`` varies per query, so the term may
    leave it out: see :class:`GaussNewtonProjector`) and the box its targets are drawn from
    (``low``, ``high``: as many numbers as the target)."""

    term: str
    low: tuple[float, ...]
    high: tuple[float, ...]
    #: where a sampler draws targets when a planner asks for configurations without one (default:
    #: ``low`` / ``high``)
    sample_low: tuple[float, ...] | None = None
    sample_high: tuple[float, ...] | None = None
    #: the task (shipped name or file, relative to this task file) whose manifold a sampler's
    #: training data covers; default: this task without the condition term
    manifold: str | None = None

    def middle(self) -> tuple[float, ...]:
        """The middle of the box, ``(low + high) / 2``."""
        return tuple(0.5 * (lo + hi) for lo, hi in zip(self.low, self.high))


#: The built-in term kinds, by the name a task file's ``kind`` gives.
TERM_KINDS: dict[str, type[Term]] = {c.__name__: c for c in (FramePose, FramePosition, FrameOrientation, Posture,
                                                            JointLimits, ComBox)}
#: Presets: the task files shipped with genplan (their stem is the name).
TASKS_DIR = Path(__file__).parent / "presets" / "tasks"


def task_names() -> tuple[str, ...]:
    """The shipped task files' names (``panda_projection``, ``talos_ik``, ...)."""
    return tuple(sorted(p.stem for p in TASKS_DIR.glob("*.toml")))


def load_task(task: "str | os.PathLike[str] | Task", robot: Robot | None = None) -> Task:
    """A task: a :class:`Task` as is, a shipped task's name (:func:`task_names`) or a task file."""
    if isinstance(task, Task):
        return task
    if isinstance(task, str) and task in task_names():
        return Task.from_file(TASKS_DIR / f"{task}.toml", robot)
    path = Path(task)
    if path.suffix != ".toml" and not path.exists():
        raise UnknownNameError(f"unknown task '{task}' (shipped: {', '.join(task_names())}; or a task file .toml)")
    return Task.from_file(path, robot)


def default_task_name(robot: Robot) -> str:
    """The task of ``robot`` when none is named (a GAN's, a scene's queries'): the shipped
    ``<robot>_ik``, else a SettingsError asking for one."""
    name = f"{robot.name}_ik"
    if name not in task_names():
        raise SettingsError(f"robot '{robot.name}' has no shipped task: give one (a task file with a [condition], "
                            f"see docs/TASKS.md; shipped tasks: {', '.join(task_names())})")
    return name


def condition_term(task: Task) -> FramePosition:
    """The task's condition term, which a sampler is conditioned on: a FramePosition (3 target
    numbers, the sampler's input), else GenplanError naming the task and the term."""
    if task.condition is None:
        raise GenplanError(f"task '{task.name}' has no [condition]: a learned sampler is conditioned on a "
                           "term's target (e.g. [condition] term = \"hand_position\" with low/high boxes); see "
                           "docs/TASKS.md")
    for t in task.primary:
        if t.name == task.condition.term:
            if not isinstance(t, FramePosition):
                raise GenplanError(f"task '{task.name}': its condition term '{t.name}' is a {type(t).__name__}; a "
                                   "learned sampler is conditioned on a FramePosition (a 3-D target)")
            if len(task.condition.low) != 3:
                raise GenplanError(f"task '{task.name}': its condition box needs 3 numbers per corner, got "
                                   f"{len(task.condition.low)}")
            return t
    names = [t.name for t in task.primary]
    raise UnknownNameError(f"task '{task.name}': condition term '{task.condition.term}' is not one of its primary "
                           f"terms (known: {names})")


def unset_condition_term(task: Task) -> str | None:
    """The name of ``task``'s condition term when it leaves its target out (each query sets it),
    else None."""
    c = task.condition
    term = None if c is None else next((t for t in task.primary if t.name == c.term), None)
    return term.name if term is not None and getattr(term, "target", 0) is None else None


def check_task_use(task: Task, robot: Robot) -> None:
    """Try, on ``robot``'s default configuration, every use a learned sampler's training, its
    card and its evaluation make of ``task``, so that a task they cannot use fails before the
    work, with the error the late use would raise: its plain form (the card's ``task``: JSON,
    read back equal), its condition term and box (:func:`condition_term`), the projector of its
    manifold (the training data, :func:`manifold_task`), and the projector of the whole task
    with the condition's target given per row (the card's IK evaluation)."""
    data = task.to_dict()
    try:
        text = json.dumps(data, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise TaskFileError(f"task '{task.name}': its plain form is not JSON ({exc})") from None
    again = Task.from_dict(json.loads(text), robot, origin=f"task '{task.name}' (read back)")
    if json.dumps(again.to_dict(), sort_keys=True) != text:
        raise TaskFileError(f"task '{task.name}': its plain form does not read back the same (a term whose fields a "
                            "task file cannot hold)")
    cond = condition_term(task)
    assert task.condition is not None
    q = robot.q_default[None]
    GaussNewtonProjector(robot, manifold_task(task, robot)).solve_batch(q, parallel=False)
    middle = np.array([task.condition.middle()])
    GaussNewtonProjector(robot, task).solve_batch(q, targets={cond.name: middle}, parallel=False)


def manifold_task(task: Task, robot: Robot | None = None) -> Task:
    """The manifold a learned sampler covers (its training data is projected onto it): the task
    named by the condition's ``manifold`` when given (the paper's projection task, whose weights
    and tolerances differ from its IK task's), else the task without its condition term."""
    cond = condition_term(task)
    assert task.condition is not None
    if task.condition.manifold is not None:
        return load_task(task.condition.manifold, robot)
    primary = tuple(t for t in task.primary if t.name != cond.name)
    if not primary:
        raise GenplanError(f"task '{task.name}': without its condition term '{cond.name}' no primary term is left")
    return dataclasses.replace(task, primary=primary, condition=None)


def _plain(v: Any) -> Any:
    """A term field as TOML-able data (None stays None: the field is left out)."""
    if isinstance(v, pin.SE3):
        return v.homogeneous.tolist()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


def _term_to_dict(t: Term) -> dict[str, Any]:
    kind = type(t).__name__
    if isinstance(t, CustomTerm):
        raise TaskFileError(f"term '{t.label()}': {kind} is a custom term (Python code), which a task file cannot hold; "
                            "build this task in Python (a task file holds built-in terms only: "
                            f"{', '.join(TERM_KINDS)})")
    if TERM_KINDS.get(kind) is not type(t):
        raise TaskFileError(f"term '{t.label()}': {kind} is not a built-in term kind (known: {', '.join(TERM_KINDS)})")
    out: dict[str, Any] = {"kind": kind}
    for f in dataclasses.fields(t):
        v = _plain(getattr(t, f.name))
        if v is None or v == {} or (f.name == "name" and v == ""):
            continue
        out[f.name] = v
    return out


def _need_robot(robot: Robot | None, where: str, what: str) -> Robot:
    """``robot``, or TaskFileError: ``what`` (a robot-relative value) cannot be read without it."""
    if robot is None:
        raise TaskFileError(f"{where}: {what} needs the robot (pass robot= when reading the task)")
    return robot


def _term_from_dict(d: Mapping[str, Any], robot: Robot | None, where: str) -> Term:
    if not isinstance(d, Mapping):
        raise TaskFileError(f"{where}: expected a table, got {type(d).__name__}")
    kind = d.get("kind")
    cls = TERM_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise TaskFileError(f"{where}: unknown term kind {kind!r} (known: {', '.join(TERM_KINDS)})")
    names = [f.name for f in dataclasses.fields(cls)]
    fields: dict[str, Any] = {}
    for key, v in d.items():
        if key == "kind":
            continue
        if key not in names:
            raise TaskFileError(f"{where}: {kind} has no field '{key}' (fields: {', '.join(names)})")
        if v == "default" and key in ("target", "q_nom"):
            r = _need_robot(robot, where if key == "q_nom" else f"{where} target", "'default'")
            if key == "q_nom":
                v = r.q_default.copy()
            else:
                m = r.frame_placement(r.q_default, str(d.get("frame", "")))
                v = m.translation.copy() if cls is FramePosition else m.rotation.copy() if cls is FrameOrientation else m
        elif key == "joint_weights" and isinstance(v, Mapping):  # joint-name patterns -> nv weights
            robot = _need_robot(robot, where, "joint_weights by joint name")
            w = np.zeros(robot.nv)
            for pattern, weight in v.items():
                hit = [j for j in robot.joint_names if fnmatch.fnmatchcase(j, pattern)]
                if not hit:
                    raise UnknownNameError(f"{where}: joint_weights pattern '{pattern}' matches no joint of robot '{robot.name}'")
                for j in hit:
                    w[robot.model.joints[robot.model.getJointId(j)].idx_v] = float(weight)
            v = w
        elif key in ("axes", "components") and isinstance(v, list):
            v = tuple(float(x) for x in v)
        elif isinstance(v, list):
            v = as_float_array(v, f"{where} {key}")
        fields[key] = v
    try:
        return cls(**fields)
    except TypeError as exc:
        raise TaskFileError(f"{where}: {exc}") from None


def _task_from_dict(data: Mapping[str, Any], robot: Robot | None, origin: str) -> Task:
    known = ("name", "primary", "secondary", "condition")
    for key in data:
        if key not in known:
            raise TaskFileError(f"{origin}: unknown key '{key}' (known: {', '.join(known)})")
    primary = data.get("primary")
    if not isinstance(primary, list) or not primary:
        raise TaskFileError(f"{origin}: needs at least one [[primary]] term")
    secondary = data.get("secondary", [])
    if not isinstance(secondary, list):
        raise TaskFileError(f"{origin}: 'secondary' must be a list of [[secondary]] tables")
    terms = [tuple(_term_from_dict(t, robot, f"{origin}: [[{group}]] {i + 1}") for i, t in enumerate(items))
             for group, items in (("primary", primary), ("secondary", secondary))]
    condition = None
    if "condition" in data:
        c = data["condition"]
        optional = {"sample_low", "sample_high", "manifold"}
        if not isinstance(c, Mapping) or not {"term", "low", "high"} <= set(c) <= {"term", "low", "high"} | optional:
            raise TaskFileError(f"{origin}: [condition] needs the keys term, low, high (optional: "
                                f"{', '.join(sorted(optional))}), got {sorted(c) if isinstance(c, Mapping) else c!r}")
        names = [t.name for t in terms[0]]
        if c["term"] not in names:
            raise UnknownNameError(f"{origin}: [condition] term '{c['term']}' is not a primary term (terms: {', '.join(names)})")

        def box(lo_key: str, hi_key: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
            low = as_float_array(c[lo_key], f"{origin}: [condition] {lo_key}").ravel()
            high = as_float_array(c[hi_key], f"{origin}: [condition] {hi_key}").ravel()
            if low.shape != high.shape or np.any(low > high) or not np.all(np.isfinite(low) & np.isfinite(high)):
                raise TaskFileError(f"{origin}: [condition] {lo_key} and {hi_key} must be finite, of one length, "
                                    f"{lo_key} <= {hi_key}")
            return tuple(map(float, low)), tuple(map(float, high))

        low, high = box("low", "high")
        sample_low = sample_high = None
        if ("sample_low" in c) != ("sample_high" in c):
            raise TaskFileError(f"{origin}: [condition] give both sample_low and sample_high, or neither")
        if "sample_low" in c:
            sample_low, sample_high = box("sample_low", "sample_high")
            if len(sample_low) != len(low):
                raise TaskFileError(f"{origin}: [condition] sample_low has {len(sample_low)} numbers, low {len(low)}")
        manifold = c.get("manifold")
        if manifold is not None and not isinstance(manifold, str):
            raise TaskFileError(f"{origin}: [condition] manifold must be a task name or file, got {manifold!r}")
        condition = Condition(str(c["term"]), low, high, sample_low, sample_high, manifold)
    for group, items in (("primary", terms[0]), ("secondary", terms[1])):
        for i, t in enumerate(items):
            if (isinstance(t, (FramePosition, FramePose)) and t.target is None
                    and not (group == "primary" and condition is not None and t.name == condition.term)):
                which = f"the [condition] term '{condition.term}'" if condition is not None else "a [condition] term"
                raise TaskFileError(f"{origin}: [[{group}]] {i + 1} ('{t.label()}'): {type(t).__name__} needs a target "
                                    f"(only {which} may leave it out: each query sets it)")
    return Task(primary=terms[0], secondary=terms[1], name=str(data.get("name", "task")), condition=condition)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if np.isfinite(v) else ("nan" if np.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TaskFileError(f"cannot write {type(v).__name__} to a task file")


def _toml(data: Mapping[str, Any]) -> str:
    """The TOML text of a task's plain data (:meth:`Task.to_dict`)."""
    lines = [f"name = {_toml_value(data['name'])}"]
    if "condition" in data:
        lines += ["", "[condition]"] + [f"{k} = {_toml_value(v)}" for k, v in data["condition"].items()]
    for group in ("primary", "secondary"):
        for t in data.get(group, []):
            lines += ["", f"[[{group}]]"] + [f"{k} = {_toml_value(v)}" for k, v in t.items()]
    return "\n".join(lines) + "\n"


#: Damped Gauss-Newton settings, defined once in the Rust core (``projection::Settings``):
#: keyword-only, immutable (``replace(**changes)``), validated (:class:`~genplan.errors.SettingsError`).
#: Defaults: the GAN paper and its public code (``mu``: damping lambda = mu r^T r + mu_bar).
SolverSettings = _core.SolverSettings
#: ``SolverSettings.active_set``: a bounded joint within this of a limit is at it (as
#: rust/core/src/projection.rs ``AT_LIMIT``; the clipping puts it exactly there).
AT_LIMIT = 1e-9


@dataclass
class ProjectionResult:
    """Outcome of one solve."""

    q: Array
    success: bool
    iterations: int
    #: per primary term: largest absolute component of its unweighted residual at ``q``
    residuals: dict[str, float]
    time_s: float


@dataclass
class BatchResult:
    """Outcome of many solves, as arrays."""

    q: Array  # (n, nq)
    success: NDArray[np.bool_]
    iterations: NDArray[np.int64]
    residuals: dict[str, Array]
    time_s: Array

    def __len__(self) -> int:
        return len(self.success)


def _damped_pinv(jac: Array, lam: float) -> Array:
    m, n = jac.shape
    if m <= n:
        return jac.T @ np.linalg.solve(jac @ jac.T + lam * np.eye(m), np.eye(m))
    return np.linalg.solve(jac.T @ jac + lam * np.eye(n), jac.T)


BACKENDS = ("native", "pinocchio")


class GaussNewtonProjector:
    """Damped Gauss-Newton with a null-space posture task (the Projector the planner calls).

    ``solve(q0)`` projects one configuration; ``solve_batch(q0s)`` many; ``project(qs, q_noms)``
    is the planner's batched entry point (posture around ``q_noms``).

    ``backend="native"`` (default) runs the Rust solver (built-in terms and :class:`CustomTerm`
    subclasses, GIL released but for a custom term's calls, batches in parallel);
    ``backend="pinocchio"`` runs the same algorithm in Python on Pinocchio's analytic derivatives
    (the test oracle of the native one), and also accepts :class:`Term` subclasses that only
    define ``bind()``.

    A task whose condition term leaves its target out (each query sets it, docs/TASKS.md) is
    solved only with per-row targets for that term (``solve_batch(q0s, targets={term: rows})``);
    ``solve``, ``solve_batch`` without them, ``project`` and :attr:`native` (what a planner runs)
    raise SettingsError naming the term.
    """

    def __init__(self, robot: Robot, task: Task, settings: SolverSettings | None = None, backend: str = "native") -> None:
        if backend not in BACKENDS:
            raise UnknownNameError(f"unknown backend '{backend}' (known: {', '.join(BACKENDS)})")
        if not task.primary:
            raise GenplanError("a task needs at least one primary term")
        self.robot = robot
        self.task = task
        self.backend = backend
        self.settings = settings or SolverSettings()
        # A condition term without its target (each query sets it): solved only with per-row
        # targets for it (solve_batch(targets=...)); the solver is built with a stand-in target, the
        # middle of the condition's box, which every such solve replaces.
        self._unset = unset_condition_term(task)
        c = task.condition
        if self._unset is not None and c is not None and len(c.low) == 3:
            task = task.with_targets(**{self._unset: np.array(c.middle())})
        self._primary = [t.bind(robot) for t in task.primary]
        self._secondary = [t.bind(robot) for t in task.secondary]
        labels = [t.label() for t in task.primary]
        if len(set(labels)) != len(labels):
            raise GenplanError(f"primary term names must be unique, got {labels}")
        self._labels = labels
        self._weights = [float(t.weight) for t in task.primary]
        self._tols = [float(t.tolerance) for t in task.primary]
        self._bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
        # (q index, v index) of each bounded 1-dof joint, in the model's order (the active set's)
        self._bounded_qv = [(j.idx_q, j.idx_v) for j in robot.model.joints[1:]
                            if j.nq == 1 and j.nv == 1 and self._bounded[j.idx_q]]
        self._eye_nv = np.eye(robot.nv)
        self._native: _core.Projector | None = None
        if backend == "native":
            self._native = _core.Projector(
                robot.kinematics,
                [t.to_native(robot) for t in task.primary],
                [t.to_native(robot) for t in task.secondary],
                self.settings,
            )

    @property
    def native(self) -> _core.Projector | None:
        """The native solver (``backend="native"``), which the planner calls without Python.
        SettingsError for a task whose condition term has no target (nothing to aim at)."""
        self._need_target(None)
        return self._native

    def _need_target(self, term_name: str | None) -> None:
        """SettingsError unless the condition term without a target gets one per row
        (``term_name``: the term given per-row targets)."""
        if self._unset is not None and term_name != self._unset:
            raise SettingsError(f"task '{self.task.name}': its condition term '{self._unset}' has no target (each "
                                f"query sets it): give one per row, solve_batch(..., targets={{'{self._unset}': "
                                f"rows}}), or set it, task.with_targets({self._unset}=...)")

    # -- evaluation --------------------------------------------------------------------------

    def _primary_residuals(self, q: Array, with_jacobians: bool) -> tuple[_State, list[Array]]:
        s = _State(self.robot, q, with_jacobians)
        return s, [b.residual(s) for b in self._primary]

    def _cost(self, raws: list[Array]) -> float:
        return float(sum(w * w * float(r @ r) for w, r in zip(self._weights, raws)))

    def _satisfied(self, raws: list[Array]) -> bool:
        return all(r.size == 0 or float(np.abs(r).max()) < tol for r, tol in zip(raws, self._tols))

    def _clip(self, q: Array) -> Array:
        if self.settings.clip_to_limits:
            b = self._bounded
            q[b] = np.clip(q[b], self.robot.lower[b], self.robot.upper[b])
        return q

    def _hold_at_limits(self, q: Array, lam: float, r1: Array, j1: Array, j1_pinv: Array,
                        dq1: Array) -> tuple[list[int], Array, Array, Array]:
        """``SolverSettings.active_set``: while the step ``-dq1`` moves a bounded joint that sits
        at a limit out of its range, hold it (zero its Jacobian column) and solve the step again;
        as rust/core/src/projection.rs ``Projector::hold_at_limits``."""
        held: list[int] = []
        lower, upper = self.robot.lower, self.robot.upper
        while True:
            before = len(held)
            for iq, iv in self._bounded_qv:
                v = -dq1[iv]
                out = (q[iq] <= lower[iq] + AT_LIMIT and v < 0.0) or (q[iq] >= upper[iq] - AT_LIMIT and v > 0.0)
                if out and iv not in held:
                    held.append(iv)
                    j1[:, iv] = 0.0
            if len(held) == before:
                return held, j1, j1_pinv, dq1
            j1_pinv = _damped_pinv(j1, lam)
            dq1 = j1_pinv @ r1

    def _step(self, q: Array, dq: Array, alpha: float) -> Array:
        return self._clip(pin.integrate(self.robot.model, q, -alpha * dq))

    # -- solving -----------------------------------------------------------------------------

    def solve(self, q0: ArrayLike, q_nom: ArrayLike | None = None) -> ProjectionResult:
        """Project ``q0`` (shape (nq,)); the posture task regularises around ``q_nom``
        (default ``q0``). A target out of reach ends with ``success=False`` and the best q."""
        t0 = time.perf_counter()
        self._need_target(None)
        q = self.robot.check_configuration(q0, "q0")
        if q.ndim != 1:
            raise ShapeError(f"q0: solve takes one configuration of shape ({self.robot.nq},); use solve_batch")
        if self._native is not None:
            nom = None if q_nom is None else self.robot.check_configuration(q_nom, "q_nom").reshape(1, -1)
            qs, ok, it, res, ts = self._native.solve_batch(q.reshape(1, -1), nom, False)
            return ProjectionResult(q=qs[0], success=bool(ok[0]), iterations=int(it[0]),
                                    residuals=dict(zip(self._labels, map(float, res[0]))), time_s=float(ts[0]))
        q = self._clip(q.copy())
        nominal = q.copy() if q_nom is None else self.robot.check_configuration(q_nom, "q_nom")
        for b in (*self._primary, *self._secondary):
            if isinstance(b, _PostureBound):
                b.set_nominal(nominal)
        st = self.settings
        model = self.robot.model
        iterations = 0
        s, raws = self._primary_residuals(q, True)
        while not self._satisfied(raws) and iterations < st.max_iterations:
            r1 = np.concatenate([w * r for w, r in zip(self._weights, raws)])
            j1 = np.vstack([w * b.jacobian(s) for w, b in zip(self._weights, self._primary)])
            c0 = float(r1 @ r1)
            lam = st.mu * c0 + st.mu_bar
            j1_pinv = _damped_pinv(j1, lam)
            dq1 = j1_pinv @ r1
            held: list[int] = []
            if st.active_set:
                held, j1, j1_pinv, dq1 = self._hold_at_limits(q, lam, r1, j1.copy(), j1_pinv, dq1)
            slope = 2.0 * float(r1 @ (j1 @ dq1))  # -d cost / d alpha at alpha = 0
            alpha = 1.0
            for _ in range(st.max_backtracks):
                q_new = self._step(q, dq1, alpha)
                _, raws_new = self._primary_residuals(q_new, False)
                c = self._cost(raws_new)
                if c <= c0 - st.armijo_c1 * alpha * slope:
                    break
                alpha *= st.backtrack
            if self._secondary:
                # eq. (3): the posture step in the primary's null space, kept only while it does
                # not make the primary cost worse (beyond a slack).
                r2 = np.concatenate([b.term.weight * b.residual(s) for b in self._secondary])
                j2 = np.vstack([b.term.weight * b.jacobian(s) for b in self._secondary])
                j2[:, held] = 0.0
                n1 = self._eye_nv - j1_pinv @ j1
                dq2 = n1 @ (_damped_pinv(j2 @ n1, st.mu_bar) @ (r2 - alpha * (j2 @ dq1)))
                alpha2 = 1.0
                for _ in range(st.secondary_backtracks):
                    q_try = self._step(q_new, dq2, alpha2)
                    _, raws_try = self._primary_residuals(q_try, False)
                    if self._cost(raws_try) <= c + st.secondary_slack:
                        q_new = q_try
                        break
                    alpha2 *= st.backtrack
            q = q_new
            iterations += 1
            s, raws = self._primary_residuals(q, True)
        residuals = {lab: (float(np.abs(r).max()) if r.size else 0.0) for lab, r in zip(self._labels, raws)}
        return ProjectionResult(
            q=q,
            success=self._satisfied(raws),
            iterations=iterations,
            residuals=residuals,
            time_s=time.perf_counter() - t0,
        )

    def solve_batch(self, q0s: ArrayLike, q_noms: ArrayLike | None = None, *, targets: Mapping[str, ArrayLike] | None = None,
                    progress: bool = False, parallel: bool = True) -> BatchResult:
        """Solve from each row of ``q0s`` (shape (n, nq)); ``q_noms`` likewise or None.

        ``targets`` gives one primary term per-row targets, e.g. ``{"hand_position": P}`` with P of
        shape (n, 3) (a FramePose term takes (n, 4, 4)). The native backend runs the rows on all
        cores when ``parallel`` (each row's ``time_s`` is its own solve time); ``parallel=False``
        runs them one after the other, as it always does for a task with a :class:`CustomTerm`
        (its calls hold the GIL: threads contending for it were slower, see
        rust/python/src/lib.rs, ``PyProjector::solve_batch``)."""
        qs = self.robot.check_configuration(q0s, "q0s")
        if qs.ndim != 2:
            raise ShapeError(f"q0s: expected shape (n, {self.robot.nq}), got {qs.shape}")
        noms = None if q_noms is None else self.robot.check_configuration(q_noms, "q_noms")
        if noms is not None and noms.shape != qs.shape:
            raise ShapeError(f"q_noms: expected shape {qs.shape}, got {noms.shape}")
        term_name, target_rows = None, None
        if targets:
            if len(targets) != 1:
                raise GenplanError(f"targets: give per-row targets for one term, got {sorted(targets)}")
            term_name, raw = next(iter(targets.items()))
            target_rows = np.ascontiguousarray(as_float_array(raw, f"targets['{term_name}']"))
            if target_rows.shape[0] != len(qs) or not np.all(np.isfinite(target_rows)):
                raise error_class(target_rows, target_rows.shape[0] == len(qs))(
                    f"targets['{term_name}']: expected {len(qs)} finite rows, got shape {target_rows.shape}")
            term = next((t for t in self.task.primary if t.name == term_name), None)
            row_shape = {FramePosition: (3,), FrameOrientation: (3, 3), FramePose: (4, 4)}.get(type(term))
            if row_shape is not None and target_rows.shape[1:] != row_shape:
                raise ShapeError(f"targets['{term_name}']: expected shape ({len(qs)}, "
                                 f"{', '.join(map(str, row_shape))}), got {target_rows.shape}")
        self._need_target(term_name)
        if self._native is not None:
            if target_rows is not None:
                # one row of numbers per configuration (a FramePose's (4, 4) flattened); zero rows too
                target_rows = target_rows.reshape(len(qs), int(np.prod(target_rows.shape[1:])))
            q, ok, it, res, ts = self._native.solve_batch(qs, noms, parallel, term_name, target_rows)
            return BatchResult(q=q, success=ok, iterations=it,
                               residuals={lab: res[:, i] for i, lab in enumerate(self._labels)}, time_s=ts)
        rows = range(len(qs))
        if progress:
            from tqdm import tqdm

            rows = tqdm(rows, desc=f"{self.task.name}", unit="task", leave=False)
        results = []
        for i in rows:
            solver = self
            if term_name is not None:
                assert target_rows is not None
                solver = GaussNewtonProjector(self.robot, self.task.with_targets(**{term_name: target_rows[i]}),
                                              self.settings, backend=self.backend)
            results.append(solver.solve(qs[i], None if noms is None else noms[i]))
        return _stack(results, self._labels, self.robot.nq)

    def project(self, qs: ArrayLike, q_noms: ArrayLike | None = None) -> tuple[Array, NDArray[np.bool_]]:
        """The planner's Projector call: project each row, posture around ``q_noms``.
        Returns (projected configurations (n, nq), success mask (n,))."""
        res = self.solve_batch(qs, q_noms)
        return res.q, res.success


def _stack(results: list[ProjectionResult], labels: list[str], nq: int) -> BatchResult:
    return BatchResult(
        q=np.array([r.q for r in results]).reshape(len(results), nq),
        success=np.array([r.success for r in results], dtype=bool),
        iterations=np.array([r.iterations for r in results], dtype=np.int64),
        residuals={lab: np.array([r.residuals[lab] for r in results]) for lab in labels},
        time_s=np.array([r.time_s for r in results]),
    )


# --------------------------------------------------------------------------------------------
# The paper's tasks
# --------------------------------------------------------------------------------------------

# The paper's constants, read from the shipped task files (their one definition).


def _preset_table(task: str, term: str) -> dict[str, Any]:
    data = tomllib.loads((TASKS_DIR / f"{task}.toml").read_text())
    return data["condition"] if term == "[condition]" else next(t for t in data["primary"] if t["name"] == term)


#: Panda: hand frame rotated -pi/2 about y must be a pure rotation about the world z axis.
PANDA_HAND_OFFSET = np.array(_preset_table("panda_projection", "hand_orientation")["offset"])
#: IK targets for the Panda benchmark (hand position box, m).
PANDA_IK_BOX = np.array([_preset_table("panda_ik", "[condition]")[k] for k in ("low", "high")])
#: IK targets for the Talos benchmark (right-hand position box, m): in front of and to the
#: right of the robot, 96 % reachable with the feet fixed.
TALOS_IK_BOX = np.array([_preset_table("talos_ik", "[condition]")[k] for k in ("low", "high")])
#: Talos centre-of-mass box (static stability), m.
TALOS_COM_BOX = np.array([_preset_table("talos_projection", "com")[k] for k in ("lower", "upper")])

TASK_KINDS = ("projection", "ik")


def paper_task(robot: Robot, kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """The paper's task for ``robot``: the shipped task file ``<robot>_<kind>`` (``panda_ik``,
    ``talos_projection``, ...; see :func:`task_names`); ``target`` sets the IK task's condition
    term (the hand position)."""
    _check_kind(kind)
    name, shipped = f"{robot.name}_{kind}", task_names()
    if name not in shipped:
        raise UnknownNameError(f"no shipped task '{name}' (shipped: {', '.join(shipped)}); "
                               "give a task of your own (a Task, or a task file: Task.from_file)")
    task = load_task(name, robot)
    if target is None:
        return task
    if task.condition is None:
        raise GenplanError(f"task '{name}' has no condition term to set a target on")
    return task.with_targets(**{task.condition.term: target})


def panda_task(kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """Panda with the gripper horizontal (yaw free) and within its limits; ``ik`` adds the hand
    position (weights and tolerances of the paper's public code): the shipped task files
    ``panda_projection`` / ``panda_ik``."""
    _check_kind(kind)
    task = load_task(f"panda_{kind}")
    return task if target is None else task.with_targets(hand_position=target)


def talos_task(robot: Robot, kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """Talos with both soles fixed at their half-sitting placement (full SE(3)), the centre of
    mass in :data:`TALOS_COM_BOX`, within joint limits and the left arm held at its default
    posture; ``ik`` adds the right-hand position. The secondary task keeps the rest of the
    posture near the initial guess. The shipped task files ``talos_projection`` / ``talos_ik``."""
    _check_kind(kind)
    task = load_task(f"talos_{kind}", robot)
    return task if target is None else task.with_targets(right_hand_position=target)


def _check_kind(kind: str) -> None:
    if kind not in TASK_KINDS:
        raise UnknownNameError(f"unknown task kind '{kind}' (known: {', '.join(TASK_KINDS)})")
