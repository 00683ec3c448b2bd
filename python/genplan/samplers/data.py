"""Training data: configurations on a task's constraint manifold.

Uniform samples within the joint limits, projected onto the task's manifold (the task without
its condition term, or the task its [condition] names: for the paper's robots, the projection
task: Panda gripper horizontal; Talos feet fixed, static stability, left arm at its default);
successes are kept until ``n`` are collected.

Where a learned sampler is asked (the [condition] box) may be a small corner of that manifold (a
two-arm robot's hands over a tray's area: a fraction of a percent of uniform projections).
``in_box`` (a share in [0, 1]) draws that share of the rows in the box instead: each is a
uniform sample projected onto the manifold with the condition term added, its target drawn
uniformly in the condition's ``low``/``high`` box (:func:`box_task`); :func:`box_share` measures
the share of any rows in the box (a GAN card reports it). ``in_box=0`` (the default) is the data set as it always was; a
learned sampler's training takes :func:`default_in_box`.

A data set of ``n`` configurations is made of shards of ``shard_size`` (the last one takes the
rest): shard ``i`` draws its uniform samples from :func:`genplan.executor.shard_rng` (the seed
and ``i`` only) in chunks of :data:`CHUNK`, projects them one after the other on one core
(:func:`project_shard`, the one definition of the loop), and keeps its first ``count``
successes. The shards run on an executor (:mod:`genplan.executor`: threads on every core by
default, or Ray), so a data set is the same bit for bit whatever runs it. A task holding Python
terms (:attr:`~genplan.projection.Task.python_terms`) runs its shards in processes instead
(:func:`executor_kind`: a Python term holds the GIL, so threads would take turns); each worker
rebuilds the terms by importing their entries (``module:Class`` and parameters, the task's plain
form), never by unpickling objects.

* :func:`valid_configurations`: the data set as an array, cached on disk (``$GENPLAN_CACHE`` or
  ``~/.cache/genplan``); :class:`TaskData`: its rows with the positions of the task's condition
  frame, what the ``"data"`` sampler draws.
* :func:`write_dataset` / :func:`read_dataset`: the data set as a folder of shards (``.npy``,
  written atomically) and a ``manifest.json`` (counts, seeds, sha256 per shard and of the whole
  set, the task, the robot's files' sha256, genplan's version); an interrupted run resumes from
  its verified shards (``genplan data``, ``genplan train gan --data``). A folder is written by
  one run at a time (its lock file, :data:`LOCK`); a run that fails before its first shard leaves
  nothing behind. The folder, lock and manifest machinery is :mod:`genplan._shards`, shared with
  the trajectory data sets of :mod:`genplan.seq2seq.data`.

Sizes are checked against the machine before anything is allocated (:func:`check_data_size`):
a data set on disk must fit in its folder's free space, a shard in memory on every local worker,
and an in-memory data set (:func:`valid_configurations`) in the available memory.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import shutil
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan import projection as P
from genplan._arrays import as_box, as_configurations
from genplan._shards import LOCK, MANIFEST, FolderLock, load_manifest, record, same, shard_file, write_shards
from genplan.cache import cache_dir, load_array, read_npy, save_array, sha256_file, write_npy
from genplan.errors import GenplanError, SettingsError, ShapeError
from genplan.executor import Executor, LocalExecutor, chunks, shard_rng, stopping
from genplan.robots import Robot

#: uniform samples projected per call (fewer for a shard of fewer configurations)
CHUNK = 2000
#: configurations per shard (default)
SHARD_SIZE = 5000
#: rows projected per call within a chunk: an interrupted run's worker threads stop after one
#: (:func:`genplan.executor.stopping`; a Talos piece takes about 0.8 s on one core)
PIECE = 250
#: the manifest's format
FORMAT = "genplan-dataset/1"
#: the most shards a data set may have (each is a file the manifest lists)
MAX_SHARDS = 100_000
#: the share of a learned sampler's training rows drawn in the condition's box, for a task of
#: the user's (:func:`default_in_box`): half, so that the rest still spans the whole manifold
IN_BOX = 0.5


def _task(robot: Robot, task: P.Task | None) -> P.Task:
    return P.manifold_task(_run_task(robot, task), robot)


def _run_task(robot: Robot, task: P.Task | None) -> P.Task:
    return P.load_task(P.default_task_name(robot), robot) if task is None else task


def _plain(value: Any) -> Any:
    """Paths as strings, recursively (a robot description as JSON data)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def _key(robot: Robot, n: int, seed: int, manifold: P.Task, shard_size: int, in_box: float = 0.0,
         box: NDArray[np.float64] | None = None) -> str:
    fields: dict[str, Any] = {"robot": robot.name, "n": n, "seed": seed, "version": _core.__version__,
                              "shards": shard_size, "chunk": CHUNK,
                              "terms": [t.to_native(robot) for t in manifold.primary if not isinstance(t, P.CustomTerm)]}
    if manifold.python_terms:  # by their entries and parameters (their native form holds the object)
        fields["python_terms"] = [d for d in manifold.to_dict()["primary"] if d["kind"] == "python"]
    if in_box > 0:  # absent otherwise: the keys of data sets made without it are unchanged
        assert box is not None
        fields["in_box"] = [float(in_box), box.tolist()]
    desc = json.dumps(fields, sort_keys=True, default=str)
    return hashlib.sha256(desc.encode()).hexdigest()[:16]


