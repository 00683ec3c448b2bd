"""Collision world: the robot's collision geometry (parry, in Rust) plus environment obstacles.

Self-collision pairs are every pair of geometries on different rigid bodies, minus the SRDF's
disabled pairs; obstacles are boxes, spheres and half-spaces. Batched queries release the GIL and
run on all cores.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, as_real
from genplan.errors import ShapeError


class CollisionWorld:
    """Collision and signed-distance queries for one robot among obstacles.

    Build it with :meth:`genplan.robots.Robot.collision_world`.
    """

    def __init__(self, native: _core.CollisionWorld) -> None:
        self._native = native
        self._nq = native.model.nq

    @property
    def native(self) -> _core.CollisionWorld:
        """The underlying Rust object (what the planner's ValidityChecker uses)."""
        return self._native

    @property
    def geometry_names(self) -> list[str]:
        return self._native.geometry_names

    @property
    def self_pairs(self) -> list[tuple[str, str]]:
        """Geometry pairs checked for self-collision."""
        return self._native.self_pairs

    @property
    def obstacle_names(self) -> list[str]:
        return self._native.obstacle_names

    @property
    def check_self(self) -> bool:
        return self._native.check_self

    @check_self.setter
    def check_self(self, value: bool) -> None:
        self._native.check_self = bool(value)

    def add_box(
        self,
        name: str,
        half_extents: ArrayLike,
        center: ArrayLike,
        rotation: ArrayLike | None = None,
    ) -> None:
        """Add a box with the given half extents (m), centre and optional 3x3 rotation."""
        rot = None if rotation is None else _matrix3(rotation, f"box '{name}' rotation")
        self._native.add_box(name, _vec3(half_extents, f"box '{name}' half_extents"),
                             _vec3(center, f"box '{name}' center"), rot)

    def add_sphere(self, name: str, radius: float, center: ArrayLike) -> None:
        """Add a sphere of ``radius`` (m) at ``center``."""
        self._native.add_sphere(name, as_real(radius, f"sphere '{name}' radius"), _vec3(center, f"sphere '{name}' center"))

    def add_halfspace(self, name: str, normal: ArrayLike, offset: float) -> None:
        """Add the solid half-space below the plane ``normal . x = offset``."""
        self._native.add_halfspace(name, _vec3(normal, f"plane '{name}' normal"), as_real(offset, f"plane '{name}' offset"))

    def remove_obstacle(self, name: str) -> None:
        self._native.remove_obstacle(name)

    def clear_obstacles(self) -> None:
        self._native.clear_obstacles()

    @overload
    def in_collision(self, q: Sequence[float]) -> bool: ...
    @overload
    def in_collision(self, q: NDArray[np.float64]) -> Any: ...
    def in_collision(self, q: Any) -> Any:
        """True where q collides (self or obstacles). (nq,) -> bool, (n, nq) -> bool array."""
        return self._native.in_collision(as_configurations(q, self._nq))

    def min_distance(self, q: Any) -> Any:
        """Minimum signed distance in m (negative: penetration depth). (nq,) -> float, (n, nq) -> array."""
        return self._native.min_distance(as_configurations(q, self._nq))

    def close_pairs(self, q: ArrayLike, margin: float = 0.0) -> list[tuple[str, str, float]]:
        """Pairs closer than ``margin`` at one configuration, closest first."""
        qa = as_configurations(q, self._nq)
        if qa.ndim != 1:
            raise ShapeError(f"q: close_pairs takes one configuration of shape ({self._nq},), got {qa.shape}")
        return self._native.close_pairs(list(qa), as_real(margin, "margin"))

    def __repr__(self) -> str:
        return repr(self._native)


def _vec3(v: ArrayLike, what: str) -> tuple[float, float, float]:
    a = as_float_array(v, what).reshape(-1)
    if a.shape != (3,):
        raise ShapeError(f"{what}: expected 3 numbers, got shape {np.shape(v)}")
    return (float(a[0]), float(a[1]), float(a[2]))


def _matrix3(m: ArrayLike, what: str) -> list[list[float]]:
    a = as_float_array(m, what)
    if a.shape != (3, 3):
        raise ShapeError(f"{what}: expected a 3x3 matrix, got shape {a.shape}")
    return a.tolist()
