"""Scenes as data: the obstacles of a planning environment in a TOML file (docs/SCENES.md).

A scene is a name, a description and obstacles, each with a unique name:

* :class:`Box` (half extents, or ``size`` = full edge lengths in a file), :class:`Sphere`,
  :class:`Cylinder` and :class:`Capsule` (``radius`` and the full ``length`` along the local z
  axis, as in URDF), :class:`Mesh` (an STL, OBJ or Collada file, used as its convex hull, its
  triangles or convex parts: ``shape``, :data:`MESH_SHAPES`), each placed by a :class:`Pose`;
* :class:`HalfSpace` (everything below the plane ``normal . x = offset``, e.g. a floor);
* :class:`Points` (a point cloud, each point a ball of ``radius``: a ``.npz``, ``.ply`` or
  ``.pcd`` file, or inline ``points``; :func:`points_from_depth` makes one from a depth image).

A file lists them as arrays of tables::

    name = "workbench"
    description = "a table and a post"

    [[box]]
    name = "table"
    size = [1.0, 1.5, 0.05]
    position = [0.7, 0.0, 0.1]

    [[cylinder]]
    name = "post"
    radius = 0.05
    length = 1.2
    position = [0.4, 0.5, 0.6]
    rpy = [0.0, 0.0, 0.0]

    [[halfspace]]
    name = "floor"
    normal = [0.0, 0.0, 1.0]
    offset = 0.0

A pose is ``position`` plus at most one of ``rpy`` (roll, pitch, yaw in radians: R = Rz(yaw)
Ry(pitch) Rx(roll), URDF's convention), ``quaternion`` (x, y, z, w) or ``rotation`` (3x3 rows).
A mesh's ``path`` is relative to the scene file. A ``[queries]`` table is left for the planning
environments (:mod:`genplan.planning.environments`) and ignored here.

:meth:`Scene.from_file` checks everything (unknown keys and shape tables, missing fields, wrong
lengths, NaN, non-positive sizes, missing mesh files, duplicate names) and raises
:class:`~genplan.errors.SceneFileError` naming the file, the table and the field;
:meth:`genplan.collision.CollisionWorld.add_scene` adds a scene (or a shipped scene's name, or a
file) all or nothing. Obstacles are kept grouped by shape, in the order of :data:`SHAPES`
(the order a file is read in), so ``from_dict(to_dict())`` and ``from_file(to_file())`` give
back an equal scene.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Union

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan.cache import cache_dir
from genplan.clouds import POINT_EXTENSIONS, camera_pose, points_from_depth, read_points
from genplan.errors import SceneFileError, UnknownNameError

__all__ = [
    "MAX_OBSTACLE_EXTENT",
    "MESH_EXTENSIONS",
    "MESH_SHAPES",
    "SCENES_DIR",
    "SHAPES",
    "Box",
    "Capsule",
    "Cylinder",
    "HalfSpace",
    "Mesh",
    "Obstacle",
    "Points",
    "Pose",
    "Scene",
    "Sphere",
    "camera_pose",
    "load_scene",
    "points_from_depth",
    "scene_names",
]

#: The largest obstacle size (half extent, radius, half length, mesh scale) and absolute
#: coordinate of a position or offset, in m: the native world's limit
#: (``MAX_OBSTACLE_EXTENT`` in rust/core/src/collision/world.rs).
MAX_OBSTACLE_EXTENT = 1e6
#: How far a quaternion's norm may be from 1 (it is normalised) and a rotation matrix from
#: orthonormal (``pose_from`` in rust/python/src/lib.rs uses the same 1e-6).
QUATERNION_TOLERANCE = 1e-3
ROTATION_TOLERANCE = 1e-6
#: A half-space normal no longer than this is refused as zero (``MIN_NORMAL_NORM`` in world.rs).
MIN_NORMAL_NORM = 1e-12
#: Mesh file extensions the native reader takes (``SUPPORTED_EXTENSIONS`` in rust/core/src/mesh.rs).
MESH_EXTENSIONS = ("stl", "obj", "dae")
#: What a mesh becomes (``MeshShape::NAMES`` in rust/core/src/collision/geometry.rs): ``"hull"``
#: (its convex hull, the default), ``"mesh"`` (its triangles: a closed mesh is a solid, an open one
#: a surface), ``"decomposed"`` (V-HACD's convex parts). docs/SCENES.md says when to use which.
MESH_SHAPES: tuple[str, ...] = tuple(_core.MESH_SHAPES)
# V-HACD decompositions ("decomposed", scenes' and robots' meshes) take seconds per mesh: the
# core keeps them in the cache folder, one file per mesh and parameters, written atomically
_core.set_decomposition_cache(str(cache_dir() / "decompositions"))
#: The shipped scenes (their stem is the name :func:`load_scene` takes).
SCENES_DIR = Path(__file__).parent / "presets" / "scenes"

_POSE_KEYS = ("position", "rpy", "quaternion", "rotation")


# --- value checks: each returns the value in canonical form or raises SceneFileError naming `what`


def _real(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise SceneFileError(f"{what}: expected a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise SceneFileError(f"{what}: must be finite, got {x}")
    return x


def _vector(v: Any, n: int, what: str) -> tuple[float, ...]:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (str, bytes)) or not isinstance(v, Sequence):
        raise SceneFileError(f"{what}: expected a list of {n} numbers, got {v!r}")
    if len(v) != n:
        raise SceneFileError(f"{what}: expected {n} numbers, got {len(v)}")
    return tuple(_real(x, f"{what}[{i}]") for i, x in enumerate(v))


def _size(v: Any, what: str, limit: float = MAX_OBSTACLE_EXTENT) -> float:
    x = _real(v, what)
    if not (0.0 < x <= limit):
        raise SceneFileError(f"{what}: must be positive and at most {limit:g}, got {x}")
    return x


#: The largest clearance margin an obstacle may ask for (m; the core's ``MAX_PADDING``).
MAX_PADDING = 10.0


def _padding(v: Any, what: str) -> float:
    """An obstacle's clearance margin (m): finite, in [0, :data:`MAX_PADDING`]."""
    x = _real(v, what)
    if not 0.0 <= x <= MAX_PADDING:
        raise SceneFileError(f"{what}: must be a distance in [0, {MAX_PADDING:g}] m, got {x}")
    return x