def cache_path(robot: Robot, n: int, seed: int, task: P.Task | None = None, shard_size: int = SHARD_SIZE, *,
               in_box: float = 0.0) -> Path:
    """Where :func:`valid_configurations` caches its result."""
    run_task = _run_task(robot, task)
    box = condition_box(run_task) if _check_in_box(in_box) > 0 else None
    key = _key(robot, n, seed, _task(robot, run_task), shard_size, in_box, box)
    return cache_dir() / "data" / f"{robot.name}_valid_{n}_{seed}_{key}.npy"


# -- the condition's box


def default_in_box(task: P.Task) -> float:
    """The share of a learned sampler's training rows drawn in the condition's box by default:
    0 for a shipped task (the papers' tasks keep the papers' data: uniform projections), else
    :data:`IN_BOX`."""
    return 0.0 if task.name in P.task_names() else IN_BOX


def _check_in_box(in_box: float) -> float:
    """``in_box`` as a float in [0, 1], else SettingsError naming it."""
    if isinstance(in_box, bool) or not isinstance(in_box, (int, float, np.integer, np.floating)) \
            or not 0.0 <= float(in_box) <= 1.0:
        raise SettingsError(f"in_box must be a share in [0, 1] (of the rows drawn in the condition's box), got {in_box!r}")
    return float(in_box)


def condition_box(task: P.Task) -> NDArray[np.float64]:
    """The [condition] box of ``task``, [[low], [high]] (its targets' box: IK queries and a
    card's held-out targets are drawn in it); GenplanError for a task without a usable condition."""
    P.condition_term(task)
    assert task.condition is not None
    return np.array([task.condition.low, task.condition.high], dtype=np.float64)


def box_task(robot: Robot, task: P.Task) -> P.Task:
    """The task the rows drawn in the condition's box are projected onto: the manifold
    (:func:`genplan.projection.manifold_task`) with the condition term added, its target set per
    row (a target drawn uniformly in :func:`condition_box`)."""
    manifold = _task(robot, task)
    cond = P.condition_term(task)
    assert task.condition is not None
    return dataclasses.replace(manifold, primary=(*manifold.primary, cond),
                               condition=dataclasses.replace(task.condition, manifold=None))


def data_description(in_box: float | None) -> str:
    """How training rows were made, as a card says: ``in_box`` the share drawn in the condition's
    box (None: rows given by the caller)."""
    if in_box is None:
        return "given by the caller"
    plain = "uniform samples in the joint limits projected onto the task's manifold"
    if in_box == 0:
        return plain
    return (f"{plain}; {in_box:g} of them with the condition term added, its target drawn uniformly in the "
            "condition's box")


def in_box_mask(positions: NDArray[np.float64], box: Any) -> NDArray[np.bool_]:
    """Which of ``positions`` (n, 3) lie in ``box`` ([[x, y, z] min, max], faces included)."""
    lo, hi = as_box(box, "box")
    return np.all((positions >= lo) & (positions <= hi), axis=1)  # type: ignore[no-any-return]


