"""Trajectory data sets: a family of motions of one robot, the data a seq2seq model learns.

A :class:`TrajectorySet` holds ``n`` trajectories, each ``K`` samples in normalised time
(``s = k / (K - 1)``) of a stated space plus its own duration (a time-optimal path has its own
length): ``positions`` (n, K, d), ``durations`` (n,) seconds. The space is a robot's joint
positions (``space = "joint"``, the axes its joint names) or a task/plant space (``"task"``, such
as the spatula's ``y, z, theta``). It records the robot (:func:`genplan.samplers.data.robot_record`),
optionally the task and the scene, and where the trajectories came from.

Sources:

* :func:`plan_trajectories`: genplan's own planner (``genplan data trajectories``): random start
  and goal configurations on the task's manifold (uniform, or with a frame's position in a box:
  IK), collision-free, planned (RRT-Connect), shortcut and time-parameterised (TOPP-RA), then
  resampled to K samples; failures are counted, not kept. Seeded per shard
  (:func:`genplan.executor.shard_rng`), so the worker count never changes the data.
* :func:`from_recordings`: the user's recordings (``.npz`` with ``q`` and ``t``; CSV with a
  header ``t, <joint>, ...``; ROS bags and MCAP files through the optional ``genplan[recordings]``
  extra: :mod:`genplan.seq2seq.recordings`), resampled onto the same grid, joint names matched to
  the robot's.

On disk a data set is a folder of shards (``shard_00000.npz``, ...: positions and durations) and
a ``manifest.json`` (format ``genplan-trajectories/1``: the space, axes, K, robot, task, scene and
source; each shard's count and the sha256 of its arrays; the set's sha256), written and read as
configuration data sets are (:mod:`genplan._shards`: one run per folder under its lock, resumed
from the verified shards, another data set refused unless overwritten):
:func:`write_planned_trajectories` (the planner's set, computed shard by shard into the folder),
:func:`write_trajectories` (a set in memory), :func:`read_trajectories`.
"""

from __future__ import annotations

import hashlib
import math
import os
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError

__all__ = ["TrajectorySet", "resample", "plan_trajectories", "write_planned_trajectories", "from_recordings",
           "write_trajectories", "read_trajectories", "set_sha256", "SPACES", "FORMAT"]

#: the spaces a data set may be stated in
SPACES = ("joint", "task")