def _name(v: Any, what: str) -> str:
    if not isinstance(v, str) or not v:
        raise SceneFileError(f"{what}: expected a non-empty string, got {v!r}")
    return v


def _position(v: Any, what: str) -> tuple[float, float, float]:
    p = _vector(v, 3, what)
    if any(abs(x) > MAX_OBSTACLE_EXTENT for x in p):
        raise SceneFileError(f"{what}: each coordinate must be within {MAX_OBSTACLE_EXTENT:g} m of the origin, got {list(p)}")
    return p  # type: ignore[return-value]


def _rpy_matrix(r: float, p: float, y: float) -> NDArray[np.float64]:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _quaternion_matrix(q: Sequence[float]) -> NDArray[np.float64]:
    x, y, z, w = np.asarray(q, dtype=np.float64) / math.sqrt(sum(c * c for c in q))
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


@dataclass(frozen=True)
class Pose:
    """Where a shape sits: ``position`` (m) and at most one of ``rpy`` (roll, pitch, yaw in rad,
    R = Rz(yaw) Ry(pitch) Rx(roll)), ``quaternion`` (x, y, z, w; its norm within 1e-3 of 1, then
    normalised) or ``rotation`` (3x3, rows; orthonormal within 1e-6, determinant +1). The form
    given is kept (and written back to a file as given); :meth:`matrix` is the rotation."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] | None = None
    quaternion: tuple[float, float, float, float] | None = None
    rotation: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position", _position(self.position, "position"))
        given = [k for k in ("rpy", "quaternion", "rotation") if getattr(self, k) is not None]
        if len(given) > 1:
            raise SceneFileError(f"{' and '.join(given)}: give at most one of rpy, quaternion, rotation")
        if self.rpy is not None:
            set_(self, "rpy", _vector(self.rpy, 3, "rpy"))
        if self.quaternion is not None:
            q = _vector(self.quaternion, 4, "quaternion")
            norm = math.sqrt(sum(c * c for c in q))
            if abs(norm - 1.0) > QUATERNION_TOLERANCE:
                raise SceneFileError(f"quaternion: must be a unit quaternion (x, y, z, w), got norm {norm:.6g}")
            set_(self, "quaternion", q)
        if self.rotation is not None:
            rows = self.rotation.tolist() if isinstance(self.rotation, np.ndarray) else self.rotation
            if isinstance(rows, (str, bytes)) or not isinstance(rows, Sequence) or len(rows) != 3:
                raise SceneFileError(f"rotation: expected 3 rows of 3 numbers, got {self.rotation!r}")
            m = tuple(_vector(r, 3, f"rotation[{i}]") for i, r in enumerate(rows))
            a = np.array(m)
            off = float(np.abs(a.T @ a - np.eye(3)).max())
            if off > ROTATION_TOLERANCE or abs(np.linalg.det(a) - 1.0) > ROTATION_TOLERANCE:
                raise SceneFileError(f"rotation: not a proper rotation matrix (|R^T R - I| = {off:.3g}, det {np.linalg.det(a):.6g})")
            set_(self, "rotation", m)

    @property
    def rotated(self) -> bool:
        """True when a rotation (in any form) was given."""
        return self.rpy is not None or self.quaternion is not None or self.rotation is not None

    def matrix(self) -> NDArray[np.float64]:
        """The 3x3 rotation (the identity when none was given)."""
        if self.rpy is not None:
            return _rpy_matrix(*self.rpy)
        if self.quaternion is not None:
            return _quaternion_matrix(self.quaternion)
        if self.rotation is not None:
            return np.array(self.rotation, dtype=np.float64)
        return np.eye(3)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"position": list(self.position)}
        for k in ("rpy", "quaternion"):
            if getattr(self, k) is not None:
                d[k] = list(getattr(self, k))
        if self.rotation is not None:
            d["rotation"] = [list(r) for r in self.rotation]
        return d


def _pose(v: Any) -> Pose:
    if not isinstance(v, Pose):
        raise SceneFileError(f"pose: expected a Pose, got {v!r}")
    return v


class _Shape:
    """What every obstacle class shares: ``kind`` (its table name in a file), the fields a file
    gives besides the pose, and the checks run on construction."""

    kind: ClassVar[str]
    #: required and optional keys of the file's table (the pose keys come on top, but for a half-space)
    required: ClassVar[tuple[str, ...]]
    optional: ClassVar[tuple[str, ...]] = ()
    name: str

    def _check(self, checks: Mapping[str, Any]) -> None:
        """Set each field to its checked value; an error is prefixed with the obstacle."""
        what = f"{self.kind} '{getattr(self, 'name', '?')}'"
        try:
            object.__setattr__(self, "name", _name(self.name, "name"))
            for key, fn in checks.items():
                object.__setattr__(self, key, fn(getattr(self, key), key))
            if getattr(self, "padding", None) is not None:
                object.__setattr__(self, "padding", _padding(self.padding, "padding"))
        except SceneFileError as exc:
            raise SceneFileError(f"{what}: {exc}") from None

    @classmethod
    def known_keys(cls) -> tuple[str, ...]:
        return ("name", *cls.required, *cls.optional, "padding", *(() if cls.kind == "halfspace" else _POSE_KEYS))


@dataclass(frozen=True)
class Box(_Shape):
    """A box of ``half_extents`` (m) centred at the pose. A file gives ``half_extents`` or ``size``
    (full edge lengths, as URDF's ``<box size>``)."""

    kind: ClassVar[str] = "box"
    required: ClassVar[tuple[str, ...]] = ("half_extents",)
    optional: ClassVar[tuple[str, ...]] = ("size",)
    name: str
    half_extents: tuple[float, float, float]
    pose: Pose = field(default_factory=Pose)
    padding: float | None = None

    def __post_init__(self) -> None:
        self._check({"half_extents": lambda v, k: tuple(_size(x, f"{k}[{i}]") for i, x in enumerate(_vector(v, 3, k))),
                     "pose": lambda v, k: _pose(v)})


@dataclass(frozen=True)
class Sphere(_Shape):
    """A ball of ``radius`` (m) centred at the pose's position (its rotation does nothing)."""

    kind: ClassVar[str] = "sphere"
    required: ClassVar[tuple[str, ...]] = ("radius",)
    name: str
    radius: float
    pose: Pose = field(default_factory=Pose)
    padding: float | None = None

    def __post_init__(self) -> None:
        self._check({"radius": _size, "pose": lambda v, k: _pose(v)})


@dataclass(frozen=True)
class _Rod(_Shape):
    """A shape of ``radius`` and ``length`` (m) along the pose's local z axis, centred at its
    position: what a cylinder and a capsule share."""

    required: ClassVar[tuple[str, ...]] = ("radius", "length")
    name: str
    radius: float
    length: float
    pose: Pose = field(default_factory=Pose)
    padding: float | None = None

    def __post_init__(self) -> None:
        self._check({"radius": _size, "length": lambda v, k: _size(v, k, 2 * MAX_OBSTACLE_EXTENT),
                     "pose": lambda v, k: _pose(v)})


@dataclass(frozen=True)
class Cylinder(_Rod):
    """A solid cylinder of ``radius`` and full ``length`` (m) along the pose's local z axis,
    centred at its position (URDF's ``<cylinder>``)."""

    kind: ClassVar[str] = "cylinder"


@dataclass(frozen=True)
class Capsule(_Rod):
    """The points within ``radius`` of a segment of ``length`` (m) along the pose's local z axis,
    centred at its position (URDF's capsule: ``length`` between the two sphere centres)."""

    kind: ClassVar[str] = "capsule"


def _file_path(v: Any, what: str, extensions: Any, kind: str) -> Path:
    """``v`` as an absolute path whose suffix is one of ``extensions``, else SceneFileError."""
    if not isinstance(v, (str, os.PathLike)) or not str(v):
        raise SceneFileError(f"{what}: expected a file path, got {v!r}")
    p = Path(os.path.normpath(os.path.abspath(v)))
    if p.suffix.lower().lstrip(".") not in extensions:
        raise SceneFileError(f"{what}: {p} is not a {kind} file ({', '.join('.' + e for e in extensions)})")
    return p


def _mesh_path(v: Any, what: str) -> Path:
    return _file_path(v, what, MESH_EXTENSIONS, "mesh")


def _scale(v: Any, what: str) -> tuple[float, float, float]:
    if not isinstance(v, (Sequence, np.ndarray)) or isinstance(v, (str, bytes)):
        v = (v, v, v)
    return tuple(_size(x, f"{what}[{i}]") for i, x in enumerate(_vector(v, 3, what)))  # type: ignore[return-value]


def _mesh_shape(v: Any, what: str) -> str:
    if v not in MESH_SHAPES:
        raise SceneFileError(f"{what}: unknown mesh shape {v!r} (known: {', '.join(MESH_SHAPES)})")
    return str(v)


@dataclass(frozen=True)
class Mesh(_Shape):
    """A mesh file (STL, OBJ or Collada), scaled per axis by ``scale`` (one number or three) in
    the file's frame, then placed at the pose, used as ``shape`` says (:data:`MESH_SHAPES`): its
    convex hull (``"hull"``, the default), its triangles (``"mesh"``: a closed mesh is a solid, an
    open one a surface) or convex parts (``"decomposed"``). ``path`` is kept absolute (a relative
    one is taken from the current folder here, from the scene file's folder in a file); the file
    must exist when the scene is read or added to a world."""

    kind: ClassVar[str] = "mesh"
    required: ClassVar[tuple[str, ...]] = ("path",)
    optional: ClassVar[tuple[str, ...]] = ("scale", "shape")
    name: str
    path: Path
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    pose: Pose = field(default_factory=Pose)
    shape: str = "hull"
    padding: float | None = None

    def __post_init__(self) -> None:
        self._check({"path": _mesh_path, "scale": _scale, "pose": lambda v, k: _pose(v), "shape": _mesh_shape})


@dataclass(frozen=True)
class HalfSpace(_Shape):
    """Everything below the plane ``n . x = offset``, n the unit vector along ``normal`` (the
    solid's outward normal): a floor is ``normal = (0, 0, 1), offset = height``."""

    kind: ClassVar[str] = "halfspace"
    required: ClassVar[tuple[str, ...]] = ("normal", "offset")
    name: str
    normal: tuple[float, float, float]
    offset: float
    padding: float | None = None

    def __post_init__(self) -> None:
        def normal(v: Any, k: str) -> tuple[float, ...]:
            n = _vector(v, 3, k)
            if math.hypot(*n) <= MIN_NORMAL_NORM:
                raise SceneFileError(f"{k}: must not be zero, got {list(n)}")
            return n

        def offset(v: Any, k: str) -> float:
            x = _real(v, k)
            if abs(x) > MAX_OBSTACLE_EXTENT:
                raise SceneFileError(f"{k}: must be at most {MAX_OBSTACLE_EXTENT:g} in absolute value, got {x}")
            return x

        self._check({"normal": normal, "offset": offset})


def _points_path(v: Any, what: str) -> Path | None:
    return None if v is None else _file_path(v, what, POINT_EXTENSIONS, "point-cloud")


def _inline_points(v: Any, what: str) -> tuple[tuple[float, float, float], ...] | None:
    if v is None:
        return None
    if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)):
        raise SceneFileError(f"{what}: expected a list of [x, y, z] points, got {v!r}")
    if len(v) == 0:
        raise SceneFileError(f"{what}: the cloud is empty (a cloud needs at least one point)")
    return tuple(_position(p, f"{what}[{i}]") for i, p in enumerate(v))


