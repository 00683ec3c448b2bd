"""Collision world: the robot's collision geometry (parry, in Rust) plus environment obstacles.

Self-collision pairs are every pair of geometries on different rigid bodies, minus the SRDF's
disabled pairs; obstacles are boxes, spheres, cylinders, capsules, meshes (hulls, triangles or convex parts),
half-spaces and point clouds (each point a ball: :meth:`CollisionWorld.add_points`), added one by
one or as a scene (:meth:`CollisionWorld.add_scene`, a scene file: docs/SCENES.md). Batched queries release the GIL and run on all cores.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, as_real
from genplan.errors import GenplanError, SceneFileError, SettingsError, ShapeError
from genplan.clouds import check_points
from genplan.scene import Box, Capsule, Cylinder, HalfSpace, Mesh, Obstacle, Points, Scene, Sphere, load_scene


class CollisionWorld:
    """Collision and signed-distance queries for one robot among obstacles.

    Build it with :meth:`genplan.robots.Robot.collision_world`.
    """

    def __init__(self, native: _core.CollisionWorld) -> None:
        self._native = native
        self._nq = native.model.nq
        # the hot calls without a Python frame in between: on an instance, in_collision and
        # min_distance are the native methods themselves (documented by the methods below,
        # which call them; benches/boundary.py)
        self.__dict__["in_collision"] = native.in_collision
        self.__dict__["min_distance"] = native.min_distance

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

    @property
    def padding(self) -> float:
        """The clearance (m) the robot (its links and attached objects) keeps from every obstacle
        without a padding of its own (default 0): a pair closer than that is a collision for
        :meth:`in_collision`, plans, certified motions and trajectories (self pairs are not
        padded; :meth:`min_distance` stays the geometric distance). Set it to a finite distance
        in [0, 10] m (a GenplanError naming ``padding`` otherwise)."""
        return float(self._native.padding)

    @padding.setter
    def padding(self, value: float) -> None:
        self._native.padding = as_real(value, "padding")

    def set_obstacle_padding(self, name: str, padding: float | None) -> None:
        """Give obstacle ``name`` its own padding (m, in [0, 10]), which replaces the world's
        :attr:`padding` for it; None: the world's again. A scene file's obstacle takes it as
        ``padding = 0.02``."""
        self._native.set_obstacle_padding(name, None if padding is None else as_real(padding, f"obstacle '{name}' padding"))

    @property
    def obstacle_paddings(self) -> dict[str, float | None]:
        """Each obstacle's own padding (None: the world's)."""
        return dict(self._native.obstacle_paddings)

    @property
    def attached(self) -> list[tuple[str, str, list[str]]]:
        """The robot's attached objects (:meth:`genplan.robots.Robot.with_attached`) in this
        world: (name, holding link, touch links: the links never checked against it)."""
        return list(self._native.attached)

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

    def add_cylinder(
        self,
        name: str,
        radius: float,
        half_height: float,
        center: ArrayLike,
        rotation: ArrayLike | None = None,
    ) -> None:
        """Add a solid cylinder of ``radius`` (m) whose axis is the local z axis (as in URDF),
        spanning ``half_height`` either side of ``center``; optional 3x3 ``rotation``."""
        rot = None if rotation is None else _matrix3(rotation, f"cylinder '{name}' rotation")
        self._native.add_cylinder(name, as_real(radius, f"cylinder '{name}' radius"),
                                  as_real(half_height, f"cylinder '{name}' half_height"),
                                  _vec3(center, f"cylinder '{name}' center"), rot)

    def add_capsule(
        self,
        name: str,
        radius: float,
        half_length: float,
        center: ArrayLike,
        rotation: ArrayLike | None = None,
    ) -> None:
        """Add a capsule: the points within ``radius`` (m) of a segment along the local z axis from
        ``-half_length`` to ``+half_length`` about ``center``; optional 3x3 ``rotation``."""
        rot = None if rotation is None else _matrix3(rotation, f"capsule '{name}' rotation")
        self._native.add_capsule(name, as_real(radius, f"capsule '{name}' radius"),
                                 as_real(half_length, f"capsule '{name}' half_length"),
                                 _vec3(center, f"capsule '{name}' center"), rot)

    def add_mesh(
        self,
        name: str,
        path: str | os.PathLike[str],
        scale: ArrayLike | float = 1.0,
        center: ArrayLike = (0.0, 0.0, 0.0),
        rotation: ArrayLike | None = None,
        shape: str = "hull",
    ) -> None:
        """Add a mesh file (STL, OBJ or Collada, as the robot's meshes), scaled per axis by
        ``scale`` (one number or three) in the file's frame, then placed at ``center`` with
        optional 3x3 ``rotation``, as ``shape`` says (:data:`genplan.scene.MESH_SHAPES`: its convex
        hull, its triangles (a closed mesh a solid, an open one a surface) or convex parts). A
        missing file raises FileNotFoundError, a malformed one (or one that cannot be made into
        the shape) RobotFileError, both naming the file; an unknown shape UnknownNameError."""
        rot = None if rotation is None else _matrix3(rotation, f"mesh '{name}' rotation")
        sc = as_float_array(scale, f"mesh '{name}' scale")
        if sc.ndim == 0:
            sc = np.full(3, float(sc))
        self._native.add_mesh(name, os.fspath(path), _vec3(sc, f"mesh '{name}' scale"),
                              _vec3(center, f"mesh '{name}' center"), rot, shape=shape)

    def add_scene(self, scene: Scene | str | os.PathLike[str]) -> list[str]:
        """Add every obstacle of a scene: a :class:`~genplan.scene.Scene`, a shipped scene's name
        (:func:`genplan.scene.scene_names`) or a scene file (docs/SCENES.md). All or nothing: the
        scene is checked first (a name already in the world, a missing mesh file:
        :class:`~genplan.errors.SceneFileError`), and if the native world refuses an obstacle part
        way (e.g. a malformed mesh) the ones already added are removed before the error, a
        SceneFileError naming the scene and the obstacle, is raised. Returns the names added."""
        s = load_scene(scene)
        s.check_files()
        where = s._origin()
        existing = set(self.obstacle_names)
        for o in s.obstacles:
            if o.name in existing:
                raise SceneFileError(f"{where}: {o.kind} '{o.name}': an obstacle of that name is already in the world")
        added: list[str] = []
        try:
            for o in s.obstacles:
                _add(self, o)
                added.append(o.name)
                if o.padding is not None:
                    self.set_obstacle_padding(o.name, o.padding)
        except (GenplanError, OSError) as exc:
            for name in reversed(added):
                self._native.remove_obstacle(name)
            raise SceneFileError(f"{where}: {o.kind} '{o.name}': {exc}") from exc
        return added

    def add_halfspace(self, name: str, normal: ArrayLike, offset: float) -> None:
        """Add the solid half-space below the plane ``normal . x = offset``."""
        self._native.add_halfspace(name, _vec3(normal, f"plane '{name}' normal"), as_real(offset, f"plane '{name}' offset"))

    def add_points(self, name: str, points: ArrayLike, radius: float, voxel: float | None = None, *,
                   robot_q: ArrayLike | None = None, robot_margin: float = 0.02) -> int:
        """Add a point cloud, ``points`` (n, 3) in the world frame, each point a ball of ``radius``
        (m), down-sampled first to one point per ``voxel`` (m: the centroid of the points in
        each cube of that edge) when given. With ``robot_q``, the points within ``robot_margin``
        of the robot's own geometry at that configuration (a camera's view of the arm) are
        dropped first (:meth:`robot_points`). Every query treats the cloud as one obstacle
        (docs/SCENES.md "Point clouds and depth images"). Checked before any work: ShapeError
        (shape, an empty cloud), NonFiniteError (naming the row), SettingsError (radius,
        voxel). Returns the number of balls kept."""
        pts = self._cloud(name, points, robot_q, robot_margin)
        r = _positive(radius, f"points '{name}' radius")
        v = None if voxel is None else _positive(voxel, f"points '{name}' voxel")
        self._native.add_points(name, pts, r, v)
        return int(self._native.clouds[name][2])

    def replace_points(self, name: str, points: ArrayLike, *, robot_q: ArrayLike | None = None,
                       robot_margin: float = 0.02) -> int:
        """Replace cloud ``name``'s points with a new frame (checked as :meth:`add_points`' are),
        keeping its radius, voxel and place; a bad frame leaves the old one. Returns the number
        of balls kept."""
        pts = self._cloud(name, points, robot_q, robot_margin)
        self._native.replace_points(name, pts)
        return int(self._native.clouds[name][2])

    def robot_points(self, points: ArrayLike, q: ArrayLike, margin: float = 0.02) -> NDArray[np.bool_]:
        """True for each point of ``points`` (n, 3) within ``margin`` (m) of the robot's collision
        geometry at configuration ``q``: the robot as its own camera sees it."""
        pts = np.ascontiguousarray(as_float_array(points, "points"), dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ShapeError(f"points: expected an array of shape (n, 3), got shape {pts.shape}")
        qa = as_configurations(q, self._nq)
        if qa.ndim != 1:
            raise ShapeError(f"q: expected one configuration of shape ({self._nq},), got {qa.shape}")
        m = as_real(margin, "margin")
        if not (np.isfinite(m) and m >= 0):
            raise SettingsError(f"margin must be a finite distance >= 0 (m), got {margin!r}")
        return self._native.robot_points(list(qa), pts, m)

    @property
    def clouds(self) -> dict[str, tuple[float, float | None, int]]:
        """The point clouds: {name: (radius, voxel or None, number of balls)}."""
        return dict(self._native.clouds)

    def _cloud(self, name: str, points: ArrayLike, robot_q: ArrayLike | None, margin: float) -> NDArray[np.float64]:
        pts = check_points(points, f"points '{name}' points")
        if robot_q is not None:
            pts = np.ascontiguousarray(pts[~self.robot_points(pts, robot_q, margin)])
            if len(pts) == 0:
                raise ShapeError(f"points '{name}' points: every point lies on the robot (robot_margin {margin})")
        return pts

    def remove_obstacle(self, name: str) -> None:
        self._native.remove_obstacle(name)

    def clear_obstacles(self) -> None:
        self._native.clear_obstacles()

    @overload
    def in_collision(self, q: Sequence[float]) -> bool: ...
    @overload
    def in_collision(self, q: NDArray[np.float64]) -> Any: ...
    def in_collision(self, q: Any) -> Any:
        """True where q collides (self or obstacles). (nq,) -> bool, (n, nq) -> bool array.
        q is read and checked in Rust as :func:`genplan._arrays.as_configurations` does."""
        return self._native.in_collision(q)

    def min_distance(self, q: Any) -> Any:
        """Minimum signed distance in m (negative: penetration depth). (nq,) -> float, (n, nq) -> array.
        q is read and checked in Rust as :func:`genplan._arrays.as_configurations` does."""
        return self._native.min_distance(q)

    def close_pairs(self, q: ArrayLike, margin: float = 0.0) -> list[tuple[str, str, float]]:
        """Pairs closer than ``margin`` at one configuration, closest first."""
        qa = as_configurations(q, self._nq)
        if qa.ndim != 1:
            raise ShapeError(f"q: close_pairs takes one configuration of shape ({self._nq},), got {qa.shape}")
        return self._native.close_pairs(list(qa), as_real(margin, "margin"))

    def point_distances(self, points: ArrayLike, cutoff: float = 1.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Signed distances of points ``(..., 3)`` to the nearest obstacle (negative inside one)
        and their gradients ``(..., 3)`` (unit vectors away from the nearest obstacle): the
        clearance of spheres covering a robot, natively (GIL released). Obstacles ``cutoff`` (m)
        or more away are skipped: a point with none nearer gets ``cutoff`` and a zero gradient.
        Mesh obstacles are the shapes every query of the world sees (:data:`genplan.scene.MESH_SHAPES`)."""
        pts = np.ascontiguousarray(as_float_array(points, "points"), dtype=np.float64)
        if pts.ndim < 1 or pts.shape[-1] != 3:
            raise ShapeError(f"points: expected a last axis of 3 (x, y, z), got shape {pts.shape}")
        cut = as_real(cutoff, "cutoff")
        if not (np.isfinite(cut) and cut > 0):
            raise SettingsError(f"cutoff must be a positive finite distance (m), got {cutoff!r}")
        d, g = self._native.point_distances(pts, cut)
        return d, g

    def __repr__(self) -> str:
        return repr(self._native)


