"""A 3D view of a planned path that anyone can open: one self-contained HTML file.

The file is a `viser <https://viser.studio>`_ scene recording embedded in viser's single-file web
client: the robot's visual meshes (from its URDF, as Pinocchio/coal load them), the obstacles,
the floor and the hand's trajectory, with a playback bar (play / pause / scrub / speed) and an
orbit camera. Nothing is fetched when it is opened: the JavaScript, the meshes and the
animation are all inside the file, so it works offline, from disk, in any recent browser.

>>> from genplan.viewer import export_plan_html
>>> export_plan_html("panda_shelf", "panda_shelf.html")          # plan one query, write the view

or, for a path you already have (rows are configurations)::

    from genplan.viewer import export_html
    export_html(robot, result.path, "plan.html", boxes=env.boxes, halfspaces=env.halfspaces)

or a run of :func:`genplan.execute` beside its plan (the executed motion as a translucent ghost
robot with its own trail, on the planned one's clock)::

    from genplan.viewer import export_execution_html
    export_execution_html(robot, log, "run.html", planned=trajectory, scene="panda_shelf")

From the shell: ``genplan view panda_shelf --out panda_shelf.html [--sampler S --seed N]``, and
``genplan execute ... --html run.html``.

Needs the optional dependencies ``viser`` and ``pycollada`` (``pip install 'genplan[viewer]'``);
without pycollada, COLLADA meshes (the Panda's) are drawn in one colour. Building the recording
starts viser's websocket server in a thread of this process (no subprocess), bound to an
ephemeral port on 127.0.0.1; it is stopped before :func:`export_html` returns, also on errors.
A file is ~2.6 MB (0.8 MB of it the web client), whatever the path's length: at most
``max_frames`` states are animated.
"""

from __future__ import annotations

import contextlib
import functools
import html
import io
import logging
import math
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan._files import write_text
from genplan._arrays import as_float_array, error_class
from genplan.errors import GenplanError, RobotFileError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot

if TYPE_CHECKING:
    from genplan._execution import ExecutionLog
    from genplan.trajectory import Trajectory

__all__ = ["CLOUD_POINT_SIZE", "DEFAULT_FPS", "DEFAULT_MAX_FRAMES", "MAX_CLOUD_POINTS", "export_execution_html", "export_html", "export_plan_html",
           "subsample_path"]

#: Playback rate of the exported animation (frames per second at speed 1x).
DEFAULT_FPS: float = 15.0
#: The path is subsampled to at most this many frames (the trail keeps every state).
DEFAULT_MAX_FRAMES: int = 150
#: A point cloud is drawn with at most this many of its points (evenly strided): 12 bytes of
#: position and 3 of colour each in the file.
MAX_CLOUD_POINTS: int = 200_000
#: The drawn size (m) of a cloud's points given to :func:`export_html` as ``clouds``.
CLOUD_POINT_SIZE: float = 0.01

_HalfSpace = tuple[str, Sequence[float], float]

_OBSTACLE_COLOR = (205, 133, 63)
_TRAIL_COLOR = (230, 40, 40)
_START_COLOR = (40, 170, 60)
_GOAL_COLOR = (40, 90, 230)
_EXECUTED_COLOR = (150, 60, 200)
#: a cloud's points from low to high (height read by colour)
_CLOUD_LOW_COLOR = (40, 110, 200)
_CLOUD_HIGH_COLOR = (240, 200, 60)
#: the executed robot's opacity: a ghost over the planned one
_GHOST_OPACITY = 0.45


def _require_viser() -> Any:
    try:
        import viser
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "genplan.viewer needs the optional dependency 'viser': pip install 'genplan[viewer]' "
            "(or pip install viser)"
        ) from exc
    return viser


def subsample_path(path: NDArray[np.float64], max_frames: int) -> NDArray[np.intp]:
    """Indices of at most ``max_frames`` states spread evenly along the path (by index, which
    for the planner's dense paths is by distance), always the first and the last."""
    if max_frames < 2:
        raise SettingsError(f"max_frames must be >= 2, got {max_frames}")
    m = len(path)
    if m <= max_frames:
        return np.arange(m)
    return np.unique(np.round(np.linspace(0, m - 1, max_frames)).astype(np.intp))


# --- geometry -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Part:
    """One visual part: a triangle mesh in its joint's frame, with its colour."""

    name: str
    joint: int
    placement: pin.SE3
    vertices: NDArray[np.float32]
    faces: NDArray[np.uint32]
    color: tuple[int, int, int]


def _rgb(c: ArrayLike) -> tuple[int, int, int]:
    a = np.clip(np.asarray(c, dtype=np.float64)[:3], 0.0, 1.0)
    return (int(round(a[0] * 255)), int(round(a[1] * 255)), int(round(a[2] * 255)))