@dataclass(frozen=True)
class Points(_Shape):
    """A point cloud, each point a ball of ``radius`` (m): the points of a file ``path``
    (:func:`genplan.clouds.read_points`: ``.npz`` with an array ``points``, ``.ply``, ``.pcd``;
    relative to the scene file's folder in a file) or given inline as ``points`` (a list of
    [x, y, z]), exactly one of the two, in the frame of the pose (e.g. the camera's; default the
    world's), down-sampled to one point per ``voxel`` (m) when given. The file is read when
    the scene is added to a world (:meth:`world_points`)."""

    kind: ClassVar[str] = "points"
    required: ClassVar[tuple[str, ...]] = ("radius",)
    optional: ClassVar[tuple[str, ...]] = ("path", "points", "voxel")
    name: str
    radius: float
    path: Path | None = None
    points: tuple[tuple[float, float, float], ...] | None = None
    voxel: float | None = None
    pose: Pose = field(default_factory=Pose)
    padding: float | None = None

    def __post_init__(self) -> None:
        self._check({"radius": _size, "path": _points_path, "points": _inline_points,
                     "voxel": lambda v, k: None if v is None else _size(v, k),
                     "pose": lambda v, k: _pose(v)})
        if (self.path is None) == (self.points is None):
            raise SceneFileError(f"points '{self.name}': give exactly one of path and points")

    def world_points(self) -> NDArray[np.float64]:
        """The cloud's points (n, 3) in the world frame (the file read now)."""
        try:
            local = read_points(self.path, f"points '{self.name}' path") if self.path is not None \
                else np.asarray(self.points, dtype=np.float64)
        except FileNotFoundError as exc:
            raise SceneFileError(str(exc)) from None
        if not self.pose.rotated and not any(self.pose.position):
            return np.ascontiguousarray(local)
        return np.ascontiguousarray(local @ self.pose.matrix().T + np.asarray(self.pose.position))