@dataclass
class TrajectorySet:
    """``n`` trajectories of ``K`` samples in normalised time plus their durations (see the
    module's text). ``robot``: the robot's record (name, sha256 of its files and description) for
    a joint-space set; ``task``: the task's dict form (its constraint) or None; ``scene``: the
    scene's name or dict form, or None; ``source``: how the set was made."""

    positions: NDArray[np.float64]
    durations: NDArray[np.float64]
    axes: tuple[str, ...]
    space: str = "joint"
    robot: dict[str, Any] | None = None
    task: dict[str, Any] | None = None
    scene: Any = None
    source: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.positions = np.asarray(self.positions, dtype=np.float64)
        self.durations = np.asarray(self.durations, dtype=np.float64).reshape(-1)
        self.axes = tuple(str(a) for a in self.axes)
        if self.space not in SPACES:
            raise SettingsError(f"space must be one of {SPACES}, got {self.space!r}")
        p = self.positions
        if p.ndim != 3 or p.shape[2] != len(self.axes) or p.shape[1] < 2:
            raise ShapeError(f"positions must have shape (n, K >= 2, {len(self.axes)}) (one column per axis "
                             f"{list(self.axes)}), got {p.shape}")
        if self.durations.shape != (p.shape[0],):
            raise ShapeError(f"durations must have one value per trajectory ({p.shape[0]}), got shape "
                             f"{self.durations.shape}")
        for name, a in (("positions", p), ("durations", self.durations)):
            if not np.all(np.isfinite(a)):
                idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
                raise NonFiniteError(f"trajectory data: {name} holds NaN or inf (first at index {idx})")
        if np.any(self.durations < 0):
            raise SettingsError(f"trajectory data: durations must be >= 0 (first negative: trajectory "
                                f"{int(np.argmax(self.durations < 0))})")

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def K(self) -> int:
        return int(self.positions.shape[1])

    @property
    def dim(self) -> int:
        return len(self.axes)

    @property
    def sha256(self) -> str:
        """A hash of the positions and durations (float64 bytes) and the axes."""
        return set_sha256(self.axes, [self.positions], [self.durations])

    def split(self, held_out: float, seed: int = 0) -> tuple["TrajectorySet", "TrajectorySet"]:
        """(training, held-out) sets, the held-out share ``held_out`` of the trajectories drawn
        with ``seed`` (at least one trajectory in each)."""
        n = len(self)
        if n < 2:
            raise SettingsError(f"a data set of {n} trajectory cannot be split into training and held-out parts")
        m = min(n - 1, max(1, int(round(held_out * n))))
        idx = np.random.default_rng(seed).permutation(n)
        return self.subset(np.sort(idx[m:])), self.subset(np.sort(idx[:m]))

    def subset(self, index: ArrayLike) -> "TrajectorySet":
        i = np.asarray(index)
        return TrajectorySet(self.positions[i], self.durations[i], self.axes, self.space, self.robot, self.task,
                             self.scene, dict(self.source))

    def ranges(self) -> dict[str, Any]:
        """Per axis, the range of the start and end samples and of all samples (the card's
        record of where the family lives)."""
        p = self.positions
        return {"start_low": p[:, 0].min(0).tolist(), "start_high": p[:, 0].max(0).tolist(),
                "end_low": p[:, -1].min(0).tolist(), "end_high": p[:, -1].max(0).tolist(),
                "low": p.min((0, 1)).tolist(), "high": p.max((0, 1)).tolist(),
                "duration_low": float(self.durations.min()), "duration_high": float(self.durations.max())}

    def check_robot(self, robot: Any, where: str = "data set") -> None:
        """GenplanError unless this joint-space set was made for ``robot`` (its joint names, and
        its record's hash when the set has one)."""
        if self.space != "joint":
            raise SettingsError(f"{where}: a {self.space}-space data set has no robot to check")
        if list(self.axes) != list(robot.joint_names):
            raise GenplanError(f"{where} holds trajectories of the joints {list(self.axes)}, robot '{robot.name}' has "
                               f"{list(robot.joint_names)}")
        if self.robot is not None:
            from genplan.samplers.data import robot_record

            mine = robot_record(robot)
            if self.robot.get("sha256") != mine["sha256"]:
                raise GenplanError(f"{where} was made for robot '{self.robot.get('name')}' (sha256 "
                                   f"{str(self.robot.get('sha256'))[:12]}), not '{robot.name}' (sha256 "
                                   f"{mine['sha256'][:12]}): its files or description differ")


def resample(t: ArrayLike, q: ArrayLike, k: int, what: str = "trajectory") -> NDArray[np.float64]:
    """``q`` (m, d) sampled at the increasing times ``t`` (m,), linearly interpolated at ``k``
    equally spaced times from ``t[0]`` to ``t[-1]``: (k, d)."""
    tt = np.asarray(t, dtype=np.float64).reshape(-1)
    qq = np.asarray(q, dtype=np.float64)
    if qq.ndim != 2 or len(qq) != len(tt):
        raise ShapeError(f"{what}: q must have one row per time ({len(tt)}), got shape {qq.shape}")
    if len(tt) < 2:
        raise ShapeError(f"{what}: at least two samples are needed, got {len(tt)}")
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(qq))):
        raise NonFiniteError(f"{what}: its times or positions hold NaN or inf")
    if np.any(np.diff(tt) <= 0):
        i = int(np.argmax(np.diff(tt) <= 0))
        raise SettingsError(f"{what}: times must increase (sample {i + 1} at {tt[i + 1]} s after {tt[i]} s)")
    grid = np.linspace(tt[0], tt[-1], k)
    return np.stack([np.interp(grid, tt, qq[:, j]) for j in range(qq.shape[1])], axis=1)


# ----------------------------------------------------------------------------- from the planner


