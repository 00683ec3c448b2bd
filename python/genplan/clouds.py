"""Point clouds for the collision world: reading them (``.npz``, ``.ply``, ``.pcd``), making them
from a depth image (:func:`points_from_depth`, the camera fixed in the world or on a robot link:
:func:`camera_pose`), and the checks every cloud goes through (:func:`check_points`).

A cloud is an ``(n, 3)`` float64 array of points in the world frame (m). The world makes each
point a ball (:meth:`genplan.collision.CollisionWorld.add_points`; docs/SCENES.md "Point clouds
and depth images").
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_float_array, as_real
from genplan.errors import GenplanError, NonFiniteError, SceneFileError, SettingsError, ShapeError

__all__ = ["POINT_EXTENSIONS", "camera_pose", "check_points", "points_from_depth", "read_points"]

#: The point-cloud files :func:`read_points` takes.
POINT_EXTENSIONS = ("npz", "ply", "pcd")

#: The largest absolute coordinate of a point (m): the native world's obstacle limit
#: (``MAX_OBSTACLE_EXTENT`` in rust/core/src/collision/world.rs).
_MAX_COORDINATE = 1e6


def check_points(points: Any, what: str = "points") -> NDArray[np.float64]:
    """``points`` as a C-contiguous float64 array of shape (n, 3), n >= 1, every coordinate finite
    and within 1e6 m of the origin. ShapeError (not numbers, another shape, an empty cloud) or
    NonFiniteError (naming the first bad row) naming ``what``."""
    arr = as_float_array(points, what)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ShapeError(f"{what}: expected an array of shape (n, 3), got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ShapeError(f"{what}: the cloud is empty (a cloud needs at least one point)")
    # two reductions without a temporary (NaN propagates through min and max); the rows are
    # searched only when one fails (a frame is checked at the sensor's rate)
    if not (-_MAX_COORDINATE <= arr.min() and arr.max() <= _MAX_COORDINATE):
        finite = np.isfinite(arr)
        if not finite.all():
            row, col = (int(i) for i in np.argwhere(~finite)[0])
            raise NonFiniteError(f"{what}: row {row} (column {col}) is not finite ({arr[row, col]})")
        row = int(np.argwhere(np.abs(arr) > _MAX_COORDINATE)[0][0])
        raise ShapeError(f"{what}: row {row} {arr[row].tolist()} lies beyond {_MAX_COORDINATE:g} m of the origin")
    return np.ascontiguousarray(arr)


def read_points(path: str | os.PathLike[str], what: str = "points file") -> NDArray[np.float64]:
    """The points of a file, (n, 3) float64: ``.npz`` (an array named ``points`` of shape (n, 3)),
    ``.ply`` (the ``x``, ``y``, ``z`` properties of its ``vertex`` element; ASCII, binary little-
    or big-endian) or ``.pcd`` (its ``x``, ``y``, ``z`` fields; ASCII or binary, not
    binary_compressed). FileNotFoundError when it does not exist; SceneFileError naming ``what``
    and the file when it cannot be read; the points checked as :func:`check_points` does (NaN
    points, as organised clouds store missing returns, are dropped first)."""
    p = Path(path)
    ext = p.suffix.lower().lstrip(".")
    if ext not in POINT_EXTENSIONS:
        raise SceneFileError(f"{what} {p}: not a point-cloud file ({', '.join('.' + e for e in POINT_EXTENSIONS)})")
    if not p.is_file():
        raise FileNotFoundError(f"{what} {p} does not exist")
    try:
        if ext == "npz":
            from genplan._files import read_npz

            arrays = read_npz(p, what)
            if "points" not in arrays:
                raise SceneFileError(f"no array named 'points' (arrays: {', '.join(sorted(arrays)) or 'none'})")
            pts = as_float_array(arrays["points"], "points", error=SceneFileError)
        else:
            pts = _read_ply(p) if ext == "ply" else _read_pcd(p)
    except (GenplanError, OSError, ValueError, UnicodeDecodeError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise SceneFileError(f"{what} {p}: {exc}") from None
    if pts.ndim == 2 and pts.shape[1] == 3:
        pts = pts[~np.isnan(pts).any(axis=1)]
    try:
        return check_points(pts, "points")
    except GenplanError as exc:
        raise SceneFileError(f"{what} {p}: {exc}") from None


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _header(raw: bytes, end: bytes, what: str) -> tuple[list[str], int]:
    """The header lines of a PLY or PCD file (up to and including the line starting with
    ``end``) and the offset of the data after it."""
    lines: list[str] = []
    pos = 0
    while True:
        nl = raw.find(b"\n", pos)
        if nl < 0:
            raise ValueError(f"{what}: the header does not end (no '{end.decode()}' line)")
        line = raw[pos:nl].decode("ascii").strip()
        pos = nl + 1
        lines.append(line)
        if line.startswith(end.decode()):
            return lines, pos
        if len(lines) > 10_000:
            raise ValueError(f"{what}: the header does not end")


def _read_ply(path: Path) -> NDArray[np.float64]:
    raw = path.read_bytes()
    if not raw.startswith(b"ply"):
        raise ValueError("not a PLY file (no 'ply' magic)")
    lines, start = _header(raw, b"end_header", "PLY")
    fmt = ""
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info", "end_header"):
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if not elements:
                raise ValueError("a property before any element")
            if words[1] == "list":
                elements[-1][2].append((words[-1], "list " + " ".join(words[2:4])))
            else:
                if words[1] not in _PLY_TYPES:
                    raise ValueError(f"unknown property type '{words[1]}'")
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unknown PLY format '{fmt}'")
    names = [e[0] for e in elements]
    if "vertex" not in names:
        raise ValueError("no 'vertex' element")
    k = names.index("vertex")
    if any(t.startswith("list") for e in elements[:k + 1] for _, t in e[2]):
        raise ValueError("list properties before or in the vertex element are not read (a mesh's faces come after)")
    name, count, props = elements[k]
    fields = [n for n, _ in props]
    for axis in "xyz":
        if axis not in fields:
            raise ValueError(f"the vertex element has no '{axis}' property (properties: {', '.join(fields)})")
    if fmt == "ascii":
        body = raw[start:].decode("ascii").split("\n")
        skip = sum(e[1] for e in elements[:k])
        rows = [ln for ln in body[skip:skip + count]]
        if len(rows) < count:
            raise ValueError(f"{count} vertices declared, {len(rows)} lines found")
        table = np.array([r.split()[:len(props)] for r in rows], dtype=np.float64) if count else np.zeros((0, len(props)))
        if table.shape != (count, len(props)):
            raise ValueError("a vertex line has fewer values than properties")
        cols = [fields.index(a) for a in "xyz"]
        return table[:, cols]
    order = "<" if fmt == "binary_little_endian" else ">"
    offset = start
    for e in elements[:k]:
        offset += e[1] * np.dtype([(n, order + t) for n, t in e[2]]).itemsize
    dt = np.dtype([(n, order + t) for n, t in props])
    if len(raw) - offset < count * dt.itemsize:
        raise ValueError(f"{count} vertices declared, the file ends after {(len(raw) - offset) // dt.itemsize}")
    v = np.frombuffer(raw, dtype=dt, count=count, offset=offset)
    return np.stack([v[a].astype(np.float64) for a in "xyz"], axis=1)


_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4", ("I", 8): "i8",
              ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}


def _read_pcd(path: Path) -> NDArray[np.float64]:
    raw = path.read_bytes()
    lines, start = _header(raw, b"DATA", "PCD")
    h: dict[str, list[str]] = {}
    for line in lines:
        words = line.split()
        if words and not words[0].startswith("#"):
            h[words[0].upper()] = words[1:]
    for key in ("FIELDS", "SIZE", "TYPE", "POINTS", "DATA"):
        if key not in h:
            raise ValueError(f"no {key} line in the header")
    fields, sizes, types = h["FIELDS"], [int(s) for s in h["SIZE"]], h["TYPE"]
    counts = [int(c) for c in h.get("COUNT", ["1"] * len(fields))]
    if not (len(fields) == len(sizes) == len(types) == len(counts)):
        raise ValueError("FIELDS, SIZE, TYPE and COUNT differ in length")
    for axis in "xyz":
        if axis not in fields:
            raise ValueError(f"no '{axis}' field (fields: {', '.join(fields)})")
    n = int(h["POINTS"][0])
    data = h["DATA"][0].lower()
    if data == "ascii":
        body = raw[start:].decode("ascii").split()
        width = sum(counts)
        if len(body) < n * width:
            raise ValueError(f"{n} points declared, {len(body) // max(width, 1)} found")
        table = np.array(body[:n * width], dtype=np.float64).reshape(n, width)
        col = np.cumsum([0, *counts])
        return table[:, [int(col[fields.index(a)]) for a in "xyz"]]
    if data != "binary":
        raise ValueError(f"DATA {data} is not read (ascii or binary; save binary_compressed clouds as binary)")
    try:
        dt = np.dtype([(f, "<" + _PCD_TYPES[(t.upper(), s)], (c,) if c > 1 else ())
                       for f, s, t, c in zip(fields, sizes, types, counts)])
    except KeyError as exc:
        raise ValueError(f"unknown field type {exc}") from None
    if len(raw) - start < n * dt.itemsize:
        raise ValueError(f"{n} points declared, the file ends after {(len(raw) - start) // dt.itemsize}")
    v = np.frombuffer(raw, dtype=dt, count=n, offset=start)
    return np.stack([v[a].astype(np.float64) for a in "xyz"], axis=1)


def _pose4(pose: Any, what: str) -> NDArray[np.float64]:
    """A 4x4 rigid transform (finite, its rotation proper within 1e-6)."""
    m = as_float_array(pose, what)
    if m.shape != (4, 4):
        raise ShapeError(f"{what}: expected a 4x4 matrix (world from camera), got shape {m.shape}")
    if not np.isfinite(m).all():
        raise NonFiniteError(f"{what}: not finite")
    r = m[:3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or abs(np.linalg.det(r) - 1.0) > 1e-6 or np.abs(m[3] - [0, 0, 0, 1]).max() > 0:
        raise SettingsError(f"{what}: not a rigid transform (its rotation is not proper, or its last row is not 0 0 0 1)")
    return m


def points_from_depth(depth: ArrayLike, intrinsics: ArrayLike, camera_pose: ArrayLike,
                      max_range: float = math.inf, *, depth_scale: float = 1.0) -> NDArray[np.float64]:
    """World points (n, 3) of a depth image.

    ``depth``: (h, w) distances along the optical axis (z), in m times ``depth_scale`` (a 16-bit
    image in mm: ``depth_scale=0.001``), of a real or integer dtype. ``intrinsics``: (fx, fy,
    cx, cy) in pixels (pixel (u, v) = column, row, their centres at integer coordinates).
    ``camera_pose``: 4x4, world from camera, in the optical frame (z forward, x right, y down),
    e.g. :func:`camera_pose` of a camera on a robot link. Pixels that are zero, NaN, infinite or
    farther than ``max_range`` (m, along z) are dropped. Every argument is checked before any
    work: ShapeError (shape, dtype), SettingsError (intrinsics, range, scale), NonFiniteError.
    """
    d = np.asarray(depth)
    if d.ndim != 2 or min(d.shape) == 0:
        raise ShapeError(f"depth: expected an image of shape (h, w), got shape {d.shape}")
    if d.dtype.kind not in "fiu":
        raise ShapeError(f"depth: expected real or integer values, got dtype {d.dtype}")
    k = as_float_array(intrinsics, "intrinsics").reshape(-1)
    if k.shape != (4,):
        raise ShapeError(f"intrinsics: expected (fx, fy, cx, cy), got {np.shape(intrinsics)}")
    if not np.isfinite(k).all() or k[0] <= 0 or k[1] <= 0:
        raise SettingsError(f"intrinsics: fx and fy must be positive and all four finite, got {k.tolist()}")
    pose = _pose4(camera_pose, "camera_pose")
    far = as_real(max_range, "max_range")
    if not far > 0:
        raise SettingsError(f"max_range must be positive (m; inf for none), got {max_range!r}")
    scale = as_real(depth_scale, "depth_scale")
    if not (math.isfinite(scale) and scale > 0):
        raise SettingsError(f"depth_scale must be positive and finite, got {depth_scale!r}")
    z = d.astype(np.float64) * scale
    keep = np.isfinite(z) & (z > 0) & (z <= far)
    v, u = np.nonzero(keep)
    zs = z[v, u]
    cam = np.stack([(u - k[2]) * zs / k[0], (v - k[3]) * zs / k[1], zs], axis=1)
    return np.ascontiguousarray(cam @ pose[:3, :3].T + pose[:3, 3])


def camera_pose(robot: Any, q: ArrayLike, link: str, link_from_camera: ArrayLike | None = None) -> NDArray[np.float64]:
    """The world pose (4x4, world from camera) of a camera mounted on ``link`` of ``robot`` at
    configuration ``q``: the link's pose from the Rust kinematics times ``link_from_camera`` (the
    camera's optical frame in the link's frame, from the hand-eye calibration; default the
    identity). For :func:`points_from_depth`'s ``camera_pose``."""
    mount = np.eye(4) if link_from_camera is None else _pose4(link_from_camera, "link_from_camera")
    qa = robot.check_configuration(q)
    if qa.ndim != 1:
        raise ShapeError(f"q: expected one configuration of shape ({robot.nq},), got {qa.shape}")
    return np.asarray(robot.link_poses(qa, [link])[0]) @ mount
