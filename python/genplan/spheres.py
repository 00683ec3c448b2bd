"""Collision spheres for any robot: each link's collision geometry covered by a few spheres.

One generator serves every use of a robot's spheres (a differentiable clearance from a scene, a
vectorised collision check, a point cloud's distance to the robot)::

    import genplan
    from genplan.spheres import robot_spheres

    panda = genplan.load("panda")
    spheres = robot_spheres(panda)                  # cached on disk after the first call
    spheres.links, spheres.centers, spheres.radii   # (S,), (S, 3) in each link's frame, (S,)
    spheres.world_centers(panda, q)                 # (n, S, 3) through the robot's kinematics

**The guarantee.** Every point of a link's collision solid lies inside at least one sphere of
that link, by construction, not by sampling: the solid is the union of the link's geometries as
Pinocchio reads them from the collision URDF (:func:`link_geometries`): boxes, spheres,
cylinders and capsules as they are, meshes raw (not their convex hulls): a closed mesh with its
interior, an open mesh as its surface (plus the part of its inside a grid resolves). The radii
are then padded by ``padding`` (default 0.1 mm) so that the cover survives float32 kinematics.

**How.** Per link, on a grid of spacing ``resolution``:

1. each geometry becomes closed polyhedra containing it (a mesh as it is, one per connected
   shell; a primitive as a circumscribed polyhedron, at most ``max_error / 50`` larger), their
   triangles cut into pieces no longer than ``resolution`` (each split at its longest edge's
   midpoint until none is longer), and the grid's nodes classified inside
   or outside (signed ray crossings, exact for a closed mesh; the solid-angle winding number
   where a ray grazes an edge); pieces inside another geometry are no boundary of the union;
2. the solid is split into cells whose convex hulls cover it: a grid cube that no boundary piece
   meets and whose corners are inside (merged into blocks of 4 x 4 x 4 where possible) is the
   convex hull of its corners; for a cube that boundary pieces meet, the cell is its corners inside
   the solid and the vertices of the pieces' parts in the cube (each piece clipped to it): the
   extreme points of the cube's part of the solid are among them. A ball holding a cell's points
   holds its convex hull, so a sphere holding the points of each of its cells covers them exactly;
3. candidate spheres sit near the solid's medial axis (grid nodes where the depth stops growing
   at the rate 1 (a sphere elsewhere is held by a deeper one that reaches no farther out), moved
   deeper, and the primitives' own axes), each of radius ``depth + max_error``, reaching at most
   ``max_error`` beyond the solid; a candidate that a larger one holds (to within 5 % of the
   resolution) is dropped. They are chosen as a set cover: the cell the fewest
   candidates hold first, by the candidate holding it that holds the most cells still open (on a
   segment, the optimal cover), then any two spheres whose cells one candidate holds replaced by
   it, redundant ones dropped (cells no candidate holds, in parts thinner than the grid, get
   spheres of their own). Each cell goes to the sphere that holds it with the most room, and each
   sphere shrinks to the farthest point of its cells (or becomes their smallest enclosing ball,
   when that reaches less far beyond the solid).

A link whose geometry is spheres alone is covered by those spheres.

``max_error`` trades count for tightness: the largest distance a sphere may reach beyond the
solid (:attr:`RobotSpheres.excess` holds each sphere's estimate, the depth measured to the
boundary pieces at the grid's resolution; spheres of cells no candidate holds may exceed it).
A sharp edge costs spheres: one reaching at most ``max_error`` past a right-angled edge covers
at most ``2.8 max_error`` of it. A link may have a max_error of its own (``link_max_error``;
:data:`DEFAULT_LINK_MAX_ERROR`: the Panda's wrist at 5 mm). Measured (benches/results/spheres.json):
the Panda preset, whose collision model is capsules, 42 spheres at the default 1 cm (43 with its
wrist at 5 mm); the UR5's meshes (sharp-edged
cylinders) several hundred at 1 cm, about a hundred at 2 cm.

**The cache.** The result is written under ``$GENPLAN_CACHE/spheres`` (:func:`genplan.cache.cache_dir`)
as JSON named by the sha256 of the geometry (each geometry's link, kind, sizes, placement,
vertices and triangles) and of the parameters; a file is used only when its checksum, format,
hash and parameters are right (a corrupt or stale one is generated again and replaced).
"""

from __future__ import annotations

import hashlib
import json
import math
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import DTypeLike, NDArray

from genplan._files import write_text
from genplan.cache import cache_dir
from genplan.errors import RobotFileError, SettingsError

if TYPE_CHECKING:
    from genplan.robots import Robot

__all__ = [
    "DEFAULT_LINK_MAX_ERROR",
    "DEFAULT_MAX_ERROR",
    "DEFAULT_PADDING",
    "LinkGeometry",
    "RobotSpheres",
    "attached_geometry",
    "attached_spheres",
    "clear_cache",
    "link_geometries",
    "robot_spheres",
]

#: The default largest distance (m) a sphere may reach beyond the link's solid.
DEFAULT_MAX_ERROR = 0.01
#: The default radius padding (m): ten times the float32 rounding of a robot's link positions
#: within 10 m of the origin (a chain of ~10 transforms, each off by a few float32 ulps of its
#: coordinates, about 1e-6 m each), and the float32 rounding of the sphere data itself.
DEFAULT_PADDING = 1e-4
#: Links covered tighter than ``max_error`` by default, per robot name: where a tighter cover of
#: one link pays. The Panda's link7 (the wrist, with the flange's capsule) at 5 mm: one sphere more
#: (43), and on the motion bench's cage (python/genplan/experiments/benchmarks/motion.py: the
#: hand passes two bars into a cage) the planning time with the spheres about halves, the other
#: families unchanged; the same at 5 mm on link5, link6 or the hand and fingers did not pay.
#: ``robot_spheres(..., link_max_error={})`` turns it off; a value above ``max_error`` is not used.
DEFAULT_LINK_MAX_ERROR: dict[str, dict[str, float]] = {"panda": {"panda_link7": 0.005}}
#: The version of the generator; part of the cache key (a new version generates again).
ALGORITHM_VERSION = 2
#: The ``format`` field of :meth:`RobotSpheres.to_dict`.
FORMAT = "genplan-robot-spheres"

# A primitive's circumscribed polyhedron is at most max_error / _CIRCUMSCRIBE larger than it.
_CIRCUMSCRIBE = 50.0
# The grid's origin is offset by this fraction of a cell, so that the grid's rays rarely meet a
# mesh edge or vertex placed on round coordinates (those that do are handled, only slower).
_GRID_OFFSET = 2.0 - math.sqrt(3.0)
# A link's grid may hold at most this many nodes (SettingsError naming the resolution beyond).
_MAX_NODES = 12_000_000
# Interior cubes are merged into blocks of this many cubes per axis.
_BLOCK = 4
# A grid node is a candidate centre unless a neighbour is deeper by this fraction of their distance.
_MEDIAL_SLOPE = 0.85
# Candidate centres per link, at most (about): more are thinned to the deepest of each block.
_MAX_CANDIDATES = 2500
# A candidate ball within this fraction of the resolution of a larger candidate is dropped.
_DOMINATED = 0.05
# Balls per query of the cells' k-d tree when finding the cells each ball holds.
_HOLDS_GROUP = 64
# Iterations of the Badoiu-Clarkson smallest enclosing ball.
_MEB_ITERATIONS = 300
# Points the Badoiu-Clarkson iteration runs on, at most (then a few steps on all).
_MEB_POINTS = 4096