Obstacle = Union[Box, Sphere, Cylinder, Capsule, Mesh, HalfSpace, Points]
#: The obstacle classes by their table name in a file, in the order a scene keeps them.
SHAPES: dict[str, type[_Shape]] = {c.kind: c for c in (Box, Sphere, Cylinder, Capsule, Mesh, HalfSpace, Points)}
_TOP_KEYS = ("name", "description", *SHAPES, "queries")


@dataclass(frozen=True)
class Scene:
    """A named set of obstacles (unique names), grouped by shape in the order of :data:`SHAPES`
    (the order :meth:`from_file` reads and ``add_scene`` adds them). ``source`` is the file it was
    read from, if any (not part of equality)."""

    name: str
    obstacles: tuple[Obstacle, ...] = ()
    description: str = ""
    source: Path | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        where = f"scene '{self.name}'"
        _name(self.name, f"{where}: name")
        if not isinstance(self.description, str):
            raise SceneFileError(f"{where}: description: expected a string, got {self.description!r}")
        obstacles = tuple(self.obstacles)
        order = list(SHAPES.values())
        for o in obstacles:
            if type(o) not in order:
                raise SceneFileError(f"{where}: {o!r} is not an obstacle ({', '.join(c.__name__ for c in order)})")
        seen: dict[str, str] = {}
        for o in obstacles:
            if o.name in seen:
                raise SceneFileError(f"{where}: duplicate obstacle name '{o.name}' ({seen[o.name]} and {o.kind})")
            seen[o.name] = o.kind
        object.__setattr__(self, "obstacles", tuple(sorted(obstacles, key=lambda o: order.index(type(o)))))

    @property
    def obstacle_names(self) -> list[str]:
        return [o.name for o in self.obstacles]

    def check_files(self) -> None:
        """SceneFileError unless every mesh file exists."""
        for o in self.obstacles:
            if isinstance(o, Mesh) and not o.path.is_file():
                raise SceneFileError(f"{self._origin()}: mesh '{o.name}': path: mesh file {o.path} does not exist")
            if isinstance(o, Points) and o.path is not None and not o.path.is_file():
                raise SceneFileError(f"{self._origin()}: points '{o.name}': path: points file {o.path} does not exist")

    def _origin(self) -> str:
        return f"scene file {self.source}" if self.source is not None else f"scene '{self.name}'"

    # --- plain data and files

    def to_dict(self) -> dict[str, Any]:
        """Plain data (TOML's form: a list of tables per shape); :meth:`from_dict` reads it back."""
        d: dict[str, Any] = {"name": self.name}
        if self.description:
            d["description"] = self.description
        for kind in SHAPES:
            rows = [_obstacle_dict(o) for o in self.obstacles if o.kind == kind]
            if rows:
                d[kind] = rows
        return d

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | os.PathLike[str] | None = None,
                  origin: str = "scene", source: Path | None = None) -> Scene:
        """A scene from plain data (:meth:`to_dict`'s form). Relative mesh paths are taken from
        ``base_dir`` (default: the current folder); every mesh file must exist. Errors
        (:class:`~genplan.errors.SceneFileError`) start with ``origin``."""
        if not isinstance(data, Mapping):
            raise SceneFileError(f"{origin}: expected a table, got {type(data).__name__}")
        for key, value in data.items():
            if key in _TOP_KEYS:
                continue
            if isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
                raise SceneFileError(f"{origin}: unknown shape table [[{key}]] (known shapes: {', '.join(SHAPES)})")
            raise SceneFileError(f"{origin}: unknown key '{key}' (known: {', '.join(_TOP_KEYS)})")
        if "name" not in data:
            raise SceneFileError(f"{origin}: missing field 'name'")
        name = _prefixed(origin, lambda: _name(data["name"], "name"))
        obstacles: list[_Shape] = []
        for kind, shape in SHAPES.items():
            rows = data.get(kind, [])
            if not isinstance(rows, list) or not all(isinstance(r, Mapping) for r in rows):
                raise SceneFileError(f"{origin}: '{kind}' must be a list of [[{kind}]] tables")
            for i, row in enumerate(rows):
                obstacles.append(_obstacle_from_dict(shape, row, f"{origin}: [[{kind}]] {i + 1}", base_dir))
        description = data.get("description", "")
        try:
            scene = cls(name=name, obstacles=tuple(obstacles), description=description, source=source)  # type: ignore[arg-type]
        except SceneFileError as exc:
            raise SceneFileError(f"{origin}: {exc}") from None
        scene.check_files()
        return scene

    def to_file(self, path: str | os.PathLike[str]) -> Path:
        """Write the scene as a scene file (TOML), atomically; mesh paths are written relative to
        the file's folder. :meth:`from_file` reads back an equal scene."""
        from genplan._files import write_text

        folder = Path(os.path.abspath(path)).parent
        data = self.to_dict()
        for row in [*data.get("mesh", []), *(r for r in data.get("points", []) if "path" in r)]:
            try:
                row["path"] = Path(os.path.relpath(row["path"], folder)).as_posix()
            except ValueError:  # another drive: keep it absolute
                pass
        return write_text(path, _toml(data))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> Scene:
        """Read a scene file (TOML); the name defaults to the file's stem. Errors name the file,
        the table and the field."""
        from genplan._files import read_toml

        path = Path(path)
        data = read_toml(path, "scene", SceneFileError)
        return cls.from_dict(data, base_dir=Path(os.path.abspath(path)).parent, origin=f"scene file {path}", source=path)


