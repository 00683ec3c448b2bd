"""Readers of recorded joint trajectories: what :func:`genplan.seq2seq.data.from_recordings` takes.

* ``.npz``: arrays ``q`` (m, c) and ``t`` (m,) seconds, optionally ``joint_names`` (c,) (else
  the caller's ``joint_names``); a genplan :class:`~genplan.trajectory.Trajectory` saved as
  ``.npz`` is one.
* ``.csv``: a header row ``t`` (or ``time``) then one column per joint, named; one row per sample.
* ROS bags through the ``rosbags`` package (the optional extra ``pip install 'genplan[recordings]'``):
  ROS 1 ``.bag`` files, ROS 2 bag folders (SQLite or MCAP storage) and ``.mcap`` files; the
  ``sensor_msgs/JointState`` messages of a topic (``topic=``; default: the only topic of that
  type), stamped by their header (else the bag's receive time), or the points of a
  ``trajectory_msgs/JointTrajectory`` message (its first, when a topic holds several).

Every reader returns ``(t, q, names)``: times (m,) from the first sample, positions (m, c) and
the c column names. Errors name the file and what is wrong in it.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.errors import GenplanError, MissingExtraError, NonFiniteError, ShapeError, UnknownNameError

__all__ = ["read_recording", "BAG_SUFFIXES"]

#: file suffixes read through rosbags (plus ROS 2 bag folders)
BAG_SUFFIXES = (".bag", ".mcap", ".db3")

Recording = tuple[NDArray[np.float64], NDArray[np.float64], list[str]]


def read_recording(path: Path, *, joint_names: Sequence[str] | None = None, topic: str | None = None) -> Recording:
    """``(t, q, names)`` of the recording at ``path`` (see the module's text)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"recording {path} does not exist")
    if path.is_dir() or path.suffix.lower() in BAG_SUFFIXES:
        t, q, names = _bag(path, topic)
    elif path.suffix.lower() == ".npz":
        t, q, names = _npz(path, joint_names)
    elif path.suffix.lower() == ".csv":
        t, q, names = _csv(path)
    else:
        raise GenplanError(f"{path}: unknown recording format {path.suffix!r} (.npz, .csv, {', '.join(BAG_SUFFIXES)} "
                           "or a ROS 2 bag folder)")
    if q.ndim != 2 or q.shape != (len(t), len(names)):
        raise ShapeError(f"{path}: {len(t)} times, positions of shape {q.shape} and {len(names)} joint names do not "
                         "fit together")
    if len(t) < 2:
        raise ShapeError(f"{path}: at least two samples are needed, got {len(t)}")
    bad = ~np.isfinite(q)
    if bad.any() or not np.all(np.isfinite(t)):
        where = f"sample {int(np.argwhere(bad)[0][0])}, joint {names[int(np.argwhere(bad)[0][1])]}" if bad.any() else "times"
        raise NonFiniteError(f"{path}: NaN or inf in the recording ({where})")
    return t - t[0], q, names


def _npz(path: Path, joint_names: Sequence[str] | None) -> Recording:
    from genplan._files import read_npz

    z = read_npz(path, "recording")
    missing = [k for k in ("q", "t") if k not in z]
    if missing:
        raise GenplanError(f"{path}: no array {missing} (a recording holds q (m, joints) and t (m,))")
    try:
        q = np.asarray(z["q"], dtype=np.float64)
        t = np.asarray(z["t"], dtype=np.float64).reshape(-1)
        names = [str(n) for n in np.atleast_1d(z["joint_names"])] if "joint_names" in z else None
    except (TypeError, ValueError) as exc:
        raise GenplanError(f"{path}: not a readable .npz recording ({exc})") from None
    if names is None:
        if joint_names is None:
            raise GenplanError(f"{path}: the recording names no joints (no joint_names array): give joint_names")
        names = [str(n) for n in joint_names]
    return t, q, names


def _csv(path: Path) -> Recording:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise GenplanError(f"{path}: not a readable CSV file ({exc})") from None
    if len(rows) < 3:
        raise GenplanError(f"{path}: a CSV recording needs a header row and at least two samples")
    header = [h.strip() for h in rows[0]]
    if header[0].lower() not in ("t", "time"):
        raise GenplanError(f"{path}: the header's first column must be t (or time), got {header[0]!r}")
    try:
        data = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=np.float64)
    except ValueError as exc:
        raise GenplanError(f"{path}: a value is not a number ({exc})") from None
    if data.shape[1] != len(header):
        raise ShapeError(f"{path}: rows have {data.shape[1]} values, the header {len(header)}")
    return data[:, 0], data[:, 1:], header[1:]


def _bag(path: Path, topic: str | None) -> Recording:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise MissingExtraError(f"{path}: reading ROS bags and MCAP files needs the rosbags package: "
                                "pip install 'genplan[recordings]'") from None
    kinds = ("sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory")
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            conns = [c for c in reader.connections if c.msgtype in kinds]
            if topic is not None:
                chosen = [c for c in conns if c.topic == topic]
                if not chosen:
                    raise UnknownNameError(f"{path}: no JointState or JointTrajectory topic {topic!r}; its joint "
                                           f"topics: {sorted({c.topic for c in conns})}")
            else:
                topics = sorted({c.topic for c in conns})
                if len(topics) != 1:
                    raise GenplanError(f"{path}: {'no' if not topics else 'several'} JointState/JointTrajectory "
                                       f"topics ({topics}): name one with topic=")
                chosen = [c for c in conns if c.topic == topics[0]]
            return _messages(path, reader, chosen)
    except (GenplanError, MissingExtraError):
        raise
    except Exception as exc:  # rosbags raises its own errors for corrupt or unknown files
        raise GenplanError(f"{path}: not a readable ROS bag or MCAP file ({type(exc).__name__}: {exc})") from None


def _messages(path: Path, reader: Any, conns: list[Any]) -> Recording:
    times: list[float] = []
    rows: list[NDArray[np.float64]] = []
    names: list[str] | None = None
    for conn, stamp, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        if conn.msgtype.endswith("JointTrajectory"):
            names = list(msg.joint_names)
            for pt in msg.points:
                times.append(float(pt.time_from_start.sec) + 1e-9 * float(pt.time_from_start.nanosec))
                rows.append(np.asarray(pt.positions, dtype=np.float64))
            break
        these = list(msg.name)
        if names is None:
            names = these
        elif these != names:
            raise GenplanError(f"{path}: a JointState message names {these}, the first named {names}")
        head = getattr(msg, "header", None)
        t = (float(head.stamp.sec) + 1e-9 * float(head.stamp.nanosec)) if head is not None and (
            head.stamp.sec or head.stamp.nanosec) else 1e-9 * float(stamp)
        times.append(t)
        rows.append(np.asarray(msg.position, dtype=np.float64))
    if names is None or not rows:
        raise GenplanError(f"{path}: the topic {conns[0].topic} holds no joint positions")
    if any(len(r) != len(names) for r in rows):
        raise ShapeError(f"{path}: a message has {min(len(r) for r in rows)} positions for {len(names)} joint names")
    return np.asarray(times), np.stack(rows), names
