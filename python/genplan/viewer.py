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

From the shell: ``python -m genplan.viewer panda_shelf panda_shelf.html [--sampler S --seed N]``.

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
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan._files import write_text
from genplan._arrays import error_class
from genplan.errors import GenplanError, RobotFileError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot

if TYPE_CHECKING:
    from genplan.trajectory import Trajectory

__all__ = ["DEFAULT_FPS", "DEFAULT_MAX_FRAMES", "export_html", "export_plan_html", "subsample_path"]

#: Playback rate of the exported animation (frames per second at speed 1x).
DEFAULT_FPS: float = 15.0
#: The path is subsampled to at most this many frames (the trail keeps every state).
DEFAULT_MAX_FRAMES: int = 150

_HalfSpace = tuple[str, Sequence[float], float]

_OBSTACLE_COLOR = (205, 133, 63)
_TRAIL_COLOR = (230, 40, 40)
_START_COLOR = (40, 170, 60)
_GOAL_COLOR = (40, 90, 230)


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
    if skipped:
        warnings.warn(f"viewer: {robot.name}: shapes not drawn: {', '.join(skipped)}", stacklevel=3)
    if not parts:
        raise RobotFileError(f"robot '{robot.name}' has no {geometry} geometry to draw")
    return tuple(parts)


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

    from genplan.scene import Box, Capsule, Cylinder, HalfSpace, Mesh, Sphere, load_scene

    s = load_scene(scene)
    planes: list[tuple[str, NDArray[np.float64], float]] = []
    meshes: list[tuple[str, NDArray[np.float32], NDArray[np.uint32]]] = []
    for o in s.obstacles:
        if isinstance(o, HalfSpace):
            planes.append((o.name, np.asarray(o.normal, dtype=np.float64), float(o.offset)))
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
            # collision treats a mesh obstacle as its convex hull (docs/SCENES.md): draw that
            m = loaded.convex_hull
            m.apply_scale(np.asarray(o.scale, dtype=np.float64))
        else:  # pragma: no cover - Scene admits only the classes above
            raise GenplanError(f"scene '{s.name}': cannot draw {type(o).__name__} '{o.name}'")
        t = np.eye(4)
        t[:3, :3] = o.pose.matrix()
        t[:3, 3] = o.pose.position
        m.apply_transform(t)
        meshes.append((o.name, np.asarray(m.vertices, dtype=np.float32), np.asarray(m.faces, dtype=np.uint32)))
    return planes, meshes


def _legend(title: str, trail_label: str | None, obstacles: bool) -> str:
    """A small fixed overlay: the title, what the colours mean, how to move the camera."""
    items = []
    if trail_label is not None:
        items += [f'<span style="color:#e62828">&#9644;</span> {html.escape(trail_label)} path',
                  '<span style="color:#28aa3c">&#9679;</span> start',
                  '<span style="color:#285ae6">&#9679;</span> goal']
    if obstacles:
        items.append('<span style="color:#cd853f">&#9632;</span> obstacles')
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


