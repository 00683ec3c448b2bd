"""Terms on the joints: a posture to stay near (:class:`Posture`, the null-space task of the
paper's tasks) and the joint limits (:class:`JointLimits`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from genplan._arrays import as_configurations
from genplan.errors import UnknownNameError
from genplan.projection.base import Array, Term, _BoundTerm, _State, _vector
from genplan.robots import Robot


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