def _mesh_arrays(go: pin.GeometryObject) -> tuple[NDArray[np.float32], NDArray[np.uint32]] | None:
    """Vertices and triangles of one geometry (coal already applied the URDF's mesh scale)."""
    g = go.geometry
    kind = type(g).__name__
    if hasattr(g, "num_tris") and hasattr(g, "tri_indices"):
        v = np.asarray(g.vertices(), dtype=np.float32).reshape(-1, 3)
        n = int(g.num_tris)
        f = np.empty((n, 3), dtype=np.uint32)
        for i in range(n):
            t = g.tri_indices(i)
            f[i] = (t[0], t[1], t[2])
        if np.prod(np.sign(np.asarray(go.meshScale, dtype=np.float64))) < 0:
            f = f[:, ::-1].copy()  # a mirrored mesh: keep the triangles facing outwards
        return v, f
    import trimesh.creation as tc

    if kind == "Box":
        m = tc.box(extents=2.0 * np.asarray(g.halfSide))
    elif kind == "Cylinder":
        m = tc.cylinder(radius=float(g.radius), height=2.0 * float(g.halfLength), sections=24)
    elif kind == "Sphere":
        m = tc.icosphere(subdivisions=2, radius=float(g.radius))
    elif kind == "Capsule":
        m = tc.capsule(height=2.0 * float(g.halfLength), radius=float(g.radius), count=(16, 16))
    else:
        return None
    return np.asarray(m.vertices, dtype=np.float32), np.asarray(m.faces, dtype=np.uint32)


def _colored_pieces(go: pin.GeometryObject) -> list[tuple[NDArray[np.float32], NDArray[np.uint32], tuple[int, int, int]]] | None:
    """A COLLADA mesh split by material colour (trimesh + pycollada), or None when that is not
    possible (no pycollada, not a .dae, or a file trimesh cannot read): coal's mesh is used then."""
    if not str(go.meshPath).lower().endswith(".dae"):
        return None
    try:
        import collada  # noqa: F401  - trimesh's COLLADA loader needs pycollada
        import trimesh
    except ImportError:
        return None
    try:
        meshes = trimesh.load(go.meshPath, force="scene").dump()
    except Exception:  # a file trimesh cannot read: coal read it, use coal's mesh
        return None
    scale = np.asarray(go.meshScale, dtype=np.float64)
    flip = bool(np.prod(np.sign(scale)) < 0)
    by_color: dict[tuple[int, int, int], list[tuple[NDArray[np.float64], NDArray[np.int64]]]] = {}
    for m in meshes:
        if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
            continue
        color = (200, 200, 200)
        material = getattr(m.visual, "material", None)
        main = getattr(material, "main_color", None)
        if main is not None:
            color = (int(main[0]), int(main[1]), int(main[2]))
        elif getattr(m.visual, "kind", None) == "face":
            color = tuple(int(c) for c in np.asarray(m.visual.face_colors)[0, :3])  # type: ignore[assignment]
        m = m.copy()
        m.merge_vertices()
        by_color.setdefault(color, []).append((np.asarray(m.vertices) * scale, np.asarray(m.faces)))
    pieces = []
    for color, items in by_color.items():
        offsets = np.cumsum([0] + [len(v) for v, _ in items[:-1]])
        v = np.concatenate([v for v, _ in items]).astype(np.float32)
        f = np.concatenate([f + o for (_, f), o in zip(items, offsets)]).astype(np.uint32)
        if flip:
            f = f[:, ::-1].copy()
        pieces.append((v, f, color))
    return pieces or None


@functools.lru_cache(maxsize=4)
def _visual_parts(robot: Robot, geometry: str) -> tuple[_Part, ...]:
    """The robot's meshes by joint (cached: robots from :func:`genplan.load` are cached too)."""
    if geometry == "visual":
        geom = pin.buildGeomFromUrdf(
            robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL,
            package_dirs=[str(p) for p in robot.package_dirs],
        )
    elif geometry == "collision":
        geom = robot.collision_model
    else:
        raise UnknownNameError(f"geometry must be 'visual' or 'collision', got {geometry!r}")
    parts: list[_Part] = []
    skipped: list[str] = []
    for go in geom.geometryObjects:
        joint, placement = int(go.parentJoint), go.placement.copy()
        pieces = _colored_pieces(go) if geometry == "visual" else None
        if pieces is not None:
            for k, (v, f, color) in enumerate(pieces):
                parts.append(_Part(f"{go.name}_{k}", joint, placement, v, f, color))
            continue
        arrays = _mesh_arrays(go)
        if arrays is None:
            skipped.append(f"{go.name} ({type(go.geometry).__name__})")
            continue
        color = _rgb(go.meshColor) if geometry == "visual" else (150, 170, 200)
        parts.append(_Part(go.name, joint, placement, *arrays, color))
    parts.extend(_attached_parts(robot))
    if skipped:
        warnings.warn(f"viewer: {robot.name}: shapes not drawn: {', '.join(skipped)}", stacklevel=3)
    if not parts:
        raise RobotFileError(f"robot '{robot.name}' has no {geometry} geometry to draw")
    return tuple(parts)