def export_html(
    robot: Robot,
    path: "ArrayLike | Trajectory",
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
) -> Path:
    """Write a self-contained HTML viewer of ``robot`` moving along ``path``; returns ``out``.

    Args:
        robot: the robot the configurations belong to (:func:`genplan.load`).
        path: (m, nq) configurations (one (nq,) configuration is a still view), finite; or a
            :class:`genplan.trajectory.Trajectory` (``result.trajectory()``), played in real time:
            its state at every 1/``fps`` s (fewer frames, evenly timed, when that exceeds
            ``max_frames``).
        out: the HTML file to write (its folder is created).
        boxes: obstacles with ``name``, ``half_extents`` and ``center`` (e.g. ``env.boxes``).
        halfspaces: ``(name, normal, offset)`` planes (e.g. ``env.halfspaces``), drawn as a grid.
        scene: a :class:`genplan.scene.Scene` (or a shipped scene's name, or a scene file): every
            obstacle drawn in place (boxes, spheres, cylinders, capsules, meshes; half-spaces as
            grids), besides ``boxes`` and ``halfspaces``.
        fps: playback rate of the subsampled frames at speed 1x.
        max_frames: at most this many frames are animated (evenly subsampled, first and last
            kept); the trail of ``trail_frame`` uses every state.
        title: the page's title (default: the robot and the path length).
        geometry: "visual" (the URDF's visual meshes) or "collision" (the collision model).
        trail_frame: a frame role or name whose trajectory is drawn (default: the hand, or the
            first "*hand" role: Talos's right hand).
        ground: without ``halfspaces``, draw a reference grid under the robot's lowest point.
        dark_mode: the viewer's dark theme.

    Raises:
        GenplanError: wrong path shape (ShapeError), non-finite values (NonFiniteError), bad fps /
            max_frames (SettingsError) or geometry (UnknownNameError).
        OSError: ``out`` cannot be written.
        ImportError: viser is not installed.
    """
    from genplan.trajectory import Trajectory

    if not (math.isfinite(fps) and fps > 0):
        raise SettingsError(f"fps must be a positive number, got {fps}")
    timed = isinstance(path, Trajectory)
    q = robot.check_configuration(path.q if timed else path, "path")
    if q.ndim == 1:
        q = q[None, :]
    if len(q) == 0:
        raise ShapeError("path: no configuration (shape (0, nq))")
    dt = 1.0 / fps
    if timed:  # played in real time: frames evenly spaced in time, fps of them per second
        duration = float(path.t[-1])
        count = int(min(max(max_frames, 2), max(2, math.floor(duration * fps) + 1)))
        if len(q) > 1 and duration > 0:
            times = np.linspace(0.0, duration, count)
            picks = np.minimum(np.searchsorted(path.t, times), len(q) - 1)
            dt = duration / (count - 1)
        else:
            picks = np.zeros(1, dtype=np.intp)
    obstacles = _check_boxes(boxes)
    planes = _check_halfspaces(halfspaces)
    shapes: list[tuple[str, NDArray[np.float32], NDArray[np.uint32]]] = []
    if scene is not None:
        extra_planes, shapes = _scene_shapes(scene)
        planes += extra_planes
    out_path = _check_out(out)
    frames = q[picks] if timed else q[subsample_path(q, max_frames)]

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

    trail = None
    if trail_id is not None:
        pts = []
        for qi in q:
            pin.framesForwardKinematics(model, data, qi)
            pts.append(np.array(data.oMf[trail_id].translation))
        trail = np.asarray(pts)

    first = placements(frames[0])
    robot_pts = _world_points(parts, first)
    cloud = [robot_pts]
    if trail is not None:
        cloud.append(trail)
    for b in obstacles:
        cloud.append(np.stack([b.center - b.half_extents, b.center + b.half_extents]))
    for _, v, _ in shapes:
        cloud.append(v.astype(np.float64))
    all_pts = np.concatenate(cloud)
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    center = 0.5 * (lo + hi)
    half_diag = max(0.5 * float(np.linalg.norm(hi - lo)), 0.3)
    grid_size = float(max(2.0, 2.0 * math.ceil(float(np.max(np.abs(np.concatenate([lo[:2], hi[:2]])))) + 0.5)))

    name = title or (f"genplan: {robot.name}, a {float(path.t[-1]):.2f} s trajectory" if timed
                     else f"genplan: {robot.name}, {len(q)} states")
    with _viser_server() as server:
        scene = server.scene
        scene.set_up_direction("+z")
        scene.world_axes.visible = False
        grid = dict(width=grid_size, height=grid_size, cell_size=0.25, section_size=1.0,
                    plane_color=(235, 235, 235), plane_opacity=0.6)
        for hs_name, normal, offset in planes:
            point, rot = _halfspace_frame(normal, offset)
            scene.add_grid(f"/environment/{hs_name}", **grid, position=point, wxyz=_wxyz(rot))
        if ground and not planes:  # a reference floor under the robot's lowest point
            scene.add_grid("/environment/ground", **grid, position=(0.0, 0.0, float(robot_pts[:, 2].min())))
        for b in obstacles:
            scene.add_box(f"/environment/{b.name}", color=_OBSTACLE_COLOR, dimensions=2.0 * b.half_extents,
                          position=b.center, flat_shading=True)
        for shape_name, v, f in shapes:
            scene.add_mesh_simple(f"/environment/{shape_name}", v, f, color=_OBSTACLE_COLOR, flat_shading=True)
        if trail is not None and len(trail) > 1:
            seg = np.stack([trail[:-1], trail[1:]], axis=1).astype(np.float32)
            scene.add_line_segments("/trail/path", seg, _TRAIL_COLOR, thickness=3.0,
                                    thickness_units="screen")
        if trail is not None:
            scene.add_icosphere("/trail/start", radius=0.02, color=_START_COLOR, position=trail[0])
            scene.add_icosphere("/trail/goal", radius=0.02, color=_GOAL_COLOR, position=trail[-1])

        joints: dict[int, Any] = {}
        for j in moving:
            M = first[j]
            joints[j] = scene.add_frame(f"/robot/{model.names[j]}", show_axes=False,
                                        wxyz=_wxyz(M.rotation), position=M.translation)
        for p in parts:
            parent = "/robot" if p.joint == 0 else f"/robot/{model.names[p.joint]}"
            scene.add_mesh_simple(f"{parent}/{p.name}", p.vertices, p.faces, color=p.color,
                                  wxyz=_wxyz(p.placement.rotation), position=p.placement.translation)

        # camera: the whole scene in view, from the front-right and a bit above
        direction = np.array([1.0, -0.8, 0.55])
        server.initial_camera.look_at = center
        server.initial_camera.position = center + 1.6 * half_diag * direction / np.linalg.norm(direction)

        recording = server.get_scene_serializer()
        last = first
        for qi in frames[1:]:
            recording.insert_sleep(dt)
            now = placements(qi)
            for j, M in now.items():
                if M.isApprox(last[j], 1e-9):
                    continue  # unchanged (e.g. a joint the plan does not move): no message
                h = joints[j]
                h.wxyz = _wxyz(M.rotation)
                h.position = M.translation
            last = now
        recording.insert_sleep(dt)
        page = recording.as_html(dark_mode=dark_mode)

    page = page.replace("<title>Viser</title>", f"<title>{html.escape(name)}</title>", 1)
    legend = _legend(name, trail_frame if trail is not None else None, bool(obstacles or shapes))
    i = page.rfind("</body>")
    page = page[:i] + legend + page[i:] if i >= 0 else page + legend
    try:
        write_text(out_path, page)  # under a temporary name, then renamed: never half a page
    except OSError as exc:
        raise OSError(f"out: cannot write {out_path}: {exc.strerror or exc}") from exc
    return out_path


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


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m genplan.viewer ENV OUT.html [--sampler S] [--seed N]``: plan and export."""
    import argparse

    from genplan.planning import ENVIRONMENT_NAMES, SAMPLERS

    parser = argparse.ArgumentParser(prog="python -m genplan.viewer", description=main.__doc__)
    parser.add_argument("env", choices=ENVIRONMENT_NAMES)
    parser.add_argument("out", type=Path)
    parser.add_argument("--sampler", choices=SAMPLERS, default="hybrid")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fps", type=float, default=DEFAULT_FPS)
    parser.add_argument("--max-frames", type=int, default=DEFAULT_MAX_FRAMES)
    args = parser.parse_args(argv)
    out = export_plan_html(args.env, args.out, sampler=args.sampler, seed=args.seed, fps=args.fps,
                           max_frames=args.max_frames)
    print(f"{out} ({out.stat().st_size / 1e6:.1f} MB): open it in a browser (works offline)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