@dataclass(frozen=True)
class PlanShard:
    """One shard of :func:`plan_trajectories`: ``count`` trajectories drawn with
    ``shard_rng(seed, index)``."""

    index: int
    count: int
    seed: int
    robot: Any
    task: Any
    scene: Any
    steps: int
    start_box: tuple[tuple[float, ...], tuple[float, ...]] | None
    goal_box: tuple[tuple[float, ...], tuple[float, ...]] | None
    frame: str | None
    max_attempts: int
    settings: dict[str, Any]
    spread: float | None = None


def _endpoints(shard: PlanShard, robot: Any, manifold: Any, world: Any, rng: np.random.Generator,
               box: tuple[tuple[float, ...], tuple[float, ...]] | None, n: int) -> NDArray[np.float64]:
    """Up to ``n`` collision-free configurations on the manifold (with the frame in ``box`` when
    given), drawn with ``rng``."""
    from genplan.projection import FramePosition, GaussNewtonProjector, Task

    if shard.spread is None:
        q0 = robot.random_configurations(n, rng=rng)
    else:
        lo, hi = np.asarray(robot.lower), np.asarray(robot.upper)
        q0 = np.clip(robot.q_default + shard.spread * rng.standard_normal((n, robot.nq)), lo, hi)
    if box is None:
        res = GaussNewtonProjector(robot, manifold).solve_batch(q0, q0)
    else:
        lo, hi = np.asarray(box[0]), np.asarray(box[1])
        targets = lo + rng.random((n, 3)) * (hi - lo)
        term = FramePosition(name="endpoint", frame=shard.frame or "tool", target=targets[0], weight=50.0,
                             tolerance=1e-4)
        task = Task(primary=(*manifold.primary, term), secondary=manifold.secondary, name="endpoints")
        res = GaussNewtonProjector(robot, task).solve_batch(q0, q0, targets={"endpoint": targets})
    ok = res.success & ~np.asarray(world.in_collision(res.q), dtype=bool)
    return res.q[ok]


def plan_shard(shard: PlanShard) -> dict[str, Any]:
    """The trajectories of one shard: positions (count, K, nq), durations, and the failures."""
    from genplan.executor import shard_rng
    from genplan.planning import Planner, PlannerSettings

    robot, manifold, world = _setup(shard)
    rng = shard_rng(shard.seed, shard.index)
    planner = Planner(robot, world, manifold, sampler="uniform", seed=int(rng.integers(2**31)),
                      settings=PlannerSettings(**shard.settings))
    positions: list[NDArray[np.float64]] = []
    durations: list[float] = []
    failures = {"endpoints": 0, "plan": 0, "timing": 0}
    attempts = 0
    starts = np.zeros((0, robot.nq))
    goals = np.zeros((0, robot.nq))
    while len(positions) < shard.count and attempts < shard.max_attempts:
        if len(starts) == 0:
            starts = _endpoints(shard, robot, manifold, world, rng, shard.start_box, 16)
            failures["endpoints"] += 16 - len(starts)
        if len(goals) == 0:
            goals = _endpoints(shard, robot, manifold, world, rng, shard.goal_box, 16)
            failures["endpoints"] += 16 - len(goals)
        if len(starts) == 0 or len(goals) == 0:
            attempts += 1
            continue
        start, goal = starts[0], goals[0]
        starts, goals = starts[1:], goals[1:]
        attempts += 1
        res = planner.plan(start, goal[None])
        if not res.success:
            failures["plan"] += 1
            continue
        try:
            traj = res.trajectory()
        except GenplanError:
            failures["timing"] += 1
            continue
        positions.append(resample(traj.t, traj.q, shard.steps))
        durations.append(traj.duration)
    if len(positions) < shard.count:
        raise GenplanError(f"shard {shard.index}: {len(positions)} of {shard.count} trajectories after "
                           f"{attempts} attempts (failures: {failures}); widen the boxes or raise --max-attempts")
    return {"positions": np.asarray(positions), "durations": np.asarray(durations), "failures": failures,
            "attempts": attempts}


def _setup(shard: PlanShard) -> tuple[Any, Any, Any]:
    from genplan.projection import load_task, manifold_task
    from genplan.robots import load

    robot = load(shard.robot)
    task = load_task(shard.task, robot)
    manifold = manifold_task(task, robot) if task.condition is not None else task
    world = robot.collision_world()
    if shard.scene is not None:
        world.add_scene(shard.scene)
    return robot, manifold, world


