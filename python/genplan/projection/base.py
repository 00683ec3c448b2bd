"""What every constraint term shares: :class:`Term` (a residual with its weight and tolerance),
its form bound to a robot for the Python solver (:class:`_BoundTerm`), the Pinocchio quantities
of one configuration its residual and Jacobian read (:class:`_State`, computed once for all the
terms of an evaluation), and the checks of the values terms are given.

A built-in term is a :class:`Term` subclass with ``to_native`` (its description for the Rust
solver) and ``bind`` (its Pinocchio twin, the test oracle of the native one): one family per
module (:mod:`~genplan.projection.frame`, :mod:`~genplan.projection.joints`,
:mod:`~genplan.projection.com`); a user's term is a :class:`~genplan.projection.custom.CustomTerm`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from genplan._arrays import as_float_array, error_class
from genplan.errors import NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot

Array = NDArray[np.float64]


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


#: A target given as ``"current"``: the placement the term's frame has at a configuration the
#: caller names later (``Task.at_configuration(robot, q)``).
CURRENT = "current"


def _is_current(target: Any) -> bool:
    return isinstance(target, str) and target == CURRENT


def _target(target: Any, what: str) -> Any:
    """``target``, or SettingsError naming ``what`` when it is not set or still ``"current"``."""
    if target is None:
        raise SettingsError(f"{what}: not set (only a task's [condition] term may leave its target out: each query "
                            "sets it)")
    if _is_current(target):
        raise SettingsError(f"{what}: \"current\" is resolved at a configuration first: "
                            "task.at_configuration(robot, q)")
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


def _unit_vector(v: Any, what: str) -> Array:
    """3 finite numbers of norm 1 (within the native solver's 1e-6), else SettingsError: a
    direction given with another length is ambiguous (a plane's offset is measured along it)."""
    a = _vector(v, 3, what)
    norm = float(np.linalg.norm(a))
    if abs(norm - 1.0) > 1e-6:
        raise SettingsError(f"{what}: expected a unit vector, got {a.tolist()} (norm {norm:.6g})")
    return a