def _add(world: CollisionWorld, o: Obstacle) -> None:
    """Add one scene obstacle (checked when it was built) to ``world``."""
    if isinstance(o, HalfSpace):
        world.add_halfspace(o.name, o.normal, o.offset)
        return
    pose = o.pose
    rot = pose.matrix() if pose.rotated else None
    if isinstance(o, Box):
        world.add_box(o.name, o.half_extents, pose.position, rot)
    elif isinstance(o, Sphere):
        world.add_sphere(o.name, o.radius, pose.position)
    elif isinstance(o, Cylinder):
        world.add_cylinder(o.name, o.radius, o.length / 2, pose.position, rot)
    elif isinstance(o, Capsule):
        world.add_capsule(o.name, o.radius, o.length / 2, pose.position, rot)
    elif isinstance(o, Mesh):
        world.add_mesh(o.name, o.path, o.scale, pose.position, rot, shape=o.shape)
    elif isinstance(o, Points):
        world.add_points(o.name, o.world_points(), o.radius, o.voxel)
    else:  # Scene refuses anything else
        raise SceneFileError(f"{o!r} is not an obstacle")


def _positive(v: Any, what: str) -> float:
    x = as_real(v, what, error=SettingsError)
    if not (np.isfinite(x) and 0 < x <= 1e6):
        raise SettingsError(f"{what} must be positive and at most 1e6 m, got {v!r}")
    return x


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
