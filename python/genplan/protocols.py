"""The interfaces a user's own part implements to plug into genplan's native core.

The constrained RRT (:class:`genplan.planning.Planner`) runs in Rust and calls its parts through
Rust traits (``Sampler``, ``Projector``, ``ValidityChecker`` in ``rust/core/src/planning/``). A
native part (``"uniform"``, ``"gan"``, a :class:`~genplan.projection.GaussNewtonProjector`, a
:class:`~genplan.collision.CollisionWorld`) is called without Python; any Python object that
satisfies one of these protocols is called back in batches instead (the GIL is taken for the call
only). An exception raised in a call ends the plan and reaches the caller unchanged; a return
value of the wrong shape or type is a :class:`~genplan.errors.CallbackError`.

These are :class:`typing.Protocol` classes: implement the method, no need to inherit. They are
``runtime_checkable``, so ``isinstance(obj, Sampler)`` tells whether ``obj`` has the method.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["Projector", "Sampler", "ValidityChecker"]


@runtime_checkable
class Sampler(Protocol):
    """Proposes configurations for the planner to extend towards."""

    def sample(self, n: int) -> NDArray[np.float64]:
        """``n`` configurations, shape (n, nq), finite."""
        ...


@runtime_checkable
class Projector(Protocol):
    """Projects configurations onto the constraint manifold."""

    def project(self, qs: NDArray[np.float64], q_noms: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.int64]]:
        """Project each row of ``qs`` (n, nq), with posture around the row of ``q_noms``;
        returns (q (n, nq), success (n,)[, iterations (n,)])."""
        ...


@runtime_checkable
class ValidityChecker(Protocol):
    """Tells which configurations are valid (e.g. collision-free)."""

    def is_valid(self, qs: NDArray[np.float64]) -> NDArray[np.bool_]:
        """One boolean per row of ``qs`` (n, nq)."""
        ...