def _attached_parts(robot: Robot) -> list[_Part]:
    """The robot's attached objects (:meth:`~genplan.robots.Robot.with_attached`) as parts on
    their links' joints, drawn as the scene's shapes are (:func:`_scene_shapes`)."""
    import dataclasses

    from genplan.robots import _compose
    from genplan.scene import Scene

    parts: list[_Part] = []
    for a in getattr(robot, "attached", {}).values():
        shape = dataclasses.replace(a.shape, name=a.name, pose=_compose(a.pose, a.shape.pose))
        _, meshes = _scene_shapes(Scene(name=a.name, obstacles=(shape,)))
        frame = robot.model.frames[robot.model.getFrameId(a.link)]
        for name, v, f in meshes:
            parts.append(_Part(name, int(frame.parentJoint), frame.placement.copy(), v, f, (205, 133, 63)))
    return parts


def _world_points(parts: Sequence[_Part], joints: dict[int, pin.SE3], stride: int = 7) -> NDArray[np.float64]:
    """A sample of the robot's vertices in the world frame, at joint placements ``joints``."""
    pts = []
    for p in parts:
        M = joints.get(p.joint, pin.SE3.Identity()) * p.placement
        v = p.vertices[::stride].astype(np.float64)
        pts.append(v @ M.rotation.T + M.translation)
    return np.concatenate(pts)