def _prefixed(origin: str, fn: Any) -> Any:
    try:
        return fn()
    except SceneFileError as exc:
        raise SceneFileError(f"{origin}: {exc}") from None


def _obstacle_from_dict(shape: type[_Shape], row: Mapping[str, Any], where: str,
                        base_dir: str | os.PathLike[str] | None) -> _Shape:
    known = shape.known_keys()
    for key in row:
        if key not in known:
            raise SceneFileError(f"{where}: unknown key '{key}' (known: {', '.join(known)})")
    fields = dict(row)
    if shape is Box:
        if "size" in fields and "half_extents" in fields:
            raise SceneFileError(f"{where}: give size or half_extents, not both")
        if "size" in fields:
            size = _prefixed(where, lambda: _vector(fields.pop("size"), 3, "size"))
            fields["half_extents"] = tuple(s / 2 for s in size)
    for key in ("name", *shape.required):
        if key not in fields:
            extra = " (or size)" if shape is Box and key == "half_extents" else ""
            raise SceneFileError(f"{where}: missing field '{key}'{extra}")
    where = f"{where} ('{fields['name']}')" if isinstance(fields["name"], str) else where
    if shape in (Mesh, Points) and base_dir is not None and isinstance(fields.get("path"), str):
        fields["path"] = Path(base_dir) / fields["path"]
    if shape is not HalfSpace:
        pose_fields = {k: fields.pop(k) for k in _POSE_KEYS if k in fields}
        try:
            fields["pose"] = Pose(**pose_fields)
        except SceneFileError as exc:
            raise SceneFileError(f"{where}: {exc}") from None
    try:
        return shape(**fields)
    except SceneFileError as exc:
        # the shape's message starts with "<kind> '<name>': "; the location already says so
        msg = str(exc).split(": ", 1)[-1]
        raise SceneFileError(f"{where}: {msg}") from None


