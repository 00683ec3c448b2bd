"""A term of the user's own (:class:`CustomTerm`): Python residuals and Jacobians on batches, run
inside the native solver through its ``CustomTerm`` trait (and by ``backend="pinocchio"`` alike),
their outputs checked as the native adapter checks them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from genplan.errors import GenplanError, NonFiniteError, ShapeError
from genplan.projection.base import Array, Term, _BoundTerm, _State
from genplan.robots import Robot


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
    raise reaches the caller of ``solve`` / ``solve_batch`` unchanged.

    A task file, a model card and a data-generation worker process hold such a term as its
    class's importable name and its fields (``kind = "python"``, ``entry = "module:Class"``,
    ``params = {...}``; a field named ``robot`` is the task's robot, filled when the task is read),
    and import it again only when told to (``allow_python=True``, ``--allow-python``). So the
    class must be defined in an importable module (not in ``__main__`` nor inside a function) and
    its fields be plain data (numbers, strings, booleans, lists and tables of them; lists come
    back as tuples); a term that is not can still be used in this process, and writing it raises
    :class:`~genplan.errors.TaskFileError` saying why. See docs/TASKS.md, "Python terms".
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
