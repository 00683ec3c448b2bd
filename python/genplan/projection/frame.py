"""Terms on a frame's placement in the world: its full pose (:class:`FramePose`), its position
(:class:`FramePosition`, the terms a learned sampler is conditioned on) and its orientation
(:class:`FrameOrientation`), each on chosen components or axes. Residuals and Jacobians in the
tangent space, as the native solver's (rust/core/src/projection.rs)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from genplan.projection.base import (
    Array, Term, _BoundTerm, _native_link, _rotation, _se3, _State, _target, _vector,
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