def box_share(robot: Robot, task: P.Task, rows: NDArray[np.float64]) -> dict[str, Any]:
    """Where the condition frame of ``task`` lies in ``rows`` against the condition's box
    (:func:`condition_box`): ``{"box", "frame", "rows", "of", "share"}`` (rows inside, of all rows,
    their share in [0, 1]; no tolerance: a row projected onto a target on the box's face within
    the term's tolerance may lie just outside)."""
    frame = P.condition_term(task).frame
    box = condition_box(task)
    inside = int(in_box_mask(robot.frame_positions(rows, frame), box).sum())
    return {"box": box.tolist(), "frame": frame, "rows": inside, "of": int(len(rows)),
            "share": inside / len(rows) if len(rows) else 0.0}


# -- sizes


def format_bytes(n: float) -> str:
    """``n`` bytes in decimal units (kB, MB, GB, TB, PB), one decimal."""
    if n < 1000:
        return f"{int(n)} B"
    for unit in ("kB", "MB", "GB", "TB"):
        n /= 1000
        if n < 1000:
            return f"{n:.1f} {unit}"
    return f"{n / 1000:.1f} PB"


def available_memory() -> int | None:
    """Bytes this process can still allocate: the system's available memory (``MemAvailable``,
    else the free pages), less under an address-space limit (``ulimit -v``) when that leaves less;
    None when neither can be read."""
    avail: int | None = None
    try:
        with open("/proc/meminfo") as f:
            avail = next((int(line.split()[1]) * 1024 for line in f if line.startswith("MemAvailable:")), None)
    except (OSError, ValueError, IndexError):
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (AttributeError, ValueError, OSError):
            pass
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/status") as f:
                used = next((int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:")), 0)
            room = max(0, soft - used)
            avail = room if avail is None else min(avail, room)
    except (ImportError, OSError, ValueError, IndexError):
        pass
    return avail


def _free_disk(folder: Path) -> tuple[int, Path]:
    """The free bytes of the file system ``folder`` is (or would be created) on, and the existing
    folder they were read from."""
    where = Path(folder).absolute()
    while not where.exists() and where != where.parent:
        where = where.parent
    return shutil.disk_usage(where).free, where


def check_data_size(n: int, nq: int, shard_size: int = SHARD_SIZE, *, out: Path | None = None, workers: int = 1,
                    names: tuple[str, str] = ("data size", "shard size")) -> None:
    """SettingsError naming ``names`` (the size's and the shard size's, e.g. the command's
    options) and the bytes, before anything is allocated, when a data set of ``n`` configurations
    of ``nq`` numbers in shards of ``shard_size`` cannot be made here: with ``out`` (a data set
    on disk), more than the free space of its file system (less what shard files there already
    hold) or more than :data:`MAX_SHARDS` shards; and a shard per worker (``workers``, twice its
    size while its chunks are joined) more than the available memory (:func:`available_memory`)."""
    for value, name in ((n, names[0]), (shard_size, names[1])):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise SettingsError(f"{name} must be a positive integer, got {value!r}")
    n, shard_size, row = int(n), int(shard_size), 8 * int(nq)
    if out is not None:
        count = -(-n // shard_size)
        need = n * row + 128 * count  # the rows and each shard's .npy header
        out = Path(out)
        have = sum(f.stat().st_size for f in out.glob("shard_*.npy")) if out.is_dir() else 0
        free, where = _free_disk(out)
        if need - have > free:
            raise SettingsError(f"{names[0]} {n}: the data set needs {format_bytes(need)} on disk ({n} x {nq} "
                                f"float64), {format_bytes(free)} free at {where}: give a smaller {names[0]} or another "
                                "folder")
        if count > MAX_SHARDS:
            raise SettingsError(f"{names[1]} {shard_size}: {count} shards, more than {MAX_SHARDS} (each is a file its "
                                f"manifest lists): give a larger {names[1]}")
    rows = min(n, shard_size)
    avail = available_memory()
    if avail is not None and 2 * workers * rows * row > avail:
        raise SettingsError(f"{names[1]} {shard_size}: {workers} worker{'s' if workers > 1 else ''} hold a shard of "
                            f"{format_bytes(rows * row)} each in memory ({rows} x {nq} float64, twice that while it is "
                            f"joined), more than the {format_bytes(avail)} available: give a smaller {names[1]}")


def _check_in_memory(robot: Robot, n: int) -> None:
    """SettingsError when ``n`` configurations of ``robot`` (twice, while the shards are joined)
    do not fit in the available memory."""
    avail = available_memory()
    need = n * 8 * robot.nq
    if avail is not None and 2 * need > avail:
        raise SettingsError(f"data size {n}: {n} configurations of {robot.name} need {format_bytes(need)} in memory "
                            f"({n} x {robot.nq} float64, twice that while they are joined), more than the "
                            f"{format_bytes(avail)} available: give a smaller data size (--data-size), or write it "
                            "to disk in shards with `genplan data`")


# -- the shards


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` of a data set seeded ``seed``: ``count`` configurations of ``robot`` (its
    description) on the task ``manifold`` (its :meth:`~genplan.projection.Task.to_dict`).
    Plain data: pickled to a worker process or a Ray node, which rebuilds the projector once."""

    robot: dict[str, Any]
    manifold: dict[str, Any]
    seed: int
    index: int
    count: int
    #: of ``count``, the rows drawn in the condition's box (projected onto ``box_task``, targets
    #: uniform in ``box``), after the others
    in_box: int = 0
    box_task: dict[str, Any] | None = None
    box: tuple[tuple[float, ...], tuple[float, ...]] | None = None


#: this process's robots and projectors by (description, manifold): a worker builds each once
_SOLVERS: dict[str, tuple[Robot, P.GaussNewtonProjector]] = {}
_ROBOTS: dict[str, Robot] = {}
_LOCK = threading.Lock()


def executor_kind(task: P.Task | None) -> str:
    """The local workers a data set of ``task`` runs on: ``"thread"`` (the native projector
    releases the GIL), or ``"process"`` when the task holds Python terms, which hold it."""
    return "process" if task is not None and task.python_terms else "thread"


def _robot_key(description: Mapping[str, Any]) -> str:
    return json.dumps(_plain(description), sort_keys=True)


def _solver(shard: Shard, task: dict[str, Any] | None = None) -> tuple[Robot, P.GaussNewtonProjector]:
    """This process's robot and projector onto ``task`` (plain data; default the shard's manifold)."""
    task = shard.manifold if task is None else task
    key = json.dumps([shard.robot, task], sort_keys=True)
    with _LOCK:
        if key not in _SOLVERS:
            rkey = _robot_key(shard.robot)
            robot = _ROBOTS.get(rkey) or Robot(shard.robot)
            _ROBOTS[rkey] = robot
            # allow_python: a shard's python terms are those of the task the run was given, already
            # imported by the process that made the shards; a worker process imports them again
            _SOLVERS[key] = (robot, P.GaussNewtonProjector(robot, P.Task.from_dict(task, robot, allow_python=True)))
        return _SOLVERS[key]


def shards(robot: Robot, n: int, seed: int = 0, task: P.Task | None = None,
           shard_size: int = SHARD_SIZE, *, in_box: float = 0.0) -> list[Shard]:
    """The shards of the data set of ``n`` configurations (see the module's docstring); each
    draws ``round(in_box * count)`` of its rows in the condition's box."""
    share = _check_in_box(in_box)
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    if shard_size < 1:
        raise SettingsError(f"shard_size must be positive, got {shard_size}")
    if -(-n // shard_size) > MAX_SHARDS:
        raise SettingsError(f"shard_size {shard_size}: {-(-n // shard_size)} shards of {n} configurations, more than "
                            f"{MAX_SHARDS}: give a larger shard size")
    description = _plain(robot.description)
    with _LOCK:
        _ROBOTS.setdefault(_robot_key(description), robot)  # this process's workers reuse it
    run_task = _run_task(robot, task)
    manifold = _task(robot, run_task).to_dict()
    if share == 0:
        return [Shard(description, manifold, seed, i, c) for i, c in enumerate(chunks(n, shard_size))]
    targeted = box_task(robot, run_task).to_dict()
    lo, hi = condition_box(run_task).tolist()
    return [Shard(description, manifold, seed, i, c, round(share * c), targeted, (tuple(lo), tuple(hi)))
            for i, c in enumerate(chunks(n, shard_size))]


def project_shard(shard: Shard) -> NDArray[np.float64]:
    """The ``shard.count`` configurations of a shard, shape (count, nq): uniform samples from
    the shard's generator projected one after the other (the native projector releases the GIL,
    so threads run shards in parallel), the first successes kept; the last ``shard.in_box`` of
    them projected onto ``shard.box_task`` with targets drawn uniformly in ``shard.box`` (from the
    same generator, after the others).

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold (or the condition's box on it) is then out of reach of the joint limits, or
    nearly so."""
    robot, solver = _solver(shard)
    rng = shard_rng(shard.seed, shard.index)
    rows = [_project(shard, robot, solver, rng, shard.count - shard.in_box)]
    if shard.in_box:
        assert shard.box_task is not None and shard.box is not None
        rows.append(_project(shard, robot, _solver(shard, shard.box_task)[1], rng, shard.in_box,
                             np.array(shard.box, dtype=np.float64)))
    return np.ascontiguousarray(np.concatenate(rows))


def _project(shard: Shard, robot: Robot, solver: P.GaussNewtonProjector, rng: np.random.Generator, count: int,
             box: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``count`` successes of ``solver`` from uniform samples drawn from ``rng`` (with ``box``:
    and the condition term's target per sample, uniform in it), (count, nq)."""
    chunk = min(CHUNK, count)
    kept: list[NDArray[np.float64]] = [np.empty((0, robot.nq))]
    found = tried = 0
    term = "" if box is None else P.condition_term(solver.task).name
    while found < count:
        qs = robot.random_configurations(chunk, rng)
        targets = None if box is None else rng.uniform(box[0], box[1], size=(chunk, 3))
        for a in range(0, chunk, PIECE):  # rows are projected independently: pieces change no result
            if stopping():
                raise KeyboardInterrupt(f"shard {shard.index}: the run was interrupted")
            res = solver.solve_batch(qs[a:a + PIECE], parallel=False,
                                     targets=None if targets is None else {term: targets[a:a + PIECE]})
            good = res.q[res.success]
            kept.append(good)
            found += len(good)
        tried += chunk
        if tried >= 10 * chunk and found < 0.01 * tried:
            where = "" if box is None else f" with its frame at targets in the condition's box {box.tolist()}"
            raise GenplanError(f"{robot.name}: only {found} of {tried} uniform samples project onto the manifold of "
                               f"task '{solver.task.name}'{where}: is it reachable within the joint limits?")
    return np.concatenate(kept)[:count]


def generate(robot: Robot, n: int, seed: int = 0, task: P.Task | None = None, *, shard_size: int = SHARD_SIZE,
             executor: Executor | None = None, progress: bool = True, in_box: float = 0.0) -> NDArray[np.float64]:
    """The data set of ``n`` configurations (not cached), its shards on ``executor`` (default:
    one worker per core, threads or, for Python terms, processes: :func:`executor_kind`);
    ``in_box``: the share drawn in the condition's box (see the module's docstring)."""
    parts = shards(robot, n, seed, task, shard_size, in_box=in_box)
    ex = executor or LocalExecutor(kind=executor_kind(_task(robot, task)))
    try:
        out = ex.map(project_shard, parts, desc=f"{robot.name} data (projecting)", progress=progress,
                     weights=[s.count for s in parts], unit="q")
    finally:
        if executor is None:
            ex.close()
    return np.concatenate(out)


def _outside_limits(robot: Robot, data: NDArray[np.float64]) -> str:
    """Where the rows of ``data`` leave ``robot``'s joint limits (its first such value), or ""."""
    bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    out = (data[:, bounded] < robot.lower[bounded]) | (data[:, bounded] > robot.upper[bounded])
    if not out.any():
        return ""
    row, col = map(int, np.argwhere(out)[0])
    j = int(np.flatnonzero(bounded)[col])
    k = int(out.any(axis=1).sum())
    return (f"{k} row{'s' if k > 1 else ''} outside the joint limits (row {row}: q[{j}] = {data[row, j]:.6g}, "
            f"limits [{robot.lower[j]:.6g}, {robot.upper[j]:.6g}])")


def valid_configurations(robot: Robot, n: int = 25_000, seed: int = 0, use_cache: bool = True,
                         progress: bool = True, task: P.Task | None = None, *, shard_size: int = SHARD_SIZE,
                         executor: Executor | None = None, in_box: float = 0.0) -> NDArray[np.float64]:
    """``n`` configurations on the manifold of ``task`` (default: the robot's shipped
    ``<robot>_ik``; see :func:`genplan.projection.manifold_task`), shape (n, nq), reproducible:
    :func:`generate`, cached; ``in_box``: the share of them drawn with the condition frame in the
    condition's box (see the module's docstring). With ``in_box=0``, the same array as ``genplan
    data`` writes for the same seed and shard size (:func:`read_dataset`).

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold is then out of reach of the joint limits, or nearly so."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    _check_in_memory(robot, n)
    path = cache_path(robot, n, seed, task, shard_size, in_box=in_box)
    cached = load_array(path, (n, robot.nq)) if use_cache else None
    if cached is not None:
        bad = _outside_limits(robot, cached)
        if not bad:
            return cached
        warnings.warn(f"{path}: {bad}, which the data set never holds (the file and its hash were changed after "
                      "they were written); regenerating it", RuntimeWarning, stacklevel=2)
    data = generate(robot, n, seed, task, shard_size=shard_size, executor=executor, progress=progress, in_box=in_box)
    if use_cache:
        save_array(path, data)
    return data



class TaskData:
    """Rows of valid configurations of a task with the positions its condition frame reaches in
    them: the one source of the ``"data"`` sampler's rows, which the planner draws uniformly
    (:func:`genplan.planning.data_sampler`: the rows whose frame lies in a box, :meth:`in_box`)
    and :func:`genplan.solve_ik` takes as warm starts (the rows whose frame is nearest each
    target, :meth:`nearest`).

    ``task``: a Task, shipped name or task file with a [condition] (default: the robot's shipped
    ``<robot>_ik``). ``rows`` (n, nq): the configurations; default: the data set a learned sampler
    of the task is trained on by default (:func:`valid_configurations`, ``size`` rows of seed
    ``seed``, :func:`default_in_box` of them in the condition's box, made once and cached).
    Raises ShapeError or NonFiniteError for bad ``rows``."""

    def __init__(self, robot: Robot, task: "str | os.PathLike[str] | P.Task | None" = None,
                 rows: Any = None, *, size: int = 25_000, seed: int = 0, progress: bool = False) -> None:
        self.robot = robot
        self._task = task
        if rows is None:
            self.rows = valid_configurations(robot, size, seed, progress=progress, task=self.task,
                                             in_box=default_in_box(self.task))
        else:
            self.rows = as_configurations(rows, robot.nq, "data")
            if self.rows.ndim != 2:
                raise ShapeError(f"data: expected shape (n, {robot.nq}), got {self.rows.shape}")

    @functools.cached_property
    def task(self) -> P.Task:
        """The task (read when first needed: rows given and drawn from anywhere need none)."""
        return P.load_task(P.default_task_name(self.robot) if self._task is None else self._task, self.robot)

    @functools.cached_property
    def frame(self) -> str:
        """The task's condition frame, whose positions a learned sampler is conditioned on."""
        return P.condition_term(self.task).frame

    @functools.cached_property
    def positions(self) -> NDArray[np.float64]:
        """Where :attr:`frame` lies in each row: (n, 3)."""
        return self.robot.frame_positions(self.rows, self.frame)

    def in_box(self, box: Any = None) -> NDArray[np.float64]:
        """The rows whose frame lies in ``box`` ([[x, y, z] min, max]; default: the box a learned
        sampler of the task draws its targets from when planning,
        :func:`genplan.samplers.costs.sampling_box`); SettingsError when none does."""
        from genplan.samplers.costs import sampling_box

        lo, hi = as_box(sampling_box(self.task) if box is None else box, "box")
        keep = in_box_mask(self.positions, [lo, hi])
        if not keep.any():
            raise SettingsError(f"box: none of the {len(self.rows)} configurations has its frame '{self.frame}' in "
                                f"{[lo.tolist(), hi.tolist()]} (give another box, or in_box=False)")
        return self.rows[keep]

    def nearest(self, targets: NDArray[np.float64], k: int) -> tuple[NDArray[np.float64], float]:
        """For each of ``targets`` (n, 3), the ``k`` rows whose frame is nearest it, nearest first:
        (n, k, nq) (k at most the number of rows); and the lookup's seconds per target (the k-d
        tree's construction, like a model's loading, not counted)."""
        from scipy.spatial import cKDTree

        tree = cKDTree(self.positions)
        k = min(k, len(self.rows))
        t0 = time.perf_counter()
        _, idx = tree.query(targets, k=k)
        lookup_s = (time.perf_counter() - t0) / len(targets)
        return self.rows[np.asarray(idx).reshape(len(targets), k)], lookup_s

# -- data sets on disk


def robot_record(robot: Robot) -> dict[str, Any]:
    """The robot as a manifest records it: its name, description, the sha256 of each of its
    files (robot file, URDF, collision URDF, SRDF), and ``sha256``: one hash of the name, the
    files' contents and the description's other fields (not its paths, so that a data set made
    on another machine matches)."""
    description = _plain(robot.description)
    files = {role: {"path": str(p), "sha256": sha256_file(Path(p))}
             for role, p in (("source", robot.source), ("urdf", robot.urdf_path),
                             ("collision_urdf", robot.collision_urdf_path), ("srdf", robot.srdf_path))
             if p is not None}
    paths = {"urdf", "collision_urdf", "srdf", "source", "package_dirs"}
    ident = {"name": robot.name, "files": {k: v["sha256"] for k, v in files.items()},
             "fields": {k: v for k, v in description.items() if k not in paths}}
    return {"name": robot.name, "sha256": hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest(),
            "files": files, "description": description}


def _shard_file(index: int) -> str:
    return shard_file(index, ".npy")


def dataset_sha256(parts: Iterable[NDArray[np.float64]]) -> str:
    """The sha256 of a data set: of its configurations' float64 bytes, row after row (the same as
    ``hashlib.sha256(np.ascontiguousarray(data, np.float64).tobytes())`` of the whole array).
    ``parts`` may be any iterable (a generator reading one shard at a time)."""
    h = hashlib.sha256()
    for a in parts:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


def _is_shard(path: Path, count: int, nq: int) -> bool:
    """Whether ``path`` holds ``count`` configurations of ``nq`` float64 numbers."""
    try:
        a = read_npy(path)
    except (OSError, ValueError):
        return False
    return a.shape == (count, nq) and a.dtype == np.float64


def _workers(ex: Executor | None) -> int:
    """The shards a run holds in this machine's memory at once."""
    if ex is None:
        return os.cpu_count() or 1
    return ex.workers if isinstance(ex, LocalExecutor) else 1


def write_dataset(out: Path, robot: Robot, n: int, seed: int = 0, task: P.Task | None = None, *,
                  shard_size: int = SHARD_SIZE, executor: Executor | None = None, progress: bool = True,
                  log: Callable[[str], Any] = print, overwrite: bool = False, force: bool = False) -> dict[str, Any]:
    """Write the data set of ``n`` configurations to the folder ``out`` (created if missing): its
    shards and ``manifest.json``; returns the manifest.

    Before any work: the sizes (:func:`check_data_size`: the folder's free space, the memory of
    the local workers; SettingsError), the task's manifold on this robot (its projector is
    built), and the folder's lock (:class:`FolderLock`; ``force`` takes another run's).

    Resumes: a shard the folder's manifest lists and whose file has the listed sha256 is kept;
    any other is (re)computed. The manifest is rewritten as shards finish (at most once a second)
    and when the run ends, failed or not, so an interrupted run keeps what it finished; a run that
    fails before its first shard leaves no manifest, and removes the folders it created. A folder
    holding another data set (another robot, task, size, seed, shard size or genplan version) is
    refused (GenplanError naming the differences) unless ``overwrite``, which removes that data
    set's files (its manifest and shards; nothing else) first."""
    out = Path(out)
    check_data_size(n, robot.nq, shard_size, out=out, workers=_workers(executor))
    run_task = _run_task(robot, task)
    parts = shards(robot, n, seed, run_task, shard_size)
    try:  # the manifold's projector: a task this robot cannot use fails here, before any file is written
        _solver(parts[0])
    except GenplanError as exc:
        raise type(exc)(f"task '{run_task.name}' (manifold '{parts[0].manifold.get('name')}') on robot "
                        f"'{robot.name}': {exc}") from None
    header: dict[str, Any] = {
        "format": FORMAT,
        "genplan_version": _core.__version__,
        "robot": robot_record(robot),
        "task": run_task.to_dict(),
        "manifold": parts[0].manifold,
        "nq": robot.nq,
        "data_size": n,
        "seed": seed,
        "shard_size": shard_size,
        "chunk": CHUNK,
        "seeds": "shard i draws from numpy.random.SeedSequence(seed, spawn_key=(i,)) (genplan.executor.shard_seed)",
    }
    keys = ("format", "genplan_version", "nq", "data_size", "seed", "shard_size", "chunk", "manifold")

    def store(folder: Path, i: int, data: NDArray[np.float64]) -> dict[str, Any]:
        digest = write_npy(folder / _shard_file(i), data)
        return {"index": i, "file": _shard_file(i), "count": int(len(data)), "seed": [seed, i], "sha256": digest}

    def verify(f: Path, rec: dict[str, Any], part: Shard) -> bool:
        return sha256_file(f) == rec.get("sha256") and _is_shard(f, part.count, robot.nq)

    def digest(folder: Path, records: list[dict[str, Any]]) -> str:
        return dataset_sha256(read_npy(folder / r["file"]) for r in records)

    kind = executor_kind(_task(robot, run_task))
    own = executor is None and kind != "thread"
    ex = LocalExecutor(kind=kind) if own else executor
    try:
        # project_shard is looked up here, at the call, so that a replaced one (tests) is the one run
        return write_shards(out, header, parts, project_shard, store=store, verify=verify, digest=digest, keys=keys,
                            suffix=".npy", desc=f"{robot.name} data", unit="q", executor=ex, progress=progress,
                            log=log, overwrite=overwrite, force=force)
    finally:
        if own and ex is not None:
            ex.close()


def read_dataset(folder: Path, robot: Robot | None = None, task: P.Task | None = None) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """The configurations of the data set in ``folder`` (its shards in order) and its manifest,
    every shard and the whole set checked against the manifest's sha256. Given ``robot`` (and
    ``task``: default the robot's ``<robot>_ik``), the data set must have been made for them
    (the robot's files and the task's manifold), else GenplanError naming both."""
    folder = Path(folder)
    path = folder / MANIFEST
    m, records = load_manifest(folder, FORMAT, ".npy", "genplan data")
    size = m.get("data_size")
    if type(size) is not int or size < 1 or type(m.get("nq")) is not int:
        raise GenplanError(f"{path}: not a data set manifest (its data_size or nq is malformed)")
    if robot is not None:
        mine = robot_record(robot)
        theirs = record(m, "robot")
        if theirs.get("sha256") != mine["sha256"]:
            raise GenplanError(f"{folder} was made for robot '{theirs.get('name')}' (sha256 {str(theirs.get('sha256'))[:12]}), "
                               f"this run's robot is '{robot.name}' (sha256 {mine['sha256'][:12]}): its files or "
                               "description differ")
        manifold = _task(robot, task).to_dict()
        if not same(m.get("manifold"), manifold):
            run_name = _run_task(robot, task).name
            raise GenplanError(f"{folder} was made for task '{record(m, 'task').get('name')}' (manifold "
                               f"'{record(m, 'manifold').get('name')}'), this run's task is '{run_name}' (manifold "
                               f"'{manifold.get('name')}'): their manifolds differ")
    parts = []
    for rec in records:
        f = folder / rec["file"]
        if not f.is_file() or sha256_file(f) != rec["sha256"]:
            raise GenplanError(f"{f}: missing or not matching the manifest's sha256: rerun `genplan data` to repair it")
        try:
            parts.append(read_npy(f))
        except ValueError as exc:  # its sha256 matched: the manifest was made to match it
            raise GenplanError(f"{f}: not a shard ({exc})") from None
    if sum(len(a) for a in parts) != size or any(a.ndim != 2 or a.shape[1] != m["nq"] or a.dtype != np.float64
                                                  for a in parts):
        raise GenplanError(f"{path}: shards do not add up to {size} configurations")
    if dataset_sha256(parts) != m.get("sha256"):
        raise GenplanError(f"{folder}: the data set's sha256 does not match its manifest")
    return np.concatenate(parts), m