def _planned(robot: Any, task: Any, scene: Any, *, count: int, steps: int, seed: int, start_box: ArrayLike | None,
             goal_box: ArrayLike | None, frame: str | None, spread: float | None, shard_size: int,
             max_attempts_factor: int, settings: Mapping[str, Any] | None) -> tuple[list[PlanShard], Any, Any, Any, dict[str, Any]]:
    """The shards of :func:`plan_trajectories` (every argument checked), the robot, task and scene
    loaded, and the source record (the run's parameters)."""
    from genplan.executor import chunks
    from genplan.projection import GaussNewtonProjector, load_task, manifold_task
    from genplan.robots import Robot, load
    from genplan.scene import load_scene

    robot_obj = robot if isinstance(robot, Robot) else load(robot)
    task_obj = load_task(task, robot_obj)
    try:  # the task's frames exist on the robot: what every shard's projector needs, checked here once
        GaussNewtonProjector(robot_obj, manifold_task(task_obj, robot_obj) if task_obj.condition is not None else task_obj)
    except UnknownNameError as exc:
        raise UnknownNameError(f"task '{task_obj.name}': {exc}") from None
    scene_obj = load_scene(scene) if scene is not None else None
    for name, v in (("count", count), ("steps", steps), ("shard_size", shard_size),
                    ("max_attempts_factor", max_attempts_factor)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < (2 if name == "steps" else 1):
            raise SettingsError(f"{name} must be an integer >= {2 if name == 'steps' else 1}, got {v!r}")
    if steps > 100_000 or count > 10_000_000:
        raise SettingsError(f"steps ({steps}) or count ({count}) is beyond what a data set holds (100,000 steps, "
                            "10,000,000 trajectories)")
    boxes = [_box(b, what) for b, what in ((start_box, "start_box"), (goal_box, "goal_box"))]
    if spread is not None and not (isinstance(spread, (int, float)) and math.isfinite(spread) and spread >= 0):
        raise SettingsError(f"spread must be None or a finite number of radians >= 0, got {spread!r}")
    if frame is None and (start_box is not None or goal_box is not None):
        frame = _condition_frame(task_obj) or ("tool" if "tool" in robot_obj.frames else next(iter(robot_obj.frames), None))
        if frame is None:
            raise SettingsError(f"start_box/goal_box: robot '{robot_obj.name}' has no frame roles; name the frame whose "
                                "position the boxes bound (frame=)")
    if frame is not None:
        try:
            robot_obj.frame_id(frame)
        except UnknownNameError as exc:
            raise UnknownNameError(f"frame {frame!r}: {exc}") from None
    base: dict[str, Any] = {"algorithm": "rrt_connect", "simplify": True, "max_extensions": 2000}
    base.update(dict(settings or {}))
    from genplan.planning import PlannerSettings

    PlannerSettings(**base)  # checked here, before any work
    source = robot if not isinstance(robot, Robot) else (robot.source or robot.name)
    task_ref = task if isinstance(task, (str, Path)) else task_obj
    shards = [PlanShard(i, c, seed, str(source), task_ref if not isinstance(task_ref, Path) else str(task_ref),
                        scene_obj, steps, boxes[0], boxes[1], frame, max_attempts_factor * c, base,
                        None if spread is None else float(spread))
              for i, c in enumerate(chunks(count, shard_size))]
    record = {"kind": "planner", "seed": seed, "count": count, "steps": steps, "shard_size": shard_size,
              "start_box": boxes[0], "goal_box": boxes[1], "frame": frame, "spread": spread, "settings": base,
              "max_attempts_factor": max_attempts_factor}
    return shards, robot_obj, task_obj, scene_obj, record


def plan_trajectories(robot: Any, task: Any, scene: Any = None, *, count: int, steps: int = 64, seed: int = 0,
                      start_box: ArrayLike | None = None, goal_box: ArrayLike | None = None, frame: str | None = None,
                      spread: float | None = None, shard_size: int = 50, executor: Any = None, progress: bool = True,
                      max_attempts_factor: int = 20, settings: Mapping[str, Any] | None = None) -> TrajectorySet:
    """``count`` planned trajectories of ``robot`` on ``task``'s manifold among ``scene`` (see
    the module's text), ``steps`` samples each, as a :class:`TrajectorySet`.

    ``start_box``, ``goal_box``: [[x0, y0, z0], [x1, y1, z1]] boxes for ``frame``'s position
    (default: the task's condition frame, else the robot's ``tool`` role) at the start and goal;
    None: uniform on the manifold. ``spread``: the start and goal configurations are solved from
    seeds drawn around the robot's default configuration (normal, this standard deviation in rad,
    clipped to the limits), their posture pulled towards the seed, so the family keeps one arm
    posture (one IK branch); None: seeds uniform in the joint limits. ``settings``: :class:`~genplan.planning.PlannerSettings`
    fields (default RRT-Connect with shortcutting). Arguments are checked before any work."""
    from genplan.executor import LocalExecutor
    from genplan.samplers.data import robot_record

    shards, robot_obj, task_obj, scene_obj, record = _planned(
        robot, task, scene, count=count, steps=steps, seed=seed, start_box=start_box, goal_box=goal_box, frame=frame,
        spread=spread, shard_size=shard_size, max_attempts_factor=max_attempts_factor, settings=settings)
    ex = executor or LocalExecutor()
    try:
        parts = ex.map(plan_shard, shards, desc=f"{robot_obj.name} trajectories", progress=progress,
                       weights=[s.count for s in shards], unit="traj")
    finally:
        if executor is None:
            ex.close()
    return TrajectorySet(
        positions=np.concatenate([p["positions"] for p in parts]),
        durations=np.concatenate([p["durations"] for p in parts]),
        axes=tuple(robot_obj.joint_names), space="joint", robot=robot_record(robot_obj), task=task_obj.to_dict(),
        scene=None if scene_obj is None else scene_obj.to_dict(), source={**record, **_tally(parts)})


def _tally(parts: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The failures and attempts of a planned set, summed over its shards."""
    keys = sorted({k for p in parts for k in p.get("failures", {})})
    return {"failures": {k: int(sum(p["failures"].get(k, 0) for p in parts)) for k in keys},
            "attempts": int(sum(p.get("attempts", 0) for p in parts))}


def _condition_frame(task: Any) -> str | None:
    for t in task.primary:
        if task.condition is not None and t.name == task.condition.term:
            return str(t.frame)
    return None


def _box(value: ArrayLike | None, what: str) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    if value is None:
        return None
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (2, 3) or not np.all(np.isfinite(a)) or np.any(a[0] > a[1]):
        raise SettingsError(f"{what} must be [[x0, y0, z0], [x1, y1, z1]] with finite corners, low <= high; got "
                            f"{np.asarray(value).tolist()}")
    return tuple(map(float, a[0])), tuple(map(float, a[1]))


# ----------------------------------------------------------------------------- recordings


def from_recordings(paths: Sequence[str | Path], robot: Any, *, steps: int = 64,
                    joint_names: Sequence[str] | None = None, topic: str | None = None) -> TrajectorySet:
    """The recordings ``paths`` as a joint-space :class:`TrajectorySet` of ``robot``, each
    resampled to ``steps`` samples (see :mod:`genplan.seq2seq.recordings` for the formats).
    Joint names are matched to the robot's (a recording naming joints the robot lacks, or lacking
    one of the robot's, is refused naming them); ``joint_names`` gives the columns' names of a
    file that has none (``.npz`` without ``joint_names``)."""
    from genplan.samplers.data import robot_record
    from genplan.seq2seq.recordings import read_recording

    if not paths:
        raise SettingsError("from_recordings: no recording given")
    positions, durations = [], []
    names = list(robot.joint_names)
    for path in paths:
        t, q, cols = read_recording(Path(path), joint_names=joint_names, topic=topic)
        missing = [n for n in names if n not in cols]
        extra = [c for c in cols if c not in names]
        if missing:
            raise UnknownNameError(f"{path}: no column for joint(s) {missing} of robot '{robot.name}' (the recording "
                                   f"has {cols}{'; unknown to the robot: ' + str(extra) if extra else ''})")
        order = [cols.index(n) for n in names]
        positions.append(resample(t, q[:, order], steps, str(path)))
        durations.append(float(t[-1] - t[0]))
    lo, hi = np.asarray(robot.lower), np.asarray(robot.upper)
    data = np.asarray(positions)
    out = (data < lo - 1e-9) | (data > hi + 1e-9)
    if out.any():
        i, k, j = np.argwhere(out)[0]
        raise GenplanError(f"{paths[int(i)]}: sample {int(k)} puts joint {names[int(j)]} at {data[i, k, j]:.6g}, outside "
                           f"its limits [{lo[j]:.6g}, {hi[j]:.6g}]")
    return TrajectorySet(positions=data, durations=np.asarray(durations), axes=tuple(names), space="joint",
                         robot=robot_record(robot), source={"kind": "recordings", "files": [str(p) for p in paths]})


# ----------------------------------------------------------------------------- files

#: the manifest's format of a trajectory data set
FORMAT = "genplan-trajectories/1"
#: the shards' file suffix (arrays ``positions`` and ``durations``)
SUFFIX = ".npz"
#: what writes a trajectory data set (for messages)
COMMAND = "genplan data trajectories"
#: the manifest's fields that tell two trajectory data sets apart (with the robot's record)
KEYS = ("format", "genplan_version", "space", "axes", "K", "count", "shard_size", "seed", "task", "scene",
        "data_sha256", "source")


def set_sha256(axes: Sequence[str], positions: Iterable[NDArray[np.float64]],
               durations: Iterable[NDArray[np.float64]]) -> str:
    """The sha256 of a trajectory set: its axes, then its positions and its durations as float64
    bytes, each given in parts (shards, in order)."""
    h = hashlib.sha256()
    h.update(repr(tuple(str(a) for a in axes)).encode())
    for part in positions:
        h.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    for part in durations:
        h.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    return h.hexdigest()


def _arrays_sha256(positions: NDArray[np.float64], durations: NDArray[np.float64]) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(positions, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(durations, dtype=np.float64).tobytes())
    return h.hexdigest()


def _read_shard(path: Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A shard's (positions, durations); ValueError or OSError when it is not one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return np.asarray(z["positions"], dtype=np.float64), np.asarray(z["durations"], dtype=np.float64)
    except KeyError as exc:
        raise ValueError(f"no array {exc}") from None
    except (EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(str(exc) or type(exc).__name__) from None


def _store(folder: Path, index: int, data: Mapping[str, Any], seed: int | None) -> dict[str, Any]:
    """Write shard ``index`` (atomically) and return its manifest record: the sha256 of its arrays
    (not of the file: a zip file records when it was written), its count, and the planner's
    failures and attempts when it has them."""
    from genplan._files import atomic_path
    from genplan._shards import shard_file

    pos = np.ascontiguousarray(data["positions"], dtype=np.float64)
    dur = np.ascontiguousarray(data["durations"], dtype=np.float64)
    name = shard_file(index, SUFFIX)
    with atomic_path(folder / name) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, positions=pos, durations=dur)
    rec: dict[str, Any] = {"index": index, "file": name, "count": int(len(pos)), "sha256": _arrays_sha256(pos, dur)}
    if seed is not None:
        rec["seed"] = [seed, index]
    for key in ("failures", "attempts"):
        if key in data:
            rec[key] = data[key]
    return rec


def _verify(shape: tuple[int, int]) -> Callable[[Path, dict[str, Any], Any], bool]:
    """Whether a listed shard file holds its ``count`` trajectories of ``shape`` (K, d) and
    matches its record's sha256."""
    def verify(f: Path, rec: dict[str, Any], part: Any) -> bool:
        try:
            pos, dur = _read_shard(f)
        except (OSError, ValueError):
            return False
        return (pos.shape == (part.count, *shape) and dur.shape == (part.count,)
                and _arrays_sha256(pos, dur) == rec.get("sha256"))
    return verify


def _digest(axes: Sequence[str]) -> Callable[[Path, list[dict[str, Any]]], str]:
    def digest(folder: Path, records: list[dict[str, Any]]) -> str:
        return set_sha256(axes, (_read_shard(folder / r["file"])[0] for r in records),
                          (_read_shard(folder / r["file"])[1] for r in records))
    return digest


def _header(space: str, axes: Sequence[str], k: int, count: int, shard_size: int, robot: Any, task: Any, scene: Any,
            source: Mapping[str, Any], data_sha256: str | None) -> dict[str, Any]:
    """A trajectory data set's manifest header: what makes two runs the same data set
    (``data_sha256``: the content of a set written from memory; ``seed``: a planned set's)."""
    from genplan import _core

    return {"format": FORMAT, "genplan_version": _core.__version__, "space": space, "axes": list(axes), "K": k,
            "count": count, "shard_size": shard_size, "seed": source.get("seed"), "robot": robot, "task": task,
            "scene": scene, "source": dict(source), "data_sha256": data_sha256}


def _check_size(count: int, k: int, d: int, shard_size: int, out: Path, executor: Any,
                names: tuple[str, str]) -> None:
    """The disk and memory a data set of ``count`` trajectories of (k, d) needs (a trajectory is
    a row of k * d + 1 float64 numbers: :func:`genplan.samplers.data.check_data_size`)."""
    from genplan.executor import LocalExecutor
    from genplan.samplers.data import check_data_size

    workers = executor.workers if isinstance(executor, LocalExecutor) else (1 if executor is not None else
                                                                            (os.cpu_count() or 1))
    check_data_size(count, k * d + 1, shard_size, out=out, workers=workers, names=names)


def write_planned_trajectories(out: str | Path, robot: Any, task: Any, scene: Any = None, *, count: int,
                               steps: int = 64, seed: int = 0, start_box: ArrayLike | None = None,
                               goal_box: ArrayLike | None = None, frame: str | None = None,
                               spread: float | None = None, shard_size: int = 50, executor: Any = None,
                               progress: bool = True, max_attempts_factor: int = 20,
                               settings: Mapping[str, Any] | None = None, overwrite: bool = False,
                               force: bool = False, log: Callable[[str], Any] = print,
                               names: tuple[str, str] = ("count", "shard_size")) -> dict[str, Any]:
    """:func:`plan_trajectories` into the folder ``out`` as a data set (``genplan data
    trajectories``): its shards (``shard_00000.npz``, ...) and ``manifest.json``; returns the
    manifest. The folder's lock, resumption from the verified shards of an interrupted run (the
    same arguments give the same shards, bit for bit), the refusal of a folder holding another
    data set (``overwrite`` replaces it) and ``force`` are :func:`genplan._shards.write_shards`'s.
    Every argument, the disk space and the memory (``names``: the count's and the shard size's
    names in messages) are checked before any work."""
    from genplan._shards import write_shards
    from genplan.samplers.data import robot_record

    out = Path(out)
    shards, robot_obj, task_obj, scene_obj, record = _planned(
        robot, task, scene, count=count, steps=steps, seed=seed, start_box=start_box, goal_box=goal_box, frame=frame,
        spread=spread, shard_size=shard_size, max_attempts_factor=max_attempts_factor, settings=settings)
    _check_size(count, steps, robot_obj.nq, shard_size, out, executor, names)
    header = _header("joint", robot_obj.joint_names, steps, count, shard_size, robot_record(robot_obj),
                     task_obj.to_dict(), None if scene_obj is None else scene_obj.to_dict(), record, None)
    return write_shards(out, header, shards, plan_shard, store=lambda f, i, d: _store(f, i, d, seed),
                        verify=_verify((steps, robot_obj.nq)), digest=_digest(robot_obj.joint_names), keys=KEYS,
                        suffix=SUFFIX, desc=f"{robot_obj.name} trajectories", unit="traj", executor=executor,
                        progress=progress, log=log, overwrite=overwrite, force=force,
                        finish=lambda m: _tally(m["shards"]))


@dataclass(frozen=True)
class _Slice:
    """Trajectories ``start:start + count`` of a set in memory, its shard ``index``."""

    index: int
    count: int
    start: int


def write_trajectories(folder: str | Path, data: TrajectorySet, *, shard_size: int = 500, overwrite: bool = False,
                       force: bool = False, log: Callable[[str], Any] = print) -> Path:
    """Write ``data`` to ``folder`` (created if missing) as a data set: shards of ``shard_size``
    trajectories (``.npz``: positions, durations; each written atomically, its arrays' sha256 in
    the manifest) and ``manifest.json`` (the space, robot, task, scene, source; the set's sha256),
    as :func:`write_planned_trajectories` writes (one lock, resumption and refusal: a folder
    holding another data set is refused naming the differences, ``overwrite`` replaces it)."""
    from genplan._shards import write_shards
    from genplan.executor import LocalExecutor, chunks

    folder = Path(folder)
    if isinstance(shard_size, bool) or not isinstance(shard_size, (int, np.integer)) or shard_size < 1:
        raise SettingsError(f"shard_size must be a positive integer, got {shard_size!r}")
    if len(data) == 0:
        raise SettingsError("write_trajectories: the set holds no trajectory")
    _check_size(len(data), data.K, data.dim, shard_size, folder, LocalExecutor(1), ("count", "shard_size"))
    parts, start = [], 0
    for i, c in enumerate(chunks(len(data), shard_size)):
        parts.append(_Slice(i, c, start))
        start += c

    def compute(part: _Slice) -> dict[str, Any]:
        return {"positions": data.positions[part.start:part.start + part.count],
                "durations": data.durations[part.start:part.start + part.count]}

    header = _header(data.space, data.axes, data.K, len(data), shard_size, data.robot, data.task, data.scene,
                     data.source, data.sha256)
    with LocalExecutor(1) as ex:
        write_shards(folder, header, parts, compute, store=lambda f, i, d: _store(f, i, d, None),
                     verify=_verify((data.K, data.dim)), digest=_digest(data.axes), keys=KEYS, suffix=SUFFIX,
                     desc="trajectories", unit="traj", executor=ex, progress=False, log=log, overwrite=overwrite,
                     force=force)
    return folder


def read_trajectories(folder: str | Path, robot: Any = None) -> TrajectorySet:
    """The trajectory data set in ``folder`` (:func:`write_planned_trajectories`,
    :func:`write_trajectories`), every shard checked against its sha256 and the whole against
    the manifest's; given ``robot``, the set must be of its joints
    (:meth:`TrajectorySet.check_robot`). A missing folder or manifest is a FileNotFoundError, any
    other problem a GenplanError naming the file."""
    from genplan._shards import MANIFEST, load_manifest

    folder = Path(folder)
    m, records = load_manifest(folder, FORMAT, SUFFIX, COMMAND)
    path = folder / MANIFEST
    axes, k = m.get("axes"), m.get("K")
    if not (isinstance(axes, list) and all(isinstance(a, str) for a in axes) and axes and type(k) is int and k >= 2
            and m.get("space") in SPACES):
        raise GenplanError(f"{path}: not a trajectory data set manifest (its space, axes or K are malformed)")
    pos, dur = [], []
    for rec in records:
        f = folder / str(rec["file"])
        try:
            p, d = _read_shard(f)
        except (OSError, ValueError) as exc:
            raise GenplanError(f"{f}: missing or unreadable ({exc}); rerun `{COMMAND}` to repair the data set") from None
        if p.ndim != 3 or p.shape[1:] != (k, len(axes)) or d.shape != (len(p),) or len(p) != rec.get("count"):
            raise GenplanError(f"{f}: holds positions of shape {p.shape} and durations of shape {d.shape}, the manifest "
                               f"says {rec.get('count')} trajectories of ({k}, {len(axes)})")
        if _arrays_sha256(p, d) != rec["sha256"]:
            raise GenplanError(f"{f}: its arrays do not match the manifest's sha256: the file changed after it was "
                               f"written; rerun `{COMMAND}` to repair the data set")
        pos.append(p)
        dur.append(d)
    if not pos:
        raise GenplanError(f"{path}: the data set lists no shard")
    source = dict(m.get("source") or {})
    source.update({key: m[key] for key in ("failures", "attempts") if key in m})
    try:
        data = TrajectorySet(np.concatenate(pos), np.concatenate(dur), tuple(axes), m["space"], m.get("robot"),
                             m.get("task"), m.get("scene"), source)
    except GenplanError as exc:
        raise type(exc)(f"{folder}: {exc}") from None
    if data.sha256 != m.get("sha256"):
        raise GenplanError(f"{folder}: the data set's sha256 does not match its manifest")
    if robot is not None:
        data.check_robot(robot, str(folder))
    return data