def _obstacle_dict(o: _Shape) -> dict[str, Any]:
    d: dict[str, Any] = {"name": o.name}
    if isinstance(o, Box):
        d["half_extents"] = list(o.half_extents)
    elif isinstance(o, Sphere):
        d["radius"] = o.radius
    elif isinstance(o, (Cylinder, Capsule)):
        d["radius"], d["length"] = o.radius, o.length
    elif isinstance(o, Mesh):
        d["path"], d["scale"] = str(o.path), list(o.scale)
        if o.shape != "hull":
            d["shape"] = o.shape
    elif isinstance(o, HalfSpace):
        d["normal"], d["offset"] = list(o.normal), o.offset
    elif isinstance(o, Points):
        d["radius"] = o.radius
        if o.path is not None:
            d["path"] = str(o.path)
        else:
            d["points"] = [list(p) for p in o.points or ()]
        if o.voxel is not None:
            d["voxel"] = o.voxel
    pose = getattr(o, "pose", None)
    if pose is not None:
        d.update(pose.to_dict())
    if o.padding is not None:
        d["padding"] = o.padding
    return d


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v))  # finite: the checks refuse NaN and infinities
    if isinstance(v, str):
        import json

        return json.dumps(v)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise SceneFileError(f"cannot write {type(v).__name__} to a scene file")


