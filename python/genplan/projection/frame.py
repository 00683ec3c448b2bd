"""Terms on a frame's placement in the world: its full pose (:class:`FramePose`), its position
(:class:`FramePosition`, the terms a learned sampler is conditioned on) and its orientation
(:class:`FrameOrientation`), each on chosen components or axes; an axis of the frame through a
point (:class:`PointAt`) and its origin on a plane (:class:`Plane`). Residuals and Jacobians in
the tangent space, as the native solver's (rust/core/src/projection/terms.rs)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from genplan.errors import SettingsError
from genplan.projection.base import (
    Array, Term, _BoundTerm, _native_link, _rotation, _se3, _State, _target, _unit_vector, _vector,
)
from genplan.robots import Robot


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
        self.target_t = (np.eye(3) if term.target is None
                         else _rotation(_target(term.target, "FrameOrientation.target"), "FrameOrientation.target")).T
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


def axis_complement(axis: Array) -> Array:
    """The rows (2 x 3) of a :class:`PointAt` residual: an orthonormal basis of the plane
    orthogonal to the unit vector ``axis``, ``e1 = axis x e_k`` normalised (``e_k`` the coordinate
    axis least aligned with ``axis``, the first of equals) and ``e2 = axis x e1``; the native
    solver's rule (``projection::axis_complement``)."""
    k = int(np.argmin(np.abs(axis)))
    e1 = np.cross(axis, np.eye(3)[k])
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(axis, e1)])


@dataclass(frozen=True)
class PointAt(Term):
    """An axis of a frame through a point (a camera looking at it, a tool aimed at it):
    r = E^T R(q)^T (c - p(q)), the part of the point's offset from the frame's origin, in the
    frame's axes, orthogonal to ``axis`` (E: :func:`axis_complement`). Two components, in metres:
    their norm is the point's distance from the axis's line. The point may lie behind the origin
    along the axis: start from a configuration that faces it.

    ``axis``: a unit vector in the frame; ``point``: in the world.
    """

    frame: str = ""
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    point: Any = None  # 3 numbers

    def bind(self, robot: Robot) -> _BoundTerm:
        return _PointAtBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        b = _PointAtBound(self, robot)
        return self._native("point_at", link=_native_link(robot, self.frame), axis=b.axis.tolist(), point=b.point.tolist())


class _PointAtBound(_BoundTerm):
    def __init__(self, term: PointAt, robot: Robot) -> None:
        self.term = term
        self.fid = robot.frame_id(term.frame)
        self.axis = _unit_vector(term.axis, f"PointAt({term.frame}).axis")
        what = f"PointAt({term.frame}).point"
        if term.point is None:
            raise SettingsError(f"{what}: not set (the point the axis passes through, in the world)")
        self.point = _vector(term.point, 3, what)
        self.rows = axis_complement(self.axis)

    def _offset(self, s: _State) -> Array:
        m = s.placement(self.fid)
        return m.rotation.T @ (self.point - m.translation)

    def residual(self, s: _State) -> Array:
        return self.rows @ self._offset(s)

    def jacobian(self, s: _State) -> Array:
        # the offset d = R^T (c - p) moves as [d]x w - v (the frame's body velocity)
        j = s.frame_jacobian_local(self.fid)
        return self.rows @ (pin.skew(self._offset(s)) @ j[3:] - j[:3])


@dataclass(frozen=True)
class Plane(Term):
    """A frame's origin on a plane: r = n . p(q) - d (one component: the signed distance).

    ``normal``: the plane's unit normal n, in the world; ``offset``: d, the plane's distance from
    the world's origin along n.
    """

    frame: str = ""
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0

    def bind(self, robot: Robot) -> _BoundTerm:
        return _PlaneBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        b = _PlaneBound(self, robot)
        return self._native("plane", link=_native_link(robot, self.frame), normal=b.normal.tolist(), offset=b.offset)


class _PlaneBound(_BoundTerm):
    def __init__(self, term: Plane, robot: Robot) -> None:
        self.term = term
        self.fid = robot.frame_id(term.frame)
        self.normal = _unit_vector(term.normal, f"Plane({term.frame}).normal")
        self.offset = float(_vector([term.offset], 1, f"Plane({term.frame}).offset")[0])

    def residual(self, s: _State) -> Array:
        return np.array([self.normal @ s.placement(self.fid).translation - self.offset])

    def jacobian(self, s: _State) -> Array:
        m = s.placement(self.fid)
        return (self.normal @ m.rotation @ s.frame_jacobian_local(self.fid)[:3])[None, :]