def _wxyz(rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    q = pin.Quaternion(np.asarray(rotation, dtype=np.float64))  # coeffs() are x, y, z, w
    return np.array([q.w, q.x, q.y, q.z])


def _halfspace_frame(normal: NDArray[np.float64], offset: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A point on the plane n.x = offset and the rotation taking +z to n."""
    n = normal / np.linalg.norm(normal)
    point = n * (offset / float(np.linalg.norm(normal)))
    rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), n).matrix()
    return point, rot


# --- export -------------------------------------------------------------------------------------


@contextlib.contextmanager
def _viser_server() -> Iterator[Any]:
    """viser's server on an ephemeral localhost port (a thread of this process), always stopped."""
    viser = _require_viser()
    # viser prints a banner when its server starts and a line when it stops (rich, to stdout,
    # whatever ``verbose``): keep an export quiet.
    with contextlib.ExitStack() as stack:
        logger = logging.getLogger("websockets")
        level = logger.level
        logger.setLevel(logging.ERROR)
        stack.callback(logger.setLevel, level)
        with contextlib.redirect_stdout(io.StringIO()):
            server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)

        def stop() -> None:
            with contextlib.redirect_stdout(io.StringIO()):
                server.stop()

        stack.callback(stop)
        yield server


@dataclass(frozen=True)
class _Obstacle:
    name: str
    half_extents: NDArray[np.float64]
    center: NDArray[np.float64]


def _check_boxes(boxes: Sequence[Any]) -> list[_Obstacle]:
    out = []
    for i, b in enumerate(boxes):
        try:
            name = str(b.name)
            h = np.asarray(b.half_extents, dtype=np.float64)
            c = np.asarray(b.center, dtype=np.float64)
        except (AttributeError, TypeError, ValueError) as exc:
            raise GenplanError(f"boxes[{i}]: expected an object with name, half_extents and center "
                               f"(such as planning.Box): {exc}") from None
        if h.shape != (3,) or c.shape != (3,) or not (np.all(np.isfinite(h)) and np.all(np.isfinite(c))):
            raise error_class([h, c], h.shape == c.shape == (3,))(
                f"boxes[{i}] ({name}): half_extents and center must be 3 finite numbers, "
                f"got {b.half_extents!r} and {b.center!r}")
        if np.any(h <= 0):
            raise GenplanError(f"boxes[{i}] ({name}): half_extents must be positive, got {b.half_extents!r}")
        out.append(_Obstacle(name, h, c))
    return out


def _check_halfspaces(halfspaces: Sequence[_HalfSpace]) -> list[tuple[str, NDArray[np.float64], float]]:
    out = []
    for i, hs in enumerate(halfspaces):
        try:
            name, normal, offset = hs
            n = np.asarray(normal, dtype=np.float64)
            d = float(offset)
        except (TypeError, ValueError) as exc:
            raise GenplanError(f"halfspaces[{i}]: expected (name, normal, offset): {exc}") from None
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-12 or not math.isfinite(d):
            raise error_class([*n.ravel(), d], n.shape == (3,))(
                f"halfspaces[{i}] ({name}): the normal must be 3 finite numbers, not all zero, "
                f"and the offset finite; got {normal!r}, {offset!r}")
        out.append((str(name), n, d))
    return out


def _scene_shapes(scene: Any) -> tuple[list[tuple[str, NDArray[np.float64], float]],
                                        list[tuple[str, NDArray[np.float32], NDArray[np.uint32]]]]:
    """A scene's half-spaces ``(name, normal, offset)`` and its other obstacles as triangle
    meshes in the world ``(name, vertices, faces)``."""
    import trimesh
    import trimesh.creation as tc

    from genplan.scene import Box, Capsule, Cylinder, HalfSpace, Mesh, Points, Sphere, load_scene

    s = load_scene(scene)
    planes: list[tuple[str, NDArray[np.float64], float]] = []
    meshes: list[tuple[str, NDArray[np.float32], NDArray[np.uint32]]] = []
    for o in s.obstacles:
        if isinstance(o, HalfSpace):
            planes.append((o.name, np.asarray(o.normal, dtype=np.float64), float(o.offset)))
            continue
        if isinstance(o, Points):  # drawn as points: _scene_clouds
            continue
        if isinstance(o, Box):
            m = tc.box(extents=2.0 * np.asarray(o.half_extents))
        elif isinstance(o, Sphere):
            m = tc.icosphere(subdivisions=2, radius=float(o.radius))
        elif isinstance(o, Cylinder):
            m = tc.cylinder(radius=float(o.radius), height=float(o.length), sections=24)
        elif isinstance(o, Capsule):
            m = tc.capsule(height=float(o.length), radius=float(o.radius), count=(16, 16))
        elif isinstance(o, Mesh):
            loaded = trimesh.load_mesh(str(o.path))
            # drawn as collision keeps it (docs/SCENES.md): the convex hull for "hull"; the
            # triangles for "mesh", and for "decomposed", whose convex parts follow the triangles
            m = loaded.convex_hull if o.shape == "hull" else loaded
            m.apply_scale(np.asarray(o.scale, dtype=np.float64))
        else:  # pragma: no cover - Scene admits only the classes above
            raise GenplanError(f"scene '{s.name}': cannot draw {type(o).__name__} '{o.name}'")
        t = np.eye(4)
        t[:3, :3] = o.pose.matrix()
        t[:3, 3] = o.pose.position
        m.apply_transform(t)
        meshes.append((o.name, np.asarray(m.vertices, dtype=np.float32), np.asarray(m.faces, dtype=np.uint32)))
    return planes, meshes


def _scene_clouds(scene: Any) -> list[tuple[str, NDArray[np.float64], float]]:
    """A scene's point clouds ``(name, points (n, 3) in the world, drawn size)``: each point as
    wide as its collision ball (the file's points, before any voxel down-sampling)."""
    from genplan.scene import Points, load_scene

    return [(o.name, o.world_points(), 2.0 * float(o.radius)) for o in load_scene(scene).obstacles if isinstance(o, Points)]


def _check_clouds(clouds: Mapping[str, ArrayLike] | None) -> list[tuple[str, NDArray[np.float64], float]]:
    """``clouds`` ({name: points (n, 3)}) checked as a collision world's clouds are
    (:func:`genplan.clouds.check_points`), each drawn :data:`CLOUD_POINT_SIZE` wide."""
    from genplan.clouds import check_points

    if clouds is None:
        return []
    if not isinstance(clouds, Mapping):
        raise ShapeError(f"clouds: expected a mapping of names to (n, 3) points, got {type(clouds).__name__}")
    return [(str(name), check_points(pts, f"clouds['{name}']"), CLOUD_POINT_SIZE) for name, pts in clouds.items()]


def _cloud_arrays(points: NDArray[np.float64]) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
    """At most :data:`MAX_CLOUD_POINTS` of ``points`` (evenly strided) and their colours, from
    blue (lowest) to yellow (highest)."""
    step = -(-len(points) // MAX_CLOUD_POINTS)
    pts = points[::step]
    z = pts[:, 2]
    span = float(z.max() - z.min())
    f = ((z - z.min()) / span if span > 0 else np.zeros_like(z))[:, None]
    colors = (1.0 - f) * np.asarray(_CLOUD_LOW_COLOR) + f * np.asarray(_CLOUD_HIGH_COLOR)
    return pts.astype(np.float32), np.round(colors).astype(np.uint8)


def _legend(title: str, trail_label: str | None, obstacles: bool, executed: bool = False, points: bool = False) -> str:
    """A small fixed overlay: the title, what the colours mean, how to move the camera."""
    items = []
    if trail_label is not None:
        planned = "planned " if executed else ""
        items += [f'<span style="color:#e62828">&#9644;</span> {planned}{html.escape(trail_label)} path',
                  '<span style="color:#28aa3c">&#9679;</span> start',
                  '<span style="color:#285ae6">&#9679;</span> goal']
    if executed:
        items.append('<span style="color:#963cc8">&#9644;</span> executed'
                     + (f" {html.escape(trail_label)} path" if trail_label is not None else "")
                     + " and robot (translucent)")
    if obstacles:
        items.append('<span style="color:#cd853f">&#9632;</span> obstacles')
    if points:
        items.append('<span style="color:#286ec8">&#8226;</span><span style="color:#f0c83c">&#8226;</span>'
                     " point clouds (colour: height)")
    return (
        '<div id="genplan-legend" style="position:fixed;top:8px;right:12px;z-index:1000;'
        'pointer-events:none;font:13px/1.4 system-ui,sans-serif;color:#333;'
        'background:rgba(255,255,255,0.8);padding:6px 10px;border-radius:6px;max-width:45%">'
        f"<b>{html.escape(title)}</b><br>"
        + (" &nbsp;".join(items) + "<br>" if items else "")
        + '<span style="color:#777">drag: orbit &middot; right-drag: pan &middot; wheel: zoom'
        " &middot; bar below: play / pause / scrub / speed</span></div>"
    )


def _check_out(out: str | os.PathLike[str]) -> Path:
    p = Path(out)
    if p.is_dir():
        raise GenplanError(f"out: {p} is a directory; give a file name such as {p / 'plan.html'}")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OSError(f"out: cannot create the folder {p.parent}: {exc.strerror or exc}") from exc
    if not os.access(p.parent, os.W_OK):
        raise PermissionError(f"out: the folder {p.parent} is not writable")
    return p


def _motion(robot: Robot, value: Any, what: str) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
    """``(times or None, configurations (m, nq))`` of what :func:`export_html` draws: an
    :class:`~genplan._execution.ExecutionLog` (its motion ticks, timed from the motion's start),
    a :class:`~genplan.trajectory.Trajectory` or a mapping with ``t`` and ``q`` (timed), or
    configurations (untimed; one (nq,) configuration is a still view)."""
    from genplan._execution import ExecutionLog
    from genplan.trajectory import Trajectory

    times: Any = None
    if isinstance(value, ExecutionLog):
        names = value.meta.get("joint_names")
        if names is not None and tuple(names) != tuple(robot.joint_names):
            raise ShapeError(f"{what}: a run of the joints {list(names)}, not robot '{robot.name}' "
                             f"({list(robot.joint_names)})")
        a, b = value.motion_start, value.motion_end
        if b <= a:
            raise ShapeError(f"{what}: the run stopped before its motion started (tick {b} of a settle phase of {a})")
        times, q = value.t[a:b] - value.t[a], value.q[a:b]
    elif isinstance(value, Trajectory):
        times, q = value.t, value.q
    elif isinstance(value, Mapping):
        if "t" not in value or "q" not in value:
            raise ShapeError(f"{what}: a mapping needs 't' and 'q', got keys {sorted(value)}")
        times, q = value["t"], value["q"]
    else:
        q = value
    q = robot.check_configuration(q, what if times is None else f"{what}.q")
    if q.ndim == 1:
        q = q[None, :]
    if len(q) == 0:
        raise ShapeError(f"{what}: no configuration (shape (0, nq))")
    if times is None:
        return None, q
    t = as_float_array(times, f"{what}.t")
    if t.shape != (len(q),) or not np.all(np.isfinite(t)) or (len(t) > 1 and not np.all(np.diff(t) >= 0)):
        raise error_class(t, t.shape == (len(q),))(
            f"{what}.t: expected {len(q)} finite, non-decreasing times (one per configuration), got shape {t.shape}")
    return t - t[0], q


def _picks(times: NDArray[np.float64], at: NDArray[np.float64]) -> NDArray[np.intp]:
    """The sample of a timed motion shown at each frame time ``at``: the first at or after it
    (the last sample once the motion ended)."""
    return np.minimum(np.searchsorted(times, at), len(times) - 1).astype(np.intp)


def _trail(model: Any, data: Any, frame: int, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """The world position of ``frame`` at every configuration of ``q``."""
    pts = np.empty((len(q), 3))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, qi)
        pts[i] = data.oMf[frame].translation
    return pts


def export_html(
    robot: Robot,
    path: "ArrayLike | Trajectory | Mapping[str, Any]",
    out: str | os.PathLike[str],
    *,
    boxes: Sequence[Any] = (),
    halfspaces: Sequence[_HalfSpace] = (),
    fps: float = DEFAULT_FPS,
    max_frames: int = DEFAULT_MAX_FRAMES,
    title: str | None = None,
    geometry: str = "visual",
    trail_frame: str | None = None,
    ground: bool = True,
    dark_mode: bool = False,
    scene: Any = None,
    executed: "ExecutionLog | Trajectory | Mapping[str, Any] | ArrayLike | None" = None,
    clouds: Mapping[str, ArrayLike] | None = None,
) -> Path:
    """Write a self-contained HTML viewer of ``robot`` moving along ``path``; returns ``out``.

    Args:
        robot: the robot the configurations belong to (:func:`genplan.load`).
        path: (m, nq) configurations (one (nq,) configuration is a still view), finite; or a
            :class:`genplan.trajectory.Trajectory` (``result.trajectory()``) or a mapping with
            ``t`` and ``q``, played in real time: its state at every 1/``fps`` s (fewer frames,
            evenly timed, when that exceeds ``max_frames``).
        out: the HTML file to write (its folder is created).
        boxes: obstacles with ``name``, ``half_extents`` and ``center`` (e.g. ``env.boxes``).
        halfspaces: ``(name, normal, offset)`` planes (e.g. ``env.halfspaces``), drawn as a grid.
        scene: a :class:`genplan.scene.Scene` (or a shipped scene's name, or a scene file): every
            obstacle drawn in place (boxes, spheres, cylinders, capsules, meshes; half-spaces as
            grids; point clouds as points as wide as their balls), besides ``boxes`` and
            ``halfspaces``.
        clouds: point clouds to draw, ``{name: points (n, 3)}`` in the world frame (e.g. a depth
            camera's, :func:`genplan.clouds.points_from_depth`), as points
            :data:`CLOUD_POINT_SIZE` wide coloured by height; at most :data:`MAX_CLOUD_POINTS` of
            each (evenly strided).
        fps: playback rate of the subsampled frames at speed 1x.
        max_frames: at most this many frames are animated (evenly subsampled, first and last
            kept); the trail of ``trail_frame`` uses every state.
        title: the page's title (default: the robot and the path length).
        geometry: "visual" (the URDF's visual meshes) or "collision" (the collision model).
        trail_frame: a frame role or name whose trajectory is drawn (default: the hand, or the
            first "*hand" role: Talos's right hand).
        ground: without ``halfspaces``, draw a reference grid under the robot's lowest point.
        dark_mode: the viewer's dark theme.
        executed: a second motion of the same robot drawn beside ``path`` as a translucent robot
            with its own trail of ``trail_frame``: a run of :func:`genplan.execute` (an
            :class:`~genplan._execution.ExecutionLog`: its motion, timed from the motion's
            start), a Trajectory or a mapping with ``t`` and ``q`` (each on the clock of a timed
            ``path``: the frames span the longer of the two, the shorter holding its last
            state), or configurations beside configurations (matched by their position along
            each: the same fraction of its length). :func:`export_execution_html` draws a run
            beside its plan.

    Raises:
        GenplanError: wrong path shape or cloud (ShapeError), non-finite values (NonFiniteError), bad fps /
            max_frames (SettingsError), geometry (UnknownNameError), or an ``executed`` motion of
            another robot (ShapeError) or timed when ``path`` is not, or the other way round
            (SettingsError).
        OSError: ``out`` cannot be written.
        ImportError: viser is not installed.
    """
    if not (math.isfinite(fps) and fps > 0):
        raise SettingsError(f"fps must be a positive number, got {fps}")
    path_t, q = _motion(robot, path, "path")
    timed = path_t is not None
    exec_t: NDArray[np.float64] | None = None
    exec_q: NDArray[np.float64] | None = None
    if executed is not None:
        exec_t, exec_q = _motion(robot, executed, "executed")
        if (exec_t is None) == timed:
            raise SettingsError(
                "executed: a timed motion (a run, a Trajectory, t and q) is drawn beside a timed path and "
                f"configurations beside configurations; got {'configurations' if exec_t is None else 'a timed motion'} "
                f"beside {'a timed path' if timed else 'configurations'}")
    dt = 1.0 / fps
    if path_t is not None:  # played in real time: frames evenly spaced in time, fps of them per second
        duration = float(path_t[-1] if exec_t is None else max(path_t[-1], exec_t[-1]))
        count = int(min(max(max_frames, 2), max(2, math.floor(duration * fps) + 1)))
        if duration > 0 and (len(q) > 1 or (exec_q is not None and len(exec_q) > 1)):
            at = np.linspace(0.0, duration, count)
            dt = duration / (count - 1)
        else:
            at = np.zeros(1)
        picks = _picks(path_t, at)
        exec_picks = _picks(exec_t, at) if exec_t is not None else None
    elif exec_q is None:
        picks = subsample_path(q, max_frames)
        exec_picks = None
    else:  # configurations beside configurations: the same fraction of each one's length
        if max_frames < 2:
            raise SettingsError(f"max_frames must be >= 2, got {max_frames}")
        at = np.linspace(0.0, 1.0, max(1, min(max_frames, max(len(q), len(exec_q)))))
        picks = np.round(at * (len(q) - 1)).astype(np.intp)
        exec_picks = np.round(at * (len(exec_q) - 1)).astype(np.intp)
    obstacles = _check_boxes(boxes)
    planes = _check_halfspaces(halfspaces)
    shapes: list[tuple[str, NDArray[np.float32], NDArray[np.uint32]]] = []
    point_clouds = _check_clouds(clouds)
    if scene is not None:
        extra_planes, shapes = _scene_shapes(scene)
        planes += extra_planes
        point_clouds = _scene_clouds(scene) + point_clouds
    out_path = _check_out(out)
    frames = q[picks]
    exec_frames = exec_q[exec_picks] if exec_q is not None and exec_picks is not None else None

    if geometry not in ("visual", "collision"):
        raise UnknownNameError(f"geometry must be 'visual' or 'collision', got {geometry!r}")
    model = robot.model
    data = model.createData()
    parts = _visual_parts(robot, geometry)
    moving = sorted({p.joint for p in parts} - {0})
    if trail_frame is None:
        trail_frame = "hand" if "hand" in robot.frames else next(
            (r for r in robot.frames if r.endswith("hand")), None)
    trail_id = robot.frame_id(trail_frame) if trail_frame is not None else None

    def placements(qi: NDArray[np.float64]) -> dict[int, pin.SE3]:
        pin.forwardKinematics(model, data, qi)
        return {j: data.oMi[j].copy() for j in moving}

    trail = _trail(model, data, trail_id, q) if trail_id is not None else None
    exec_trail = _trail(model, data, trail_id, exec_q) if trail_id is not None and exec_q is not None else None

    first = placements(frames[0])
    exec_first = placements(exec_frames[0]) if exec_frames is not None else None
    robot_pts = _world_points(parts, first)
    cloud = [robot_pts]
    if exec_first is not None:
        cloud.append(_world_points(parts, exec_first))
    for points in (trail, exec_trail):
        if points is not None:
            cloud.append(points)
    for b in obstacles:
        cloud.append(np.stack([b.center - b.half_extents, b.center + b.half_extents]))
    for _, v, _ in shapes:
        cloud.append(v.astype(np.float64))
    for _, pts, _ in point_clouds:
        cloud.append(pts[[int(np.argmin(pts[:, k])) for k in range(3)] + [int(np.argmax(pts[:, k])) for k in range(3)]])
    all_pts = np.concatenate(cloud)
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    center = 0.5 * (lo + hi)
    half_diag = max(0.5 * float(np.linalg.norm(hi - lo)), 0.3)
    grid_size = float(max(2.0, 2.0 * math.ceil(float(np.max(np.abs(np.concatenate([lo[:2], hi[:2]])))) + 0.5)))

    name = title or (f"genplan: {robot.name}, a {float(path_t[-1]):.2f} s trajectory" if path_t is not None
                     else f"genplan: {robot.name}, {len(q)} states")
    with _viser_server() as server:
        viewer_scene = server.scene
        viewer_scene.set_up_direction("+z")
        viewer_scene.world_axes.visible = False
        grid = dict(width=grid_size, height=grid_size, cell_size=0.25, section_size=1.0,
                    plane_color=(235, 235, 235), plane_opacity=0.6)
        for hs_name, normal, offset in planes:
            point, rot = _halfspace_frame(normal, offset)
            viewer_scene.add_grid(f"/environment/{hs_name}", **grid, position=point, wxyz=_wxyz(rot))
        if ground and not planes:  # a reference floor under the robot's lowest point
            viewer_scene.add_grid("/environment/ground", **grid, position=(0.0, 0.0, float(robot_pts[:, 2].min())))
        for b in obstacles:
            viewer_scene.add_box(f"/environment/{b.name}", color=_OBSTACLE_COLOR, dimensions=2.0 * b.half_extents,
                                 position=b.center, flat_shading=True)
        for shape_name, v, f in shapes:
            viewer_scene.add_mesh_simple(f"/environment/{shape_name}", v, f, color=_OBSTACLE_COLOR, flat_shading=True)
        for cloud_name, pts, size in point_clouds:
            drawn, colors = _cloud_arrays(pts)
            viewer_scene.add_point_cloud(f"/environment/{cloud_name}", drawn, colors, point_size=size,
                                         point_shape="rounded", precision="float32")
        for root, points, color in (("/trail", trail, _TRAIL_COLOR), ("/executed_trail", exec_trail, _EXECUTED_COLOR)):
            if points is not None and len(points) > 1:
                seg = np.stack([points[:-1], points[1:]], axis=1).astype(np.float32)
                viewer_scene.add_line_segments(f"{root}/path", seg, color, thickness=3.0, thickness_units="screen")
        if trail is not None:
            viewer_scene.add_icosphere("/trail/start", radius=0.02, color=_START_COLOR, position=trail[0])
            viewer_scene.add_icosphere("/trail/goal", radius=0.02, color=_GOAL_COLOR, position=trail[-1])

        def add_robot(root: str, at: dict[int, pin.SE3], ghost: bool) -> dict[int, Any]:
            handles = {j: viewer_scene.add_frame(f"{root}/{model.names[j]}", show_axes=False,
                                                 wxyz=_wxyz(at[j].rotation), position=at[j].translation)
                       for j in moving}
            for p in parts:
                parent = root if p.joint == 0 else f"{root}/{model.names[p.joint]}"
                viewer_scene.add_mesh_simple(f"{parent}/{p.name}", p.vertices, p.faces,
                                             color=_EXECUTED_COLOR if ghost else p.color,
                                             opacity=_GHOST_OPACITY if ghost else None,
                                             wxyz=_wxyz(p.placement.rotation), position=p.placement.translation)
            return handles

        robots = [(add_robot("/robot", first, False), frames, first)]
        if exec_frames is not None and exec_first is not None:
            robots.append((add_robot("/executed", exec_first, True), exec_frames, exec_first))

        # camera: the whole scene in view, from the front-right and a bit above
        direction = np.array([1.0, -0.8, 0.55])
        server.initial_camera.look_at = center
        server.initial_camera.position = center + 1.6 * half_diag * direction / np.linalg.norm(direction)

        recording = server.get_scene_serializer()
        last = [start for _, _, start in robots]
        for i in range(1, len(frames)):
            recording.insert_sleep(dt)
            for k, (handles, states, _) in enumerate(robots):
                now = placements(states[i])
                for j, M in now.items():
                    if M.isApprox(last[k][j], 1e-9):
                        continue  # unchanged (e.g. a joint the plan does not move): no message
                    handles[j].wxyz = _wxyz(M.rotation)
                    handles[j].position = M.translation
                last[k] = now
        recording.insert_sleep(dt)
        page = recording.as_html(dark_mode=dark_mode)

    page = page.replace("<title>Viser</title>", f"<title>{html.escape(name)}</title>", 1)
    legend = _legend(name, trail_frame if trail is not None else None, bool(obstacles or shapes),
                     executed=exec_q is not None, points=bool(point_clouds))
    i = page.rfind("</body>")
    page = page[:i] + legend + page[i:] if i >= 0 else page + legend
    try:
        write_text(out_path, page)  # under a temporary name, then renamed: never half a page
    except OSError as exc:
        raise OSError(f"out: cannot write {out_path}: {exc.strerror or exc}") from exc
    return out_path


def export_execution_html(
    robot: Robot,
    log: "ExecutionLog",
    out: str | os.PathLike[str],
    *,
    planned: "Trajectory | Mapping[str, Any] | ArrayLike | None" = None,
    **kwargs: Any,
) -> Path:
    """Write the HTML view of a run of :func:`genplan.execute` beside its plan: the planned
    motion as the robot and its red trail, the executed one (``log.q`` over the motion's ticks)
    as a translucent robot with its own trail, both on one clock from the motion's start.

    Args:
        robot: the robot the run was made with.
        log: the run (an :class:`~genplan._execution.ExecutionLog`).
        out: the HTML file to write.
        planned: the plan (a Trajectory, or a mapping with ``t`` and ``q``); default: the run's
            reference (``log.q_ref`` over the motion's ticks: the plan at the control period).
        **kwargs: what :func:`export_html` takes (``scene``, ``fps``, ``max_frames``, ``title``,
            ``trail_frame``, ...); the default title gives the tool frame's largest error.

    Raises:
        SettingsError: ``log`` is not an ExecutionLog; otherwise as :func:`export_html`.
    """
    from genplan._execution import ExecutionLog

    if not isinstance(log, ExecutionLog):
        raise SettingsError(f"log: expected an ExecutionLog (what genplan.execute returns), got {type(log).__name__}")
    _motion(robot, log, "log")  # a run of this robot, with a motion: else an error naming the log
    shown: Any = planned
    if shown is None:
        if log.q_ref is None:
            raise SettingsError("planned: the run has no joint reference (log.q_ref); give the plan as planned=")
        a, b = log.motion_start, log.motion_end
        shown = {"t": log.t[a:b] - log.t[a], "q": log.q_ref[a:b]}
    kwargs.setdefault(
        "title",
        f"genplan execute: {robot.name}, planned (solid) and executed (translucent); the "
        f"{log.meta.get('frame', 'tool frame')}'s largest error {log.max_tracking_error_mm:.2f} mm, "
        f"{log.max_tracking_error_deg:.2f} deg")
    return export_html(robot, shown, out, executed=log, **kwargs)


def export_plan_html(
    env_name: str,
    out: str | os.PathLike[str],
    sampler: str = "hybrid",
    seed: int = 0,
    **kwargs: Any,
) -> Path:
    """Plan one query of a paper environment ("panda_shelf", "talos_task1".."3") with the
    constrained RRT and write its HTML view (keyword arguments go to :func:`export_html`)."""
    import genplan
    from genplan.planning import Planner, environment

    env = environment(env_name)
    robot = genplan.load(env.robot)
    query = env.queries(robot, n=1, seed=seed)[0]
    result = Planner(robot, world=env.world(robot), sampler=sampler, seed=seed).plan(query.start, query.goals)
    if not result.success:
        raise RuntimeError(f"{env_name}: the {sampler} planner found no path for query seed {seed}")
    kwargs.setdefault(
        "title",
        f"genplan: {env_name}, {sampler} sampler, seed {seed} ({len(result.path)} states, {result.time_s:.2f} s)",
    )
    return export_html(robot, result.path, out, boxes=env.boxes, halfspaces=env.halfspaces, **kwargs)


if __name__ == "__main__":  # `python -m genplan.viewer`, deprecated: the command is `genplan view`
    import sys
    import warnings

    from genplan.cli import main

    warnings.warn("python -m genplan.viewer is deprecated (removed in the next release): use "
                  "genplan view ENV --out OUT.html [--sampler S] [--seed N]", DeprecationWarning, stacklevel=1)
    sys.exit(main(["view", *sys.argv[1:2], "--out", *sys.argv[2:]]))  # ENV OUT [options]