def _toml(data: Mapping[str, Any]) -> str:
    """The TOML text of a scene's plain data (:meth:`Scene.to_dict`)."""
    lines = [f"name = {_toml_value(data['name'])}"]
    if "description" in data:
        lines.append(f"description = {_toml_value(data['description'])}")
    for kind in SHAPES:
        for row in data.get(kind, []):
            lines += ["", f"[[{kind}]]"] + [f"{k} = {_toml_value(v)}" for k, v in row.items()]
    return "\n".join(lines) + "\n"


def scene_names() -> tuple[str, ...]:
    """The shipped scene files' names (``panda_shelf``, ``talos_task1``, ...)."""
    return tuple(sorted(p.stem for p in SCENES_DIR.glob("*.toml")))


def load_scene(scene: str | os.PathLike[str] | Scene | Mapping[str, Any]) -> Scene:
    """A scene: a :class:`Scene` as is, a shipped scene's name (:func:`scene_names`), a scene file,
    or a scene's dict form (:meth:`Scene.to_dict`, as data sets and model cards record it)."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, Mapping):
        return Scene.from_dict(scene)
    if isinstance(scene, str) and scene in scene_names():
        return Scene.from_file(SCENES_DIR / f"{scene}.toml")
    if not isinstance(scene, (str, os.PathLike)):
        raise SceneFileError(f"expected a Scene, a shipped scene's name, a scene file or a scene's dict form, got "
                             f"{type(scene).__name__}")
    path = Path(scene)
    if path.suffix != ".toml" and not path.exists():
        raise UnknownNameError(f"unknown scene '{scene}' (shipped: {', '.join(scene_names())}; or a scene file .toml)")
    return Scene.from_file(path)
