"""Terms on one frame's placement relative to another's: the pose (:class:`RelativePose`, on
chosen components: with the linear ones dropped, an orientation with free axes) and the position
(:class:`RelativePosition`) of frame A in frame B. The constraint of a two-arm task (the grippers
holding one object: their relative pose fixed), of a tool held against a fixture on the robot.
Residuals and Jacobians in the tangent space, as the native solver's
(rust/core/src/projection/terms.rs); both frames move with q."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pinocchio as pin

from genplan.errors import SettingsError
from genplan.projection.base import Array, Term, _BoundTerm, _native_link, _se3, _State, _target, _vector
from genplan.robots import Robot


def _frames(term: "RelativePose | RelativePosition", robot: Robot) -> tuple[int, int]:
    """The Pinocchio frame ids of ``frame`` and ``relative_to``; SettingsError when they are one frame."""
    kind = type(term).__name__
    if not term.relative_to:
        raise SettingsError(f"{kind}({term.frame}).relative_to: not set (the frame the pose is measured in)")
    fa, fb = robot.frame_id(term.frame), robot.frame_id(term.relative_to)
    if fa == fb:
        raise SettingsError(f"{kind}({term.frame}): relative_to '{term.relative_to}' is the frame itself")
    return fa, fb


def _relative(s: _State, fa: int, fb: int) -> pin.SE3:
    """T_B^-1 T_A: frame A's placement in frame B's."""
    return s.placement(fb).actInv(s.placement(fa))


def _relative_jacobian(s: _State, fa: int, fb: int, rel: pin.SE3) -> Array:
    """The body velocity of T_B^-1 T_A (6 x nv): J_A - Ad(T_rel^-1) J_B, local Jacobians."""
    return s.frame_jacobian_local(fa) - rel.inverse().action @ s.frame_jacobian_local(fb)


@dataclass(frozen=True)
class RelativePose(Term):
    """Pose of ``frame`` (A) in ``relative_to`` (B): r = w_c * log6(T_ref^-1 T_B(q)^-1 T_A(q))
    (6 components: linear, angular; the error convention of :class:`FramePose`)."""

    frame: str = ""
    relative_to: str = ""
    target: Any = None  # pin.SE3 or 4x4: A's pose in B
    components: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _RelativePoseBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        _frames(self, robot)
        what = f"RelativePose({self.frame}).target"
        return self._native("relative_pose", link=_native_link(robot, self.frame),
                            relative_to=_native_link(robot, self.relative_to),
                            target=_se3(_target(self.target, what), what).homogeneous.tolist(),
                            mask=_vector(self.components, 6, "RelativePose.components").tolist())


class _RelativePoseBound(_BoundTerm):
    def __init__(self, term: RelativePose, robot: Robot) -> None:
        self.term = term
        self.fa, self.fb = _frames(term, robot)
        what = f"RelativePose({term.frame}).target"
        self.target_inv = _se3(_target(term.target, what), what).inverse()
        self.mask = _vector(term.components, 6, "RelativePose.components")

    def residual(self, s: _State) -> Array:
        return self.mask * pin.log6(self.target_inv * _relative(s, self.fa, self.fb)).vector

    def jacobian(self, s: _State) -> Array:
        rel = _relative(s, self.fa, self.fb)
        jrel = _relative_jacobian(s, self.fa, self.fb, rel)
        return self.mask[:, None] * (pin.Jlog6(self.target_inv * rel) @ jrel)


@dataclass(frozen=True)
class RelativePosition(Term):
    """Position of ``frame``'s origin (A) in ``relative_to`` (B), in B's axes:
    r = axes * (R_B^T (p_A - p_B) - p_ref)."""

    frame: str = ""
    relative_to: str = ""
    target: Any = None  # 3 numbers, in B's frame
    axes: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def bind(self, robot: Robot) -> _BoundTerm:
        return _RelativePositionBound(self, robot)

    def to_native(self, robot: Robot) -> dict[str, Any]:
        _frames(self, robot)
        what = f"RelativePosition({self.frame}).target"
        return self._native("relative_position", link=_native_link(robot, self.frame),
                            relative_to=_native_link(robot, self.relative_to),
                            target=_vector(_target(self.target, what), 3, what).tolist(),
                            mask=_vector(self.axes, 3, "RelativePosition.axes").tolist())


class _RelativePositionBound(_BoundTerm):
    def __init__(self, term: RelativePosition, robot: Robot) -> None:
        self.term = term
        self.fa, self.fb = _frames(term, robot)
        what = f"RelativePosition({term.frame}).target"
        self.target = _vector(_target(term.target, what), 3, what)
        self.mask = _vector(term.axes, 3, "RelativePosition.axes")

    def residual(self, s: _State) -> Array:
        return self.mask * (_relative(s, self.fa, self.fb).translation - self.target)

    def jacobian(self, s: _State) -> Array:
        # the translation of T_rel moves as R_rel times the linear part of its body velocity
        rel = _relative(s, self.fa, self.fb)
        return self.mask[:, None] * (rel.rotation @ _relative_jacobian(s, self.fa, self.fb, rel)[:3])
