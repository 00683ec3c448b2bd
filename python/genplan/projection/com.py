"""The centre-of-mass term: static stability, the centre of mass inside a box (:class:`ComBox`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from genplan.errors import GenplanError
from genplan.projection.base import Array, Term, _BoundTerm, _State, _vector
from genplan.robots import Robot


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