# --- the geometry ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class LinkGeometry:
    """One collision geometry of a link, as Pinocchio reads it from the collision URDF.

    ``kind`` is "box" (``size`` = half extents), "sphere" (radius), "cylinder" or "capsule"
    (radius, half length along the shape's z axis) or "mesh" (``vertices`` scaled, ``triangles``
    their indices, in the shape's frame). ``placement`` (4x4) is the shape's frame in the link's
    frame. ``name`` is Pinocchio's (``<link>_<i>``)."""

    name: str
    link: str
    kind: str
    size: tuple[float, ...]
    placement: NDArray[np.float64]
    vertices: NDArray[np.float64] | None = None
    triangles: NDArray[np.int64] | None = None
    source: str = ""

    def contains(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which points (n, 3), in the link's frame, lie in the geometry's solid (its boundary
        included): a primitive's exact test; a mesh's generalised winding number above 1/2 (the
        inside of a closed mesh; of an open one, what its winding number calls inside)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        m = self.placement
        x = (p - m[:3, 3]) @ m[:3, :3]
        if self.kind == "box":
            return np.all(np.abs(x) <= np.array(self.size), axis=1)
        if self.kind == "sphere":
            return np.linalg.norm(x, axis=1) <= self.size[0]
        if self.kind == "cylinder":
            r, h = self.size
            return (np.hypot(x[:, 0], x[:, 1]) <= r) & (np.abs(x[:, 2]) <= h)
        if self.kind == "capsule":
            r, h = self.size
            z = np.clip(x[:, 2], -h, h)
            return np.hypot(np.hypot(x[:, 0], x[:, 1]), x[:, 2] - z) <= r
        assert self.vertices is not None and self.triangles is not None
        return np.abs(_winding(x, self.vertices, self.triangles)) > 0.5

    def digest(self, h: Any) -> None:
        """Feed what the geometry is (not where it was read from) to the hash ``h``."""
        h.update(json.dumps([self.link, self.kind, [float(x) for x in self.size]]).encode())
        h.update(np.ascontiguousarray(self.placement, dtype="<f8").tobytes())
        if self.vertices is not None and self.triangles is not None:
            h.update(np.ascontiguousarray(self.vertices, dtype="<f8").tobytes())
            h.update(np.ascontiguousarray(self.triangles, dtype="<i8").tobytes())


#: Each robot's geometries, read once (:func:`link_geometries`).
_GEOMETRIES: weakref.WeakKeyDictionary[Robot, tuple[LinkGeometry, ...]] = weakref.WeakKeyDictionary()


def link_geometries(robot: Robot) -> list[LinkGeometry]:
    """Every collision geometry of ``robot`` (its Pinocchio collision model, the same geometry
    genplan's collision world and coal see; the locked joints' links where the locks hold them),
    in the frame of the link it is attached to. RobotFileError names a geometry of a kind genplan
    does not read (a cone, an ellipsoid, a height field) or a link the kinematics lacks. Read
    once per robot object (a mesh's triangles come out of coal one at a call: seconds for a
    detailed robot, and every sphere checker asks), then kept while the robot lives."""
    known_geometries = _GEOMETRIES.get(robot)
    if known_geometries is not None:
        return list(known_geometries)
    import coal

    geom = robot.collision_model
    model = robot.model
    known = set(robot.kinematics.link_names)
    out: list[LinkGeometry] = []
    for go in geom.geometryObjects:
        frame = model.frames[go.parentFrame]
        link = str(frame.name)
        where = f"robot '{robot.name}': collision geometry '{go.name}' of link '{link}'"
        if link not in known:
            raise RobotFileError(f"{where}: the link is not one of the kinematics' links")
        if int(frame.parentJoint) != int(go.parentJoint):
            raise RobotFileError(f"{where}: attached to another joint than its link")
        placement = np.asarray((frame.placement.inverse() * go.placement).homogeneous, dtype=np.float64).copy()
        g = go.geometry
        source = str(getattr(go, "meshPath", "") or "")
        if isinstance(g, coal.Box):
            out.append(LinkGeometry(go.name, link, "box", tuple(float(x) for x in g.halfSide), placement))
        elif isinstance(g, coal.Sphere):
            out.append(LinkGeometry(go.name, link, "sphere", (float(g.radius),), placement))
        elif isinstance(g, coal.Cylinder):
            out.append(LinkGeometry(go.name, link, "cylinder", (float(g.radius), float(g.halfLength)), placement))
        elif isinstance(g, coal.Capsule):
            out.append(LinkGeometry(go.name, link, "capsule", (float(g.radius), float(g.halfLength)), placement))
        elif isinstance(g, coal.BVHModelBase):
            vertices, triangles = _bvh_arrays(g, f"{where}: mesh {source}")
            out.append(LinkGeometry(go.name, link, "mesh", (), placement, vertices, triangles, source))
        else:
            raise RobotFileError(
                f"{where}: a {type(g).__name__} cannot be covered by spheres (genplan reads boxes, "
                "spheres, cylinders, capsules and meshes)")
    for g in out:
        for a in (g.placement, g.vertices, g.triangles):
            if a is not None:
                a.setflags(write=False)
    _GEOMETRIES[robot] = tuple(out)
    return out


def _bvh_arrays(g: Any, where: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The vertices (n, 3) and triangles (m, 3) of coal's mesh ``g``; RobotFileError (``where``
    names it) when it has no triangles or a non-finite vertex."""
    vertices = np.array(g.vertices(), dtype=np.float64, copy=True).reshape(-1, 3)
    tris = g.tri_indices
    triangles = np.array([[t[0], t[1], t[2]] for t in (tris(i) for i in range(g.num_tris))],
                         dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0 or not np.all(np.isfinite(vertices)):
        raise RobotFileError(f"{where} has no triangles or non-finite vertices")
    return vertices, triangles


def attached_geometry(attached: Any) -> LinkGeometry:
    """An attached object (:class:`genplan.robots.Attached`: its shape at its pose in the
    holding link's frame) as a :class:`LinkGeometry` of that link; a mesh read by coal (as the
    robot's own meshes), scaled as the shape says."""
    from genplan.robots import _compose
    from genplan.scene import Box, Capsule, Cylinder, Mesh, Sphere

    shape = attached.shape
    pose = _compose(attached.pose, shape.pose)
    placement = np.eye(4)
    placement[:3, :3] = pose.matrix()
    placement[:3, 3] = pose.position
    name = f"attached '{attached.name}'"
    if isinstance(shape, Box):
        return LinkGeometry(name, attached.link, "box", tuple(shape.half_extents), placement)
    if isinstance(shape, Sphere):
        return LinkGeometry(name, attached.link, "sphere", (float(shape.radius),), placement)
    if isinstance(shape, (Cylinder, Capsule)):
        return LinkGeometry(name, attached.link, shape.kind, (float(shape.radius), 0.5 * float(shape.length)), placement)
    if isinstance(shape, Mesh):
        import coal

        mesh = coal.MeshLoader().load(str(shape.path), np.asarray(shape.scale, dtype=np.float64))
        vertices, triangles = _bvh_arrays(mesh, f"{name}: mesh {shape.path}")
        return LinkGeometry(name, attached.link, "mesh", (), placement, vertices, triangles, str(shape.path))
    raise SettingsError(f"{name}: a {type(shape).__name__} cannot be covered by spheres")


#: The attached objects' spheres, by their geometry's hash and the parameters.
_ATTACHED_MEMO: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}


def attached_spheres(attached: Any, *, max_error: float = DEFAULT_MAX_ERROR, padding: float = DEFAULT_PADDING
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Spheres covering an attached object (:class:`genplan.robots.Attached`) with the same
    guarantee as :func:`robot_spheres`' (its solid covered, no sphere reaching more than about
    ``max_error`` beyond it, radii padded by ``padding``): centres (n, 3) in the holding link's
    frame and radii (n,). Generated once per geometry and parameters in this process.
    SettingsError names a bad ``max_error`` or ``padding`` before any work."""
    eps = _positive(max_error, "max_error", 1.0)
    pad = _padding(padding)
    geometry = attached_geometry(attached)
    key = geometry_hash([geometry], eps, eps / 2, pad)
    if key not in _ATTACHED_MEMO:
        centers, radii, _ = _cover_link(geometry.name, [geometry], eps, eps / 2)
        _ATTACHED_MEMO[key] = (centers, radii + pad)
    centers, radii = _ATTACHED_MEMO[key]
    return centers.copy(), radii.copy()


# --- the result --------------------------------------------------------------------------------


def _array(value: Any, shape: tuple[int, ...], what: str, origin: str) -> NDArray[np.float64]:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise RobotFileError(f"{origin}: {what}: expected numbers") from None
    if a.shape != shape:
        raise RobotFileError(f"{origin}: {what}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise RobotFileError(f"{origin}: {what}: must be finite")
    return a


@dataclass(frozen=True, eq=False)
class RobotSpheres:
    """The spheres of a robot: sphere i has its centre ``centers[i]`` (m) in the frame of link
    ``links[i]`` and radius ``radii[i]`` (padding included). ``excess[i]`` bounds how far sphere i
    reaches beyond its link's solid (m, padding included). The parameters and the sha256 of the
    geometry and parameters they were generated with are kept (``geometry_hash``)."""

    robot: str
    links: tuple[str, ...]
    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    excess: NDArray[np.float64]
    max_error: float
    resolution: float
    padding: float
    geometry_hash: str
    algorithm: int = ALGORITHM_VERSION
    #: the links generated with a max_error of their own (:func:`robot_spheres`'s ``link_max_error``)
    link_max_error: Mapping[str, float] = field(default_factory=dict)
    #: seconds spent generating (0 when read from the cache; not part of the file)
    generation_s: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        s = len(self.links)
        for name, shape in (("centers", (s, 3)), ("radii", (s,)), ("excess", (s,))):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise RobotFileError(f"spheres of '{self.robot}': {name}: expected finite values of shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if s and float(self.radii.min()) <= 0:
            raise RobotFileError(f"spheres of '{self.robot}': radii: must be positive")
        object.__setattr__(self, "links", tuple(str(x) for x in self.links))
        object.__setattr__(self, "link_max_error", {str(k): float(v) for k, v in dict(self.link_max_error).items()})

    def __len__(self) -> int:
        return len(self.links)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RobotSpheres):
            return NotImplemented
        return (self.to_dict() == other.to_dict())

    __hash__ = None  # type: ignore[assignment]

    @property
    def link_names(self) -> tuple[str, ...]:
        """The links that have spheres, in the order of their first sphere."""
        return tuple(dict.fromkeys(self.links))

    def counts(self) -> dict[str, int]:
        """Spheres per link."""
        return {link: self.links.count(link) for link in self.link_names}

    def world_centers(self, robot: Robot, q: Any, *, dtype: DTypeLike = np.float64) -> NDArray[Any]:
        """The spheres' centres in the world at ``q`` through ``robot``'s kinematics
        (:meth:`~genplan.robots.Robot.link_poses`): q of shape (nq,) gives (S, 3), (n, nq) gives
        (n, S, 3). ``dtype`` float64 (default) or float32 (the poses and the product in float32,
        what ``padding`` allows for)."""
        dt = np.dtype(dtype)
        if dt not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise SettingsError(f"dtype: expected float64 or float32, got {dt}")
        names = self.link_names
        index = {n: i for i, n in enumerate(names)}
        poses = robot.link_poses(q, list(names), dtype=dt)
        which = np.array([index[n] for n in self.links], dtype=np.intp)
        sel = poses[..., which, :, :]  # (..., S, 4, 4)
        c = self.centers.astype(dt)
        # R c + p, written out (an einsum or numpy's batched 3 x 3 products are several times slower)
        return (sel[..., :3, 0] * c[:, 0:1] + sel[..., :3, 1] * c[:, 1:2] + sel[..., :3, 2] * c[:, 2:3]
                + sel[..., :3, 3])

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON's types) that :meth:`from_dict` reads back to an equal object
        (``link_max_error`` only when a link has a max_error of its own)."""
        out = {
            "format": FORMAT,
            "algorithm": int(self.algorithm),
            "robot": self.robot,
            "geometry_hash": self.geometry_hash,
            "max_error": float(self.max_error),
            "resolution": float(self.resolution),
            "padding": float(self.padding),
            "links": list(self.links),
            "centers": [[float(x) for x in row] for row in self.centers],
            "radii": [float(x) for x in self.radii],
            "excess": [float(x) for x in self.excess],
        }
        if self.link_max_error:
            out["link_max_error"] = dict(sorted(self.link_max_error.items()))
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], origin: str = "spheres") -> RobotSpheres:
        """Read :meth:`to_dict`'s form; RobotFileError (starting with ``origin``) naming the field
        for anything else: a missing or unknown field, another format, arrays of the wrong
        length, NaN, a radius that is not positive."""
        if not isinstance(data, Mapping):
            raise RobotFileError(f"{origin}: expected a table, got {type(data).__name__}")
        keys = ("format", "algorithm", "robot", "geometry_hash", "max_error", "resolution", "padding",
                "links", "centers", "radii", "excess")
        for k in data:
            if k not in keys and k != "link_max_error":
                raise RobotFileError(f"{origin}: unknown field '{k}' (known: {', '.join(keys)}, link_max_error)")
        for k in keys:
            if k not in data:
                raise RobotFileError(f"{origin}: missing field '{k}'")
        if data["format"] != FORMAT:
            raise RobotFileError(f"{origin}: format: expected '{FORMAT}', got {data['format']!r}")
        for k in ("robot", "geometry_hash"):
            if not isinstance(data[k], str):
                raise RobotFileError(f"{origin}: {k}: expected a string, got {data[k]!r}")
        algorithm = data["algorithm"]
        if isinstance(algorithm, bool) or not isinstance(algorithm, int):
            raise RobotFileError(f"{origin}: algorithm: expected an integer, got {algorithm!r}")
        params = {}
        for k in ("max_error", "resolution", "padding"):
            v = data[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise RobotFileError(f"{origin}: {k}: expected a finite number >= 0, got {v!r}")
            params[k] = float(v)
        links = data["links"]
        if not isinstance(links, list) or not all(isinstance(x, str) and x for x in links):
            raise RobotFileError(f"{origin}: links: expected a list of link names")
        s = len(links)
        centers = _array(data["centers"], (s, 3), "centers", origin)
        radii = _array(data["radii"], (s,), "radii", origin)
        excess = _array(data["excess"], (s,), "excess", origin)
        if s and radii.min() <= 0:
            raise RobotFileError(f"{origin}: radii[{int(np.argmin(radii))}]: must be positive, got {radii.min()}")
        per_link = data.get("link_max_error", {})
        if not isinstance(per_link, Mapping) or not all(
                isinstance(k, str) and not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                for k, v in per_link.items()):
            raise RobotFileError(f"{origin}: link_max_error: expected a table of link names to positive numbers, "
                                 f"got {per_link!r}")
        return cls(robot=data["robot"], links=tuple(links), centers=centers, radii=radii, excess=excess,
                   geometry_hash=data["geometry_hash"], algorithm=algorithm, link_max_error=dict(per_link), **params)


# --- entry point -------------------------------------------------------------------------------

#: Spheres generated or read in this process, by cache key.
_MEMO: dict[str, RobotSpheres] = {}


def clear_cache() -> None:
    """Forget the spheres held in memory (the next call reads the cache file, or generates)."""
    _MEMO.clear()


def _positive(value: Any, what: str, upper: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SettingsError(f"{what}: expected a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and 0.0 < v <= upper):
        raise SettingsError(f"{what}: must be positive and at most {upper:g} m, got {value!r}")
    return v


def _padding(value: Any) -> float:
    """``padding`` (m) as a float in [0, 0.01], else SettingsError naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(float(value)) and 0.0 <= float(value) <= 0.01):
        raise SettingsError(f"padding: expected a number in [0, 0.01] m, got {value!r}")
    return float(value)


def geometry_hash(geometries: Sequence[LinkGeometry], max_error: float, resolution: float, padding: float,
                  link_max_error: Mapping[str, float] | None = None, link_resolution: float | None = None) -> str:
    """The sha256 (hex) of the geometry and the parameters: the cache key (``link_max_error``, the
    links with a max_error of their own, only when there are any: a cover without them keeps its key;
    ``link_resolution``, their grid spacing when it was given rather than half their max_error)."""
    h = hashlib.sha256()
    params: dict[str, Any] = {"format": FORMAT, "algorithm": ALGORITHM_VERSION, "max_error": max_error,
                              "resolution": resolution, "padding": padding}
    if link_max_error:
        params["link_max_error"] = {str(k): float(v) for k, v in link_max_error.items()}
        if link_resolution is not None:
            params["link_resolution"] = float(link_resolution)
    h.update(json.dumps(params, sort_keys=True).encode())
    for g in geometries:
        g.digest(h)
    return h.hexdigest()


def _cache_path(robot_name: str, key: str) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in robot_name) or "robot"
    return cache_dir() / "spheres" / f"{safe}-{key[:24]}.json"


def _checksum(payload: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _read_cache(path: Path, key: str) -> RobotSpheres | None:
    """The cached spheres at ``path`` when the file is whole and of this key, else None."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        payload = data["spheres"]
        if not isinstance(data, dict) or data.get("checksum") != _checksum(payload):
            return None
        spheres = RobotSpheres.from_dict(payload, origin=str(path))
    except (OSError, ValueError, KeyError, TypeError):
        return None  # missing, unreadable, corrupt: generated again
    if spheres.geometry_hash != key or spheres.algorithm != ALGORITHM_VERSION:
        return None
    return spheres


def robot_spheres(
    robot: Robot,
    *,
    max_error: float = DEFAULT_MAX_ERROR,
    resolution: float | None = None,
    padding: float = DEFAULT_PADDING,
    cache: bool = True,
    link_max_error: Mapping[str, float] | None = None,
) -> RobotSpheres:
    """Spheres covering every link's collision solid of ``robot`` (the module's docstring: the
    guarantee, the method, the cache).

    ``max_error`` (m): the largest distance a sphere may reach beyond the solid (smaller: tighter
    and more spheres). ``resolution`` (m): the grid spacing, default ``max_error / 2`` (finer:
    slower, the same guarantee, slightly fewer or tighter spheres). ``padding`` (m) is added to
    every radius (float32 kinematics). ``cache``: read and write ``$GENPLAN_CACHE/spheres``.
    ``link_max_error``: links (by name) covered with a max_error of their own (m; their grid
    ``resolution`` is half of it unless ``resolution`` is given), the same guarantee; None (default):
    :data:`DEFAULT_LINK_MAX_ERROR`'s for the robot's name, where below ``max_error``; ``{}``: none.
    SettingsError names a bad parameter before any work; links without collision geometry get
    no sphere."""
    from genplan.robots import Robot

    if not isinstance(robot, Robot):
        raise SettingsError(f"robot: expected a genplan Robot (genplan.load(...)), got {type(robot).__name__}")
    eps = _positive(max_error, "max_error", 1.0)
    res = eps / 2 if resolution is None else _positive(resolution, "resolution", 1.0)
    pad = _padding(padding)
    if not isinstance(cache, bool):
        raise SettingsError(f"cache: expected True or False, got {cache!r}")

    geometries = link_geometries(robot)
    with_geometry = list(dict.fromkeys(g.link for g in geometries))
    if link_max_error is None:
        per_link = {k: v for k, v in DEFAULT_LINK_MAX_ERROR.get(robot.name, {}).items()
                    if k in with_geometry and v < eps}
    else:
        if not isinstance(link_max_error, Mapping):
            raise SettingsError(f"link_max_error: expected a table of link names to max_errors (m), got {link_max_error!r}")
        per_link = {}
        for name, value in link_max_error.items():
            if name not in with_geometry:
                raise SettingsError(f"link_max_error: {name!r} is no link with collision geometry of '{robot.name}' "
                                    f"(those: {', '.join(with_geometry)})")
            per_link[name] = _positive(value, f"link_max_error[{name!r}]", 1.0)
    # the links of their own max_error are gridded at half of it unless a resolution was given:
    # the same (max_error, resolution) pair must not name two covers
    key = geometry_hash(geometries, eps, res, pad, per_link, None if resolution is None else res)
    if cache and key in _MEMO:
        return _MEMO[key]
    path = _cache_path(robot.name, key)
    if cache:
        found = _read_cache(path, key)
        if found is not None:
            _MEMO[key] = found
            return found

    import time

    t0 = time.perf_counter()
    links: list[str] = []
    centers: list[NDArray[np.float64]] = []
    radii: list[NDArray[np.float64]] = []
    excess: list[NDArray[np.float64]] = []
    by_link: dict[str, list[LinkGeometry]] = {}
    for g in geometries:
        by_link.setdefault(g.link, []).append(g)
    for link, geoms in by_link.items():
        e = per_link.get(link, eps)
        c, r, x = _cover_link(link, geoms, e, e / 2 if resolution is None else res)
        links += [link] * len(r)
        centers.append(c)
        radii.append(r + pad)
        excess.append(x + pad)
    result = RobotSpheres(
        robot=robot.name, links=tuple(links),
        centers=np.concatenate(centers) if centers else np.zeros((0, 3)),
        radii=np.concatenate(radii) if radii else np.zeros(0),
        excess=np.concatenate(excess) if excess else np.zeros(0),
        max_error=eps, resolution=res, padding=pad, geometry_hash=key, link_max_error=per_link,
        generation_s=time.perf_counter() - t0,
    )
    if cache:
        payload = result.to_dict()
        write_text(path, json.dumps({"checksum": _checksum(payload), "spheres": payload}))
        _MEMO[key] = result
    return result


# --- solids: each geometry as a closed polyhedron containing it ----------------------------------


@dataclass
class _Solid:
    """A geometry as triangles in the link frame: ``closed`` (every edge on two triangles),
    ``oriented`` (consistently), ``shrink``: how much larger than the geometry the polyhedron is
    (depths are lowered by it); ``geometry``: what it was made from."""

    vertices: NDArray[np.float64]
    triangles: NDArray[np.int64]
    closed: bool
    oriented: bool
    shrink: float
    geometry: LinkGeometry

    def strictly_inside(self, p: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """For a primitive, which points (link frame) lie in its interior (a convex set: a
        triangle whose vertices do lies in it too); None for a mesh."""
        g = self.geometry
        if g.kind == "mesh":
            return None
        m = g.placement
        x = (p - m[:3, 3]) @ m[:3, :3]
        margin = 1e-9
        if g.kind == "box":
            return np.all(np.abs(x) < np.array(g.size) - margin, axis=1)
        if g.kind == "sphere":
            return np.linalg.norm(x, axis=1) < g.size[0] - margin
        r, h = g.size
        if g.kind == "cylinder":
            return (np.hypot(x[:, 0], x[:, 1]) < r - margin) & (np.abs(x[:, 2]) < h - margin)
        z = np.clip(x[:, 2], -h, h)
        return np.linalg.norm(x - np.column_stack([np.zeros_like(z), np.zeros_like(z), z]), axis=1) < r - margin


def _hull_triangles(points: NDArray[np.float64]) -> NDArray[np.int64]:
    """The convex hull's triangles of ``points``, oriented outwards."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    tri = hull.simplices.astype(np.int64).copy()
    # the hull's facet equations have outward normals: flip triangles that disagree
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    n = np.cross(b - a, c - a)
    flip = np.einsum("ij,ij->i", n, hull.equations[:, :3]) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def _sphere_points(tol: float) -> tuple[NDArray[np.float64], float]:
    """Points on the unit sphere whose hull, scaled by the returned factor, contains the unit
    ball and lies within 1 + tol of its centre (a Fibonacci lattice, refined until it does)."""
    n = 32
    while True:
        i = np.arange(n) + 0.5
        z = 1 - 2 * i / n
        phi = math.pi * (1 + math.sqrt(5)) * i
        rho = np.sqrt(1 - z * z)
        pts = np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)
        tri = _hull_triangles(pts)
        a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
        nrm = np.cross(b - a, c - a)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        d_min = float(np.min(np.einsum("ij,ij->i", nrm, a)))  # the faces' nearest plane distance
        if 1.0 / d_min - 1.0 <= tol or n >= 65536:
            return pts, 1.0 / d_min
        n *= 2


def _primitive_solid(g: LinkGeometry, tol_abs: float) -> _Solid:
    """A primitive as a convex polyhedron containing it, at most ``tol_abs`` beyond it."""
    if g.kind == "box":
        hx, hy, hz = g.size
        pts = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        shrink = 0.0
    elif g.kind in ("cylinder",):
        r, h = g.size
        n = 12
        while r * (1 / math.cos(math.pi / n) - 1) > tol_abs and n < 4096:
            n *= 2
        ang = 2 * math.pi * (np.arange(n) + 0.5) / n
        ring = np.stack([np.cos(ang), np.sin(ang)], axis=1) * (r / math.cos(math.pi / n))
        pts = np.concatenate([np.column_stack([ring, np.full(n, -h)]), np.column_stack([ring, np.full(n, h)])])
        shrink = r * (1 / math.cos(math.pi / n) - 1)
    else:  # sphere, capsule: a circumscribed polyhedron of the ball, swept along the segment
        r = g.size[0]
        unit, scale = _sphere_points(tol_abs / r)
        ball = unit * (r * scale)
        if g.kind == "capsule":
            h = g.size[1]
            pts = np.concatenate([ball + [0, 0, -h], ball + [0, 0, h]])
        else:
            pts = ball
        shrink = r * (scale - 1)
    tri = _hull_triangles(pts)
    used = np.unique(tri)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    v = _transform(g.placement, pts[used])
    return _Solid(v, remap[tri], True, True, shrink, g)


def _transform(m: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    return p @ m[:3, :3].T + m[:3, 3]


def _mesh_solids(g: LinkGeometry) -> list[_Solid]:
    """A mesh as it is (identical vertices merged, degenerate triangles dropped), one solid per
    connected part (a mesh of overlapping shells: each shell, so that the parts of one inside
    another are known to be inside the union); a part is closed when every edge lies on exactly
    two of its triangles, oriented when those two run it both ways."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    assert g.vertices is not None and g.triangles is not None
    uniq, inverse = np.unique(g.vertices, axis=0, return_inverse=True)
    tri = inverse.reshape(-1)[g.triangles]
    keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
    tri = tri[keep].astype(np.int64)
    v = _transform(g.placement, uniq)
    if not len(tri):
        return []
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(uniq), len(uniq)))
    _, label = connected_components(graph, directed=False)
    part = label[tri[:, 0]]
    out = []
    for k in np.unique(part):
        t = tri[part == k]
        used, local = np.unique(t, return_inverse=True)
        t = local.reshape(-1, 3)
        directed = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
        _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
        closed = bool(np.all(counts == 2))
        oriented = closed and len(np.unique(directed, axis=0)) == len(directed)
        out.append(_Solid(v[used], t, closed, oriented, 0.0, g))
    return out


# --- geometry kernels ----------------------------------------------------------------------------


def _subdivide(v: NDArray[np.float64], tri: NDArray[np.int64], edge: float) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The triangles cut into pieces whose edges are at most ``edge``: each triangle split at the
    midpoint of its longest edge until none is longer (a long thin triangle becomes a row of
    pieces along it, not slivers across it): the pieces' vertices (three per piece) and their
    indices. The pieces keep their triangle's orientation."""
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    done: list[NDArray[np.float64]] = []
    limit = edge * (1 + 1e-9)
    while len(a):
        lengths = np.stack([np.einsum("ij,ij->i", b - a, b - a), np.einsum("ij,ij->i", c - b, c - b),
                            np.einsum("ij,ij->i", a - c, a - c)], axis=1)
        longest = np.argmax(lengths, axis=1)
        split = lengths[np.arange(len(a)), longest] > limit * limit
        if not split.all():
            keep = ~split
            done.append(np.stack([a[keep], b[keep], c[keep]], axis=1))
        a, b, c, longest = a[split], b[split], c[split], longest[split]
        # rotate each triangle so that its longest edge is (a, b), then split it into (a, m, c)
        # and (m, b, c)
        r1, r2 = longest == 1, longest == 2
        a, b, c = (np.where(r1[:, None], b, np.where(r2[:, None], c, a)),
                   np.where(r1[:, None], c, np.where(r2[:, None], a, b)),
                   np.where(r1[:, None], a, np.where(r2[:, None], b, c)))
        m = (a + b) / 2
        a, b, c = np.concatenate([a, m]), np.concatenate([m, b]), np.concatenate([c, c])
    pieces = np.concatenate(done) if done else np.zeros((0, 3, 3))
    return pieces.reshape(-1, 3), np.arange(3 * len(pieces), dtype=np.int64).reshape(-1, 3)


class _Surface:
    """Distances from points to a triangle mesh (coal's bounding volume hierarchy, the point a
    ball of radius 0)."""

    def __init__(self, pv: NDArray[np.float64], pt: NDArray[np.int64]) -> None:
        import coal

        self.mesh = coal.BVHModelOBBRSS()
        self.mesh.beginModel(len(pt), len(pv))
        self.mesh.addVertices(np.ascontiguousarray(pv, dtype=np.float64))
        self.mesh.addTriangles(np.ascontiguousarray(pt, dtype=np.int64))
        self.mesh.endModel()
        self.point = coal.Sphere(0.0)
        self.request = coal.DistanceRequest()
        self.result = coal.DistanceResult()
        self.where = coal.Transform3s()
        self.identity = coal.Transform3s()
        self.empty = len(pt) == 0

    def distance(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each point's distance to the surface."""
        return self.closest(p)[0]

    def closest(self, p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each point's distance to the surface and its nearest point on it."""
        import coal

        p = np.atleast_2d(np.asarray(p, dtype=np.float64))
        dist = np.full(len(p), np.inf)
        near = np.array(p, copy=True)
        if self.empty:
            return dist, near
        for i, x in enumerate(p):
            self.where.setTranslation(x)
            self.result.clear()
            dist[i] = coal.distance(self.point, self.where, self.mesh, self.identity, self.request, self.result)
            near[i] = self.result.getNearestPoint2()
        return np.maximum(dist, 0.0), near


def _winding(p: NDArray[np.float64], v: NDArray[np.float64], tri: NDArray[np.int64]) -> NDArray[np.float64]:
    """The generalised winding number of each point (the solid angle the triangles subtend over
    4 pi; Van Oosterom and Strackee's formula): 1 inside a closed outward mesh, 0 outside."""
    p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(p))
    tchunk = min(max(len(tri), 1), 4096)
    pchunk = max(1, 2_000_000 // tchunk)
    for plo in range(0, len(p), pchunk):
        q = p[plo:plo + pchunk]
        acc = np.zeros(len(q))
        for lo in range(0, len(tri), tchunk):
            t = tri[lo:lo + tchunk]
            a = v[t[:, 0]][None] - q[:, None]
            b = v[t[:, 1]][None] - q[:, None]
            c = v[t[:, 2]][None] - q[:, None]
            la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
            num = np.einsum("pti,pti->pt", a, np.cross(b, c))
            den = (la * lb * lc + np.einsum("pti,pti->pt", a, b) * lc + np.einsum("pti,pti->pt", b, c) * la
                   + np.einsum("pti,pti->pt", c, a) * lb)
            acc += np.arctan2(num, den).sum(axis=1)
        out[plo:plo + pchunk] = acc
    return out / (2 * math.pi)


# --- the grid -----------------------------------------------------------------------------------


@dataclass
class _Grid:
    origin: NDArray[np.float64]
    step: float
    shape: tuple[int, int, int]  # nodes per axis; the cubes are one fewer

    def nodes(self, flat: NDArray[np.int64]) -> NDArray[np.float64]:
        i, j, k = np.unravel_index(flat, self.shape)
        return self.origin + self.step * np.stack([i, j, k], axis=1)


def _inside_nodes(grid: _Grid, solid: _Solid) -> NDArray[np.bool_]:
    """Which grid nodes are inside ``solid``: the signed crossings of a ray from each node along
    +z (a closed oriented mesh: a non-zero sum; closed but not oriented: an odd count; open: an
    odd count both up and down). Columns whose ray passes within 1e-9 of an edge (relative) are
    decided by the solid-angle winding number instead."""
    nx, ny, nz = grid.shape
    v, tri = solid.vertices, solid.triangles
    o, s = grid.origin, grid.step
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    lo = np.minimum(np.minimum(a, b), c)
    hi = np.maximum(np.maximum(a, b), c)
    i0 = np.clip(np.ceil((lo[:, 0] - o[0]) / s), 0, nx).astype(np.int64)
    i1 = np.clip(np.floor((hi[:, 0] - o[0]) / s), -1, nx - 1).astype(np.int64)
    j0 = np.clip(np.ceil((lo[:, 1] - o[1]) / s), 0, ny).astype(np.int64)
    j1 = np.clip(np.floor((hi[:, 1] - o[1]) / s), -1, ny - 1).astype(np.int64)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    counts = ni * nj
    t_idx = np.repeat(np.arange(len(tri)), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    local = np.arange(len(t_idx)) - start
    ci = i0[t_idx] + local // np.maximum(nj[t_idx], 1)
    cj = j0[t_idx] + local % np.maximum(nj[t_idx], 1)
    px, py = o[0] + ci * s, o[1] + cj * s
    ax, ay, bx, by, cx, cy = a[t_idx, 0], a[t_idx, 1], b[t_idx, 0], b[t_idx, 1], c[t_idx, 0], c[t_idx, 1]
    area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    w0 = (bx - px) * (cy - py) - (by - py) * (cx - px)
    w1 = (cx - px) * (ay - py) - (cy - py) * (ax - px)
    w2 = (ax - px) * (by - py) - (ay - py) * (bx - px)
    scale = np.abs(area)
    with np.errstate(divide="ignore", invalid="ignore"):
        u0, u1, u2 = w0 / area, w1 / area, w2 / area
    flat_tri = scale <= 1e-14 * (np.abs(bx - ax) + np.abs(cx - ax) + np.abs(by - ay) + np.abs(cy - ay)) ** 2
    tol = 1e-9
    inside = ~flat_tri & (u0 > tol) & (u1 > tol) & (u2 > tol)
    grazing = ~flat_tri & (u0 >= -tol) & (u1 >= -tol) & (u2 >= -tol) & ~inside
    col = ci * ny + cj
    degenerate = np.zeros(nx * ny, dtype=bool)
    degenerate[col[grazing]] = True
    hit = inside & ~degenerate[col]
    zc = u0[hit] * a[t_idx[hit], 2] + u1[hit] * b[t_idx[hit], 2] + u2[hit] * c[t_idx[hit], 2]
    sign = np.sign(area[hit])
    colh = col[hit]
    # per node: the crossings above it in its column (sorted keys: column, then z)
    zspan = (nz + 2) * s
    key = colh * zspan + (zc - o[2])
    order = np.argsort(key)
    key, sign = key[order], sign[order]
    csum = np.concatenate([[0.0], np.cumsum(sign)])
    col_end = np.searchsorted(key, (np.arange(nx * ny) + 1) * zspan - 0.5 * s)  # keys of a column < (col + 1) * zspan
    node_col = np.repeat(np.arange(nx * ny), nz)
    node_z = np.tile(np.arange(nz) * s, nx * ny)
    at = np.searchsorted(key, node_col * zspan + node_z, side="right")
    end = col_end[node_col]
    above = end - at
    signed = csum[end] - csum[at]
    col_start = np.searchsorted(key, np.arange(nx * ny) * zspan - 0.5 * s)
    total = (col_end - col_start)[node_col]
    if solid.closed and solid.oriented:
        inside_nodes = np.abs(signed) > 0.5
        # a closed oriented mesh's crossings sum to zero along a whole column; a column that
        # does not (rounding at a near-grazing hit) is decided by the winding number
        col_sum = csum[col_end] - csum[col_start]
        degenerate |= np.abs(col_sum) > 0.5
    elif solid.closed:
        inside_nodes = (above % 2) == 1
        degenerate |= ((col_end - col_start) % 2) == 1
    else:
        inside_nodes = ((above % 2) == 1) & (((total - above) % 2) == 1)
    bad = np.flatnonzero(degenerate[node_col])
    if len(bad):
        w = _winding(grid.nodes(bad), v, tri)
        inside_nodes[bad] = np.abs(w) > 0.5
    return inside_nodes.reshape(grid.shape)


def _clip_to_cubes(grid: _Grid, cshape: tuple[int, ...], tris: NDArray[np.float64], cubes: NDArray[np.int64]
                   ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The vertices of each triangle ``tris[i]`` (3 x 3) clipped to the closed grid cube
    ``cubes[i]`` (Sutherland-Hodgman against its six faces; a point on a face is set exactly on
    it): the cubes and points of the non-empty parts."""
    n = len(tris)
    lo = grid.origin + grid.step * np.stack(np.unravel_index(cubes, cshape), axis=1)
    hi = lo + grid.step
    poly = np.array(tris, dtype=np.float64)
    count = np.full(n, 3, dtype=np.int64)
    for axis in range(3):
        for bound, sign in ((lo[:, axis], 1.0), (hi[:, axis], -1.0)):
            width = poly.shape[1]
            f = sign * (poly[:, :, axis] - bound[:, None])  # >= 0: inside this face's half-space
            valid = np.arange(width)[None, :] < count[:, None]
            outside = np.where(valid, f < 0, False).sum(axis=1)
            count = np.where(outside == count, 0, count)  # wholly outside: empty
            cut = np.flatnonzero((outside > 0) & (count > 0))  # only those the face cuts change
            if not len(cut):
                continue
            sub, fs, cnt, bnd = poly[cut], f[cut], count[cut], bound[cut]
            m = len(cut)
            r = np.arange(m)
            out = np.zeros((m, 2 * width, 3))  # each edge gives at most two points
            out_count = np.zeros(m, dtype=np.int64)
            for i in range(width):
                ok = i < cnt
                nxt = np.where(i + 1 < cnt, i + 1, 0)
                cur_p, nxt_p = sub[:, i], sub[r, nxt]
                fc, fn = fs[:, i], fs[r, nxt]
                keep = ok & (fc >= 0)
                out[r[keep], out_count[keep]] = cur_p[keep]
                out_count += keep
                cross = ok & ((fc >= 0) != (fn >= 0)) & (cnt > 1)
                with np.errstate(divide="ignore", invalid="ignore"):  # (rows that do not cross: unused)
                    t = fc / (fc - fn)
                    pt = cur_p + t[:, None] * (nxt_p - cur_p)
                pt[:, axis] = bnd
                out[r[cross], out_count[cross]] = pt[cross]
                out_count += cross
            new_width = max(width, int(out_count.max(initial=0)))
            if new_width > width:
                poly = np.concatenate([poly, np.zeros((n, new_width - width, 3))], axis=1)
            poly[cut] = out[:, :new_width]
            count[cut] = out_count
    has = count > 0
    mask = np.arange(poly.shape[1])[None, :] < count[:, None]
    return np.repeat(cubes[has], count[has]), poly[mask & has[:, None]]


def _piece_cubes(grid: _Grid, pv: NDArray[np.float64], pt: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(cube, piece) pairs: every grid cube (closed) that a piece's bounding box meets."""
    cs = np.array(grid.shape) - 1
    a, b, c = pv[pt[:, 0]], pv[pt[:, 1]], pv[pt[:, 2]]
    margin = 1e-7 * grid.step
    lo = np.floor((np.minimum(np.minimum(a, b), c) - grid.origin - margin) / grid.step).astype(np.int64)
    hi = np.floor((np.maximum(np.maximum(a, b), c) - grid.origin + margin) / grid.step).astype(np.int64)
    lo = np.clip(lo, 0, cs - 1)
    hi = np.clip(hi, 0, cs - 1)
    ext = hi - lo + 1  # at most 2 per axis: a piece is no longer than a cube's edge
    cubes, pieces = [], []
    for dx in range(int(ext[:, 0].max(initial=1))):
        for dy in range(int(ext[:, 1].max(initial=1))):
            for dz in range(int(ext[:, 2].max(initial=1))):
                ok = (dx < ext[:, 0]) & (dy < ext[:, 1]) & (dz < ext[:, 2])
                idx = np.flatnonzero(ok)
                ijk = lo[idx] + [dx, dy, dz]
                cubes.append(np.ravel_multi_index(ijk.T, tuple(cs)))
                pieces.append(idx)
    return np.concatenate(cubes), np.concatenate(pieces)


# --- covering one link ----------------------------------------------------------------------------


def _cover_link(link: str, geoms: Sequence[LinkGeometry], eps: float, res: float
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Spheres (centres, radii, excess bounds; no padding) covering the union of ``geoms``."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    if all(g.kind == "sphere" for g in geoms):  # spheres are their own exact cover
        return (np.array([g.placement[:3, 3] for g in geoms]), np.array([g.size[0] for g in geoms]),
                np.zeros(len(geoms)))
    solids = [s for g in geoms for s in
              (_mesh_solids(g) if g.kind == "mesh" else [_primitive_solid(g, eps / _CIRCUMSCRIBE)])]
    shrink = max(s.shrink for s in solids)
    allv = np.concatenate([s.vertices for s in solids])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    origin = lo - res * (1.0 + _GRID_OFFSET)
    shape = tuple(int(x) for x in np.ceil((hi - origin) / res).astype(np.int64) + 2)
    nnodes = int(np.prod(shape, dtype=np.int64))
    if nnodes > _MAX_NODES:
        raise SettingsError(
            f"resolution: {res:g} m is too fine for link '{link}' ({np.round(hi - lo, 3).tolist()} m across: "
            f"{nnodes} grid nodes, at most {_MAX_NODES}); raise resolution or max_error")
    grid = _Grid(origin, res, shape)  # type: ignore[arg-type]
    cshape = tuple(x - 1 for x in shape)
    ncubes = int(np.prod(cshape))
    ci, cj, ck = np.unravel_index(np.arange(ncubes), cshape)
    corners = np.stack([np.ravel_multi_index((ci + dx, cj + dy, ck + dz), shape)
                        for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)], axis=1)  # (ncubes, 8) node ids
    del ci, cj, ck

    # per geometry: the nodes inside it, its pieces and the cubes they touch, its interior cubes
    inside_g, pieces_g, pairs_g, interior_g = [], [], [], []
    for s in solids:
        ins = _inside_nodes(grid, s).reshape(-1)
        pv, pt = _subdivide(s.vertices, s.triangles, res)
        cubes, pieces = _piece_cubes(grid, pv, pt)
        touched = np.zeros(ncubes, dtype=bool)
        touched[cubes] = True
        inside_g.append(ins)
        pieces_g.append((pv, pt))
        pairs_g.append((cubes, pieces))
        interior_g.append(~touched & ins[corners].all(axis=1) if s.closed else np.zeros(ncubes, dtype=bool))

    # the union's surface: the pieces not within another geometry's interior (a primitive's:
    # the piece's vertices in it; a closed mesh's: every cube the piece touches inside it); the
    # union's boundary lies on the pieces kept
    surf_v, surf_t, clip_cube, clip_pts, base = [], [], [], [], 0
    boundary = np.zeros(ncubes, dtype=bool)
    inside = np.logical_or.reduce(inside_g)
    # cubes inside a closed solid (untouched by its surface, their corners in it): how many
    interior_count = np.sum(interior_g, axis=0)
    for gi, ((pv, pt), (cubes, pieces)) in enumerate(zip(pieces_g, pairs_g)):
        internal = np.zeros(len(pt), dtype=bool)
        for hi_, h in enumerate(solids):
            vin = h.strictly_inside(pv) if hi_ != gi else None
            if vin is not None:
                internal |= vin[pt].all(axis=1)
        # every cube the piece touches inside another closed solid (one or another)
        others = interior_count[cubes] - interior_g[gi][cubes]
        internal |= np.bincount(pieces, weights=others < 1, minlength=len(pt)) == 0
        keep = ~internal
        # depths are measured to the kept pieces near the union's outside (touching a cube with
        # a corner out of it): a piece deep inside (of two shells that nearly coincide inside
        # the union, say) is no boundary, however the exact test above judged it
        near_out = np.bincount(pieces, weights=~inside[corners[cubes]].all(axis=1), minlength=len(pt)) > 0
        surf_v.append(pv)
        surf_t.append(pt[keep & near_out] + base)
        on = keep[pieces]
        # each kept piece's part in each cube it meets: its vertices are the cell's surface points
        cc, cp = _clip_to_cubes(grid, cshape, pv[pt[pieces[on]]], cubes[on])
        boundary[cc] = True
        clip_cube.append(cc)
        clip_pts.append(cp)
        base += len(pv)
    surface = _Surface(np.concatenate(surf_v), np.concatenate(surf_t))
    # one point per cube and position (the pieces' parts share their edges' points)
    clip_cube_all = np.concatenate(clip_cube)
    clip_all = np.concatenate(clip_pts)
    # (points of a cube closer than res / 2^17 are one: the first one kept)
    lo_c = grid.origin + res * np.stack(np.unravel_index(clip_cube_all, cshape), axis=1)
    q = np.clip(np.round((clip_all - lo_c) / res * 2.0 ** 17), 0, 2 ** 18 - 1).astype(np.int64)
    local = (q[:, 0] << 36) | (q[:, 1] << 18) | q[:, 2]
    order = np.lexsort((local, clip_cube_all))
    first = order[np.r_[True, (np.diff(clip_cube_all[order]) != 0) | (np.diff(local[order]) != 0)]]
    clip_cube_all, clip_all = clip_cube_all[first], clip_all[first]

    corner_in = inside[corners]
    interior = ~boundary & corner_in.all(axis=1)
    partial = boundary | (corner_in.any(axis=1) & ~interior)

    # interior cubes merged into blocks of _BLOCK^3 cubes where all are interior
    b = _BLOCK
    bshape = tuple(x // b for x in cshape)
    merged = np.zeros(cshape, dtype=bool)
    block_corners = np.zeros((0, 8), dtype=np.int64)
    if all(x > 0 for x in bshape):
        full = interior.reshape(cshape)[: bshape[0] * b, : bshape[1] * b, : bshape[2] * b]
        full = full.reshape(bshape[0], b, bshape[1], b, bshape[2], b).all(axis=(1, 3, 5))
        bi, bj, bk = np.nonzero(full)
        block_corners = np.stack([np.ravel_multi_index((b * (bi + dx), b * (bj + dy), b * (bk + dz)), shape)
                                  for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)], axis=1).reshape(-1, 8)
        for dx in range(b):
            for dy in range(b):
                for dz in range(b):
                    merged[b * bi + dx, b * bj + dy, b * bk + dz] = True
    single = np.flatnonzero(interior & ~merged.reshape(-1))

    # cells: the partial cubes (their corners inside, the vertices of the surface pieces' parts
    # in them), the interior cubes and blocks (their corners); as (cell, point) pairs sorted by
    # cell, points numbered nodes first, then the surface points
    pcube = np.flatnonzero(partial)
    cell_of_cube = np.full(ncubes, -1, dtype=np.int64)
    cell_of_cube[pcube] = np.arange(len(pcube))
    rows, cols = np.nonzero(corner_in[pcube])
    n_single, n_blocks = len(single), len(block_corners)
    ncells = len(pcube) + n_single + n_blocks
    pair_cell = np.concatenate([rows, cell_of_cube[clip_cube_all],
                                np.repeat(len(pcube) + np.arange(n_single), 8),
                                np.repeat(len(pcube) + n_single + np.arange(n_blocks), 8)]).astype(np.int64)
    pair_point = np.concatenate([corners[pcube][rows, cols], nnodes + np.arange(len(clip_all)),
                                 corners[single].reshape(-1), block_corners.reshape(-1)]).astype(np.int64)
    del corners, corner_in
    order = np.argsort(pair_cell, kind="stable")
    pair_cell, pair_point = pair_cell[order], pair_point[order]
    used, pair_point = np.unique(pair_point, return_inverse=True)
    points = np.concatenate([grid.nodes(used[used < nnodes]), clip_all[used[used >= nnodes] - nnodes]])
    cell_start = np.searchsorted(pair_cell, np.arange(ncells))
    cell_end = np.searchsorted(pair_cell, np.arange(ncells), side="right")
    has_points = cell_end > cell_start  # a partial cube may hold no point of the solid
    cell_first = np.minimum(cell_start, len(pair_cell) - 1)
    pc_pts = points[pair_point]
    cell_lo, cell_hi = np.minimum.reduceat(pc_pts, cell_first), np.maximum.reduceat(pc_pts, cell_first)
    cell_mid = (cell_lo + cell_hi) / 2
    # each cell's lowest and highest point along each axis (the first and last of its points
    # sorted by that coordinate): a ball missing one of them does not hold the cell
    by_axis = [np.lexsort((pc_pts[:, axis], pair_cell)) for axis in range(3)]
    cell_extremes = np.stack([pc_pts[order[at]] for order in by_axis
                              for at in (cell_first, np.maximum(cell_end - 1, 0))], axis=1)
    del by_axis
    cell_reach = np.maximum.reduceat(np.linalg.norm(pc_pts - cell_mid[pair_cell], axis=1), cell_first)
    cell_size = cell_end - cell_start

    def depth(p: NDArray[np.float64], inside_p: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """A lower bound of each point's depth in the solid (negative: its distance outside);
        inside: given, or where some geometry's winding number says so."""
        if inside_p is None:
            inside_p = np.zeros(len(p), dtype=bool)
            for s in solids:
                inside_p |= np.abs(_winding(p, s.vertices, s.triangles)) > 0.5
        d = surface.distance(p)
        return np.where(inside_p, d, -d) - shrink

    cell_ids = np.flatnonzero(has_points)
    mids, reaches = cell_mid[cell_ids], cell_reach[cell_ids]

    cell_tree = cKDTree(mids)
    reach_max = float(reaches.max()) if len(reaches) else 0.0

    def holds_all(centers: NDArray[np.float64], radius: NDArray[np.float64]) -> list[NDArray[np.int32]]:
        """For each ball, the cells all of whose points lie in it: those whose bounding ball
        does or whose box does, and of the others whose bounding ball the sphere crosses and
        whose extreme points it holds, the ones whose points do. The balls go in groups of
        similar radius; a group's (ball, cell) pairs within reach come from the cells' k-d tree
        in one query, and every pair's points are tested at once."""
        out: list[NDArray[np.int32]] = [np.zeros(0, dtype=np.int32)] * len(centers)
        by_radius = np.argsort(radius, kind="stable")
        for lo in range(0, len(centers), _HOLDS_GROUP):
            group = by_radius[lo:lo + _HOLDS_GROUP]
            pairs = cKDTree(centers[group]).sparse_distance_matrix(
                cell_tree, float(radius[group].max()) + reach_max, output_type="ndarray")
            ball, cell, dist = group[pairs["i"]], pairs["j"].astype(np.int64), pairs["v"]
            rr = radius[ball]
            sure = dist + reaches[cell] <= rr
            maybe = np.flatnonzero(~sure & (dist - reaches[cell] <= rr))
            held = sure
            if len(maybe):
                # a ball holding the cell's box holds the cell; one missing an extreme point not
                mc = cell_ids[cell[maybe]]
                c, r2 = centers[ball[maybe]], rr[maybe] ** 2
                box_far = np.maximum(np.abs(cell_lo[mc] - c), np.abs(cell_hi[mc] - c))
                held = sure.copy()
                held[maybe[np.einsum("ij,ij->i", box_far, box_far) <= r2]] = True
                ext = cell_extremes[mc] - c[:, None]
                open_ = (np.einsum("ikj,ikj->ik", ext, ext) <= r2[:, None]).all(axis=1) & ~held[maybe]
                maybe = maybe[open_]
            if len(maybe):
                mc = cell_ids[cell[maybe]]
                idx = _ranges(cell_start[mc], cell_end[mc])
                diff = pc_pts[idx] - np.repeat(centers[ball[maybe]], cell_size[mc], axis=0)
                inside_p = np.einsum("ij,ij->i", diff, diff) <= np.repeat(rr[maybe] ** 2, cell_size[mc])
                held[maybe] = np.logical_and.reduceat(inside_p, np.cumsum(cell_size[mc]) - cell_size[mc])
            ball, cell = ball[held], cell_ids[cell[held]]
            order = np.lexsort((cell, ball))
            ball, cell = ball[order], cell[order].astype(np.int32)
            bounds = np.searchsorted(ball, group, side="left"), np.searchsorted(ball, group, side="right")
            for g, a, b in zip(group, *bounds):
                out[g] = cell[a:b]
        return out

    # candidates: inside nodes near the medial axis (where the distance transform stops growing)
    inside3 = inside.reshape(shape)
    edt = ndimage.distance_transform_edt(inside3, sampling=res)
    padded = np.pad(edt, 1)
    medial = inside3.copy()
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if dx or dy or dz:
                    nb = padded[1 + dx: 1 + dx + shape[0], 1 + dy: 1 + dy + shape[1], 1 + dz: 1 + dz + shape[2]]
                    medial &= nb < edt + _MEDIAL_SLOPE * res * math.sqrt(dx * dx + dy * dy + dz * dz)
    # at most _MAX_CANDIDATES: the deepest medial node of each block of t^3 nodes, t the
    # smallest that keeps that many (neighbours hold nearly the same cells)
    t = 1
    while int(medial.sum()) > _MAX_CANDIDATES * t ** 3 and t < 4:
        t += 1
    key = np.where(medial, edt, -1.0)
    m0, m1, m2 = (x + (-x) % t for x in shape)
    blocks = np.pad(key, [(0, m0 - shape[0]), (0, m1 - shape[1]), (0, m2 - shape[2])], constant_values=-1.0)
    blocks = blocks.reshape(m0 // t, t, m1 // t, t, m2 // t, t).transpose(0, 2, 4, 1, 3, 5).reshape(-1, t ** 3)
    best = np.argmax(blocks, axis=1)
    bi, bj, bk = np.unravel_index(np.arange(len(blocks)), (m0 // t, m1 // t, m2 // t))
    di, dj, dk = np.unravel_index(best, (t, t, t))
    ok_b = blocks[np.arange(len(blocks)), best] >= 0
    cand = np.ravel_multi_index((t * bi[ok_b] + di[ok_b], t * bj[ok_b] + dj[ok_b], t * bk[ok_b] + dk[ok_b]), shape)
    # ... moved deeper (away from their nearest surface point, within the ball they are the
    # centre of, so inside still), and the primitives' own medial points
    cand_centers = np.concatenate([_ascend(grid.nodes(cand), surface, res), *(_medial_points(s.geometry, res) for s in solids)])
    cand_radius = depth(cand_centers, np.ones(len(cand_centers), dtype=bool)) + eps
    ok = cand_radius > 0
    cand_centers, cand_radius = cand_centers[ok], cand_radius[ok]
    keep = _undominated(cand_centers, cand_radius, _DOMINATED * res)
    cand_centers, cand_radius = cand_centers[keep], cand_radius[keep]

    uncovered = has_points.copy()
    chosen: list[tuple[NDArray[np.float64], float, NDArray[Any]]] = []

    def select(centers: NDArray[np.float64], radius: NDArray[np.float64]) -> None:
        """Cover the uncovered cells the balls (centers, radius) can hold: repeatedly take the
        uncovered cell the fewest balls hold, and of those balls the one that holds the most
        uncovered cells (on an interval, the optimal cover; a set cover's greedy that places
        spheres from the solid's ends inwards, not from its middle out)."""
        covs = holds_all(centers, radius)
        lens = np.array([len(c) for c in covs], dtype=np.int64)
        if not lens.sum():
            return
        cells_cat = np.concatenate(covs)
        cand_cat = np.repeat(np.arange(len(covs)), lens)
        order = np.argsort(cells_cat, kind="stable")
        cand_by_cell = cand_cat[order]
        c_start = np.searchsorted(cells_cat[order], np.arange(ncells))
        c_end = np.searchsorted(cells_cat[order], np.arange(ncells), side="right")
        ncov = c_end - c_start
        gain = np.array([int(uncovered[c].sum()) for c in covs], dtype=np.int64)
        todo = uncovered & (ncov > 0)
        target = todo.copy()  # the cells this call covers
        picked: list[int] = []
        while todo.any():
            open_cells = np.flatnonzero(todo)
            rare = open_cells[int(np.argmin(ncov[open_cells]))]
            js = cand_by_cell[c_start[rare]:c_end[rare]]
            j = int(js[int(np.argmax(gain[js]))])
            newly = covs[j][todo[covs[j]]]
            picked.append(j)
            todo[newly] = False
            gain -= np.bincount(cand_by_cell[_ranges(c_start[newly], c_end[newly])], minlength=len(covs))
        # local search: two spheres whose cells (those no other picked sphere holds) one
        # candidate holds are replaced by it, while any pair is
        masks_cache: dict[int, NDArray[np.bool_]] = {}

        def mask(j: int) -> NDArray[np.bool_]:
            m = masks_cache.get(j)
            if m is None:
                m = masks_cache[j] = np.zeros(ncells, dtype=bool)
                m[covs[j]] = True
            return m

        masks = [mask(j) for j in picked]
        count = np.sum(masks, axis=0) if masks else np.zeros(ncells, dtype=np.int64)
        # a candidate replacing x and y holds the cells x alone holds: the candidates that hold
        # them (None: x holds no cell alone) rule out most pairs before their cells are compared
        unknown = object()
        holders: list[Any] = [unknown] * len(picked)

        def holders_of(x: int) -> set[int] | None:
            if holders[x] is unknown:
                own = np.flatnonzero(masks[x] & target & (count == 1))
                if len(own):
                    rare = own[int(np.argmin(ncov[own]))]
                    js = cand_by_cell[c_start[rare]:c_end[rare]]
                    holders[x] = {int(k) for k in js[lens[js] >= len(own)] if mask(int(k))[own].all()}
                else:
                    holders[x] = None
            return holders[x]  # type: ignore[no-any-return]

        improved = True
        while improved and len(picked) > 1:
            improved = False
            x = 0
            while x < len(picked):
                y = x + 1
                while y < len(picked):
                    hx, hy = holders_of(x), holders_of(y)
                    if hx is not None and hy is not None and not (hx & hy):
                        y += 1
                        continue
                    ma, mb = masks[x], masks[y]
                    alone = np.flatnonzero((ma | mb) & target & (count - ma - mb == 0))
                    j = -1
                    if len(alone):
                        rare = alone[int(np.argmin(ncov[alone]))]
                        js = cand_by_cell[c_start[rare]:c_end[rare]]
                        js = js[lens[js] >= len(alone)]
                        fits = [int(k) for k in js if mask(int(k))[alone].all()]
                        if fits:
                            j = max(fits, key=lambda k: lens[k])
                    if j < 0:
                        y += 1
                        continue
                    mj = mask(j)
                    count = count - ma - mb + mj
                    picked[x], masks[x] = j, mj
                    del picked[y], masks[y]
                    holders = [unknown] * len(picked)
                    improved = True
                x += 1
        for j in picked:
            chosen.append((centers[j], float(radius[j]), covs[j]))
        uncovered[target] = False

    select(cand_centers, cand_radius)
    # cells no candidate holds (thin parts): balls about the cells themselves, their centre
    # taken as outside the solid (a conservative radius), each holding at least its own cell
    while uncovered.any():
        rest = np.flatnonzero(uncovered)
        before = len(rest)
        centers = cell_mid[rest]
        radius = np.maximum(eps - surface.distance(centers) - shrink, cell_reach[rest] * (1 + 1e-12) + 1e-12)
        select(centers, radius)
        if int(uncovered.sum()) == before:  # each ball holds its own cell: never happens
            raise RuntimeError(f"link '{link}': {before} cells could not be covered")

    # drop spheres whose cells others hold too (the last picked, the smallest gains, first)
    count = np.zeros(ncells, dtype=np.int64)
    for _, _, cov in chosen:
        count[cov] += 1
    kept: list[int] = []
    for n in range(len(chosen) - 1, -1, -1):
        cov = chosen[n][2]
        if np.all(count[cov] >= 2):
            count[cov] -= 1
        else:
            kept.append(n)
    spheres = [chosen[n] for n in reversed(kept)]

    def farthest(cells: NDArray[np.int64], center: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each cell's largest distance from ``center`` (cells with points)."""
        dist = np.linalg.norm(pc_pts[_ranges(cell_start[cells], cell_end[cells])] - center, axis=1)
        return np.maximum.reduceat(dist, np.cumsum(cell_size[cells]) - cell_size[cells])

    def points_of(cells: NDArray[np.int64]) -> NDArray[np.float64]:
        return points[np.unique(pair_point[_ranges(cell_start[cells], cell_end[cells])])]

    # each cell to the sphere that holds it with the most room
    best = np.full(ncells, -np.inf)
    owner = np.full(ncells, -1, dtype=np.int64)
    for n, (cen, rad, cov) in enumerate(spheres):
        far = farthest(cov, cen)
        room = rad - far
        better = room > best[cov]
        best[cov[better]] = room[better]
        owner[cov[better]] = n

    # each sphere shrinks to its cells' farthest point, or becomes their smallest enclosing ball
    # when that reaches less far beyond the solid
    options = []
    for n, (cen, _, _) in enumerate(spheres):
        cells = np.flatnonzero(owner == n)
        if len(cells):
            pts = points_of(cells)
            c1, r1 = _enclosing_ball(pts, cen)
            options.append((cen, float(np.linalg.norm(pts - cen, axis=1).max()), c1, r1))
    if not options:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    both = np.array([o[0] for o in options] + [o[2] for o in options])
    d = depth(both)
    k = len(options)
    out_c, out_r, out_x = [], [], []
    for n, (c0, r0, c1, r1) in enumerate(options):
        x0, x1 = r0 - d[n], r1 - d[k + n]
        if x1 < x0:
            c0, r0, x0 = c1, r1, x1
        out_c.append(c0)
        out_r.append(r0)
        out_x.append(max(x0, 0.0))
    return np.array(out_c), np.array(out_r), np.array(out_x)


def _ascend(points: NDArray[np.float64], surface: _Surface, res: float) -> NDArray[np.float64]:
    """Points inside the solid moved to where their distance to the surface grows most, along
    the direction away from their nearest surface point, by steps shorter than that distance
    (so that they stay inside)."""
    p = np.array(points, dtype=np.float64)
    if not len(p):
        return p
    d, q = surface.closest(p)
    for _ in range(2):
        ok = d > 0
        u = np.where(ok[:, None], (p - q) / np.where(ok, d, 1.0)[:, None], 0.0)
        best_p, best_d, best_q = p, d, q
        for t in (0.2, 0.5, 1.0):
            step = np.minimum(t * res, 0.9 * d)
            p2 = p + u * step[:, None]
            d2, q2 = surface.closest(p2)
            better = d2 > best_d
            best_p = np.where(better[:, None], p2, best_p)
            best_q = np.where(better[:, None], q2, best_q)
            best_d = np.where(better, d2, best_d)
        p, d, q = best_p, best_d, best_q
    return p


def _medial_points(g: LinkGeometry, res: float) -> NDArray[np.float64]:
    """Points of a primitive's medial axis (link frame), ``res / 2`` apart: a sphere's centre,
    a cylinder's or capsule's axis, a box's centre plane between its two longest axes."""
    if g.kind == "mesh":
        return np.zeros((0, 3))
    if g.kind == "sphere":
        local = np.zeros((1, 3))
    elif g.kind in ("cylinder", "capsule"):
        r, h = g.size
        reach = h if g.kind == "capsule" else max(h - r, 0.0)
        n = int(math.ceil(2 * reach / (res / 2))) + 1
        local = np.column_stack([np.zeros(n), np.zeros(n), np.linspace(-reach, reach, n)])
    else:
        half = np.array(g.size)
        axes = np.argsort(half)[::-1]
        ext = np.maximum(half - half[axes[2]], 0.0)
        n0 = int(math.ceil(2 * ext[axes[0]] / (res / 2))) + 1
        n1 = int(math.ceil(2 * ext[axes[1]] / (res / 2))) + 1
        u, v = np.meshgrid(np.linspace(-ext[axes[0]], ext[axes[0]], n0), np.linspace(-ext[axes[1]], ext[axes[1]], n1))
        local = np.zeros((u.size, 3))
        local[:, axes[0]], local[:, axes[1]] = u.ravel(), v.ravel()
    return _transform(g.placement, local)


def _undominated(centers: NDArray[np.float64], radius: NDArray[np.float64], tol: float) -> NDArray[np.int64]:
    """The balls (largest first) that no larger ball kept before them holds to within ``tol``
    (ball i is held by ball j when |c_i - c_j| + r_i <= r_j + tol): the cells a dropped ball
    holds lie in a kept one, but for a shell of width ``tol``, which other balls hold (or the
    cover's spheres of its own). Near the medial axis many candidates are such balls (a
    sphere's centre region: thousands of balls within a tenth of a millimetre of the one at its
    centre)."""
    order = np.argsort(-radius, kind="stable")
    kept_c = np.empty((len(order), 3))
    kept_r = np.empty(len(order))
    kept: list[int] = []
    for i in order:
        n = len(kept)
        if n:
            d = kept_c[:n] - centers[i]
            if np.any(np.sqrt(np.einsum("ij,ij->i", d, d)) + radius[i] <= kept_r[:n] + tol):
                continue
        kept_c[n], kept_r[n] = centers[i], radius[i]
        kept.append(int(i))
    return np.sort(np.array(kept, dtype=np.int64))


def _ranges(starts: NDArray[np.int64], ends: NDArray[np.int64]) -> NDArray[np.int64]:
    """The concatenated ranges ``starts[i]:ends[i]``."""
    lens = ends - starts
    total = int(lens.sum())
    if not total:
        return np.zeros(0, dtype=np.int64)
    offsets = np.cumsum(lens) - lens
    return np.repeat(starts - offsets, lens) + np.arange(total)


def _enclosing_ball(points: NDArray[np.float64], start: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """A ball holding every point: the Badoiu-Clarkson iteration towards the smallest one from
    ``start``; the radius is the exact largest distance from the centre found."""
    c = np.array(start, dtype=np.float64)
    if len(points) > 64:  # the smallest enclosing ball of the points is that of their hull's vertices
        from scipy.spatial import ConvexHull, QhullError

        try:
            points = points[ConvexHull(points).vertices]
        except (QhullError, ValueError):  # flat or too few points: all of them
            pass
    # the iteration runs on at most _MEB_POINTS of them (every k-th: a curved surface's points
    # are all on its hull), then a few steps on all; any centre is valid, its radius exact
    sample = points[:: max(1, len(points) // _MEB_POINTS)]
    # the farthest point from c maximises |p|^2 - 2 p.c (one product per iteration)
    for pts, steps, first in ((sample, _MEB_ITERATIONS, 1), (points, 10, _MEB_ITERATIONS + 1)):
        norms = np.einsum("ij,ij->i", pts, pts)
        for i in range(first, first + steps):
            c = c + (pts[int(np.argmax(norms - 2.0 * (pts @ c)))] - c) / (i + 1)
    return c, float(np.sqrt(np.einsum("ij,ij->i", points - c, points - c).max()))
