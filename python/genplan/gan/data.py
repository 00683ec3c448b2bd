"""Training data: configurations on a task's constraint manifold.

Uniform samples within the joint limits, projected onto the task's manifold (the task without
its condition term, or the task its [condition] names: for the paper's robots, the projection
task: Panda gripper horizontal; Talos feet fixed, static stability, left arm at its default);
successes are kept until ``n`` are collected.

A data set of ``n`` configurations is made of shards of ``shard_size`` (the last one takes the
rest): shard ``i`` draws its uniform samples from :func:`genplan.executor.shard_rng` (the seed
and ``i`` only) in chunks of :data:`CHUNK`, projects them one after the other on one core
(:func:`project_shard`, the one definition of the loop), and keeps its first ``count``
successes. The shards run on an executor (:mod:`genplan.executor`: threads on every core by
default, or Ray), so a data set is the same bit for bit whatever runs it.

* :func:`valid_configurations`: the data set as an array, cached on disk (``$GENPLAN_CACHE`` or
  ``~/.cache/genplan``).
* :func:`write_dataset` / :func:`read_dataset`: the data set as a folder of shards (``.npy``,
  written atomically) and a ``manifest.json`` (counts, seeds, sha256 per shard and of the whole
  set, the task, the robot's files' sha256, genplan's version); an interrupted run resumes from
  its verified shards (``genplan data``, ``genplan train gan --data``). A folder is written by
  one run at a time (its lock file, :data:`LOCK`); a run that fails before its first shard leaves
  nothing behind.

Sizes are checked against the machine before anything is allocated (:func:`check_data_size`):
a data set on disk must fit in its folder's free space, a shard in memory on every local worker,
and an in-memory data set (:func:`valid_configurations`) in the available memory.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import shutil
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan import projection as P
from genplan._files import missing_folders, remove_empty_folders, write_text
from genplan.cache import cache_dir, load_array, read_npy, save_array, sha256_file, write_npy
from genplan.errors import GenplanError, SettingsError
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
MANIFEST = "manifest.json"
#: the lock file of a data set folder while a run writes it: JSON ``{"run", "host", "pid",
#: "pid_start", "started", "command"}`` (see :class:`FolderLock`)
LOCK = "genplan.lock"
#: the most shards a data set may have (each is a file the manifest lists)
MAX_SHARDS = 100_000
#: the files of a data set folder that genplan writes (what ``overwrite`` removes): the manifest,
#: the shards, and the temporary files of either left by a killed run
_OWN_FILES = re.compile(r"manifest\.json|shard_\d{5,}\.npy|\.(manifest|shard_\d{5,})\..*\.tmp\.(json|npy)")


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


def _key(robot: Robot, n: int, seed: int, manifold: P.Task, shard_size: int) -> str:
    desc = json.dumps({"robot": robot.name, "n": n, "seed": seed, "version": _core.__version__, "shards": shard_size,
                       "chunk": CHUNK, "terms": [t.to_native(robot) for t in manifold.primary]},
                      sort_keys=True, default=str)
    return hashlib.sha256(desc.encode()).hexdigest()[:16]


def cache_path(robot: Robot, n: int, seed: int, task: P.Task | None = None, shard_size: int = SHARD_SIZE) -> Path:
    """Where :func:`valid_configurations` caches its result."""
    key = _key(robot, n, seed, _task(robot, task), shard_size)
    return cache_dir() / "data" / f"{robot.name}_valid_{n}_{seed}_{key}.npy"


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


#: this process's robots and projectors by (description, manifold): a worker builds each once
_SOLVERS: dict[str, tuple[Robot, P.GaussNewtonProjector]] = {}
_ROBOTS: dict[str, Robot] = {}
_LOCK = threading.Lock()


def _robot_key(description: Mapping[str, Any]) -> str:
    return json.dumps(_plain(description), sort_keys=True)


def _solver(shard: Shard) -> tuple[Robot, P.GaussNewtonProjector]:
    key = json.dumps([shard.robot, shard.manifold], sort_keys=True)
    with _LOCK:
        if key not in _SOLVERS:
            rkey = _robot_key(shard.robot)
            robot = _ROBOTS.get(rkey) or Robot(shard.robot)
            _ROBOTS[rkey] = robot
            manifold = P.Task.from_dict(shard.manifold, robot)
            _SOLVERS[key] = (robot, P.GaussNewtonProjector(robot, manifold))
        return _SOLVERS[key]


def shards(robot: Robot, n: int, seed: int = 0, task: P.Task | None = None,
           shard_size: int = SHARD_SIZE) -> list[Shard]:
    """The shards of the data set of ``n`` configurations (see the module's docstring)."""
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
    manifold = _task(robot, task).to_dict()
    return [Shard(description, manifold, seed, i, c) for i, c in enumerate(chunks(n, shard_size))]


def project_shard(shard: Shard) -> NDArray[np.float64]:
    """The ``shard.count`` configurations of a shard, shape (count, nq): uniform samples from
    the shard's generator projected one after the other (the native projector releases the GIL,
    so threads run shards in parallel), the first successes kept.

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold is then out of reach of the joint limits, or nearly so."""
    robot, solver = _solver(shard)
    rng = shard_rng(shard.seed, shard.index)
    chunk = min(CHUNK, shard.count)
    kept: list[NDArray[np.float64]] = []
    count = tried = 0
    while count < shard.count:
        qs = robot.random_configurations(chunk, rng)
        for a in range(0, chunk, PIECE):  # rows are projected independently: pieces change no result
            if stopping():
                raise KeyboardInterrupt(f"shard {shard.index}: the run was interrupted")
            res = solver.solve_batch(qs[a:a + PIECE], parallel=False)
            good = res.q[res.success]
            kept.append(good)
            count += len(good)
        tried += chunk
        if tried >= 10 * chunk and count < 0.01 * tried:
            raise GenplanError(f"{robot.name}: only {count} of {tried} uniform samples project onto the manifold of "
                               f"task '{solver.task.name}': is it reachable within the joint limits?")
    return np.ascontiguousarray(np.concatenate(kept)[:shard.count])


def generate(robot: Robot, n: int, seed: int = 0, task: P.Task | None = None, *, shard_size: int = SHARD_SIZE,
             executor: Executor | None = None, progress: bool = True) -> NDArray[np.float64]:
    """The data set of ``n`` configurations (not cached), its shards on ``executor`` (default:
    threads, one per core)."""
    parts = shards(robot, n, seed, task, shard_size)
    ex = executor or LocalExecutor()
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
                         executor: Executor | None = None) -> NDArray[np.float64]:
    """``n`` configurations on the manifold of ``task`` (default: the robot's shipped
    ``<robot>_ik``; see :func:`genplan.projection.manifold_task`), shape (n, nq), reproducible:
    :func:`generate`, cached. The same array as ``genplan data`` writes for the same seed and
    shard size (:func:`read_dataset`).

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold is then out of reach of the joint limits, or nearly so."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    _check_in_memory(robot, n)
    path = cache_path(robot, n, seed, task, shard_size)
    cached = load_array(path, (n, robot.nq)) if use_cache else None
    if cached is not None:
        bad = _outside_limits(robot, cached)
        if not bad:
            return cached
        warnings.warn(f"{path}: {bad}, which the data set never holds (the file and its hash were changed after "
                      "they were written); regenerating it", RuntimeWarning, stacklevel=2)
    data = generate(robot, n, seed, task, shard_size=shard_size, executor=executor, progress=progress)
    if use_cache:
        save_array(path, data)
    return data


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
    return f"shard_{index:05d}.npy"


def _same(a: Any, b: Any) -> bool:
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def dataset_sha256(parts: Iterable[NDArray[np.float64]]) -> str:
    """The sha256 of a data set: of its configurations' float64 bytes, row after row (the same as
    ``hashlib.sha256(np.ascontiguousarray(data, np.float64).tobytes())`` of the whole array).
    ``parts`` may be any iterable (a generator reading one shard at a time)."""
    h = hashlib.sha256()
    for a in parts:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


# -- the folder's lock


def _process_start(pid: int) -> str | None:
    """When process ``pid`` started (Linux: /proc/PID/stat, in clock ticks since boot), or None
    where that cannot be read: told apart from a later process given the same pid."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return stat.rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError, ValueError):
        return None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` (>= 1) of this host runs."""
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # OverflowError: no process has such a pid
        return False
    except PermissionError:
        return True  # another user's process
    except OSError:
        return True  # cannot tell: assume it runs
    return True


class FolderLock:
    """A data set folder's lock (:data:`LOCK`), held by one run while it writes there.

    The lock file is created whole or not at all (written under a temporary name, then hard-linked
    to :data:`LOCK`, which fails when one exists: also on NFS) and holds the run's id, host, pid,
    the pid's start time, when it started and its command. A second run is refused with a
    GenplanError naming the first (host, pid, start). A lock of this host whose process is gone
    (its pid not running, or running a process started later) is taken over with a message;
    ``force`` takes any lock (a run on another host cannot be checked from here: Ray nodes,
    shared file systems). :meth:`release` removes the lock only while it is still this run's."""

    def __init__(self, folder: Path, *, force: bool = False, log: Callable[[str], Any] = print) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK
        self.force = force
        self.log = log
        pid = os.getpid()
        self.record = {"run": secrets.token_hex(8), "host": socket.gethostname(), "pid": pid,
                       "pid_start": _process_start(pid),
                       "started": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                       "command": " ".join(sys.argv)[:500]}
        self.held = False

    def __enter__(self) -> "FolderLock":
        self.acquire()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()

    def _create(self) -> bool:
        """Create the lock file holding this run's record; False when one exists."""
        tmp = self.folder / f".{LOCK}.{self.record['run']}.tmp"
        try:
            tmp.write_text(json.dumps(self.record, indent=1) + "\n")
            try:
                os.link(tmp, self.path)
            except FileExistsError:
                return False
            except OSError:  # a file system without hard links: an exclusive create
                try:
                    fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
                except FileExistsError:
                    return False
                with os.fdopen(fd, "w") as f:
                    f.write(tmp.read_text())
            return True
        finally:
            tmp.unlink(missing_ok=True)

    def _read(self) -> tuple[dict[str, Any] | None, bytes | None, str]:
        """(the lock's record, its bytes, why it is not a lock genplan wrote ("" when it is));
        (None, None, "") when it vanished."""
        try:
            raw = self.path.read_bytes()
        except FileNotFoundError:
            return None, None, ""
        except OSError as exc:
            return None, b"", str(exc.strerror or exc)
        try:
            rec = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            return None, raw, f"not JSON: {exc}"
        fields = {"run": str, "host": str, "started": str, "pid": int}
        if (not isinstance(rec, dict) or any(not isinstance(rec.get(k), t) or isinstance(rec.get(k), bool)
                                             for k, t in fields.items())
                or rec["pid"] < 1 or not isinstance(rec.get("pid_start"), (str, type(None)))):
            return None, raw, f"expected the fields {', '.join(fields)} (pid >= 1)"
        return rec, raw, ""

    def _gone(self, rec: dict[str, Any]) -> str:
        """Why the lock's run is known to be gone ("" when it may still run)."""
        if rec["host"] != self.record["host"]:
            return ""
        pid = rec["pid"]
        if not _alive(pid):
            return f"its process {pid} is gone"
        start = rec.get("pid_start")
        if start is not None and _process_start(pid) not in (None, start):
            return f"its process {pid} is gone (the pid now runs another process)"
        return ""

    def _take_over(self, raw: bytes) -> None:
        """Remove the lock file if it still holds ``raw``: renamed away first (only one run wins
        a rename), and put back if it was another run's newer lock."""
        grabbed = self.folder / f".{LOCK}.{self.record['run']}.old"
        try:
            os.rename(self.path, grabbed)
        except FileNotFoundError:
            return
        try:
            if grabbed.read_bytes() != raw:
                try:
                    os.link(grabbed, self.path)
                except OSError:
                    pass
        finally:
            grabbed.unlink(missing_ok=True)

    def acquire(self) -> None:
        for _ in range(5):
            if self._create():
                self.held = True
                return
            rec, raw, problem = self._read()
            if raw is None:
                continue  # released meanwhile: try again
            if problem:
                if not self.force:
                    raise GenplanError(f"{self.path}: not a genplan lock file ({problem}): if no run is writing "
                                       f"{self.folder}, remove it or rerun with --force (force=True)")
                self.log(f"taking over the unreadable lock file {self.path} (--force)")
                self._take_over(raw)
                continue
            assert rec is not None
            who = f"host {rec['host']}, pid {rec['pid']}, started {rec['started']}"
            gone = self._gone(rec)
            if not gone and not self.force:
                here = rec["host"] == self.record["host"]
                raise GenplanError(f"{self.folder} is being written by another run ({who}): "
                                   + ("wait for it to finish or give another folder (--force takes the folder "
                                      "even so)" if here else "if that run is gone, rerun with --force (force=True)"))
            self.log(f"taking over the lock of run {rec['run']} ({who}): {gone or 'forced'}")
            self._take_over(raw)
        raise GenplanError(f"{self.path}: other runs keep taking the lock; give another folder")

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        rec, _, _ = self._read()
        if rec is not None and rec.get("run") == self.record["run"]:
            self.path.unlink(missing_ok=True)


# -- data sets on disk


def _read_manifest(path: Path) -> dict[str, Any]:
    """A data set's manifest as JSON data, or GenplanError naming ``path`` when it is not one
    genplan wrote (unreadable, not JSON, no ``genplan-dataset/`` format)."""
    try:
        m = json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise GenplanError(f"{path}: not a readable data set manifest ({exc}); remove it or give another "
                           "folder") from None
    if not isinstance(m, dict) or not str(m.get("format", "")).startswith("genplan-dataset/"):
        raise GenplanError(f"{path}: not a genplan data set manifest (no format 'genplan-dataset/...'); remove it or "
                           "give another folder")
    return m


def _record(m: Mapping[str, Any], key: str) -> dict[str, Any]:
    value = m.get(key)
    return value if isinstance(value, dict) else {}


def _differences(old: Mapping[str, Any], header: Mapping[str, Any]) -> list[str]:
    """What makes the data set of manifest ``old`` another than the one of ``header``."""
    keys = ("format", "genplan_version", "nq", "data_size", "seed", "shard_size", "chunk", "manifold")
    diffs = [f"{k} {json.dumps(old.get(k), default=str)[:80]} there, {json.dumps(header[k])[:80]} here" for k in keys
             if not _same(old.get(k), header[k])]
    theirs, mine = _record(old, "robot"), header["robot"]
    if theirs.get("sha256") != mine["sha256"]:
        diffs.insert(0, f"robot '{theirs.get('name')}' (sha256 {str(theirs.get('sha256'))[:12]}) there, "
                        f"'{mine['name']}' (sha256 {mine['sha256'][:12]}) here")
    return diffs


def _remove_dataset(out: Path, log: Callable[[str], Any]) -> None:
    """Remove the files genplan wrote in ``out`` (manifest, shards, their temporary files), and
    nothing else."""
    gone = [f for f in out.iterdir() if f.is_file() and _OWN_FILES.fullmatch(f.name)]
    for f in sorted(gone):
        f.unlink(missing_ok=True)
    log(f"overwriting {out}: removed its manifest and {sum(f.suffix == '.npy' for f in gone)} shard files")


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
    path = out / MANIFEST
    created = missing_folders(out)
    out.mkdir(parents=True, exist_ok=True)
    lock = FolderLock(out, force=force, log=log)
    try:
        lock.acquire()
    except BaseException:
        remove_empty_folders(created)
        raise
    try:
        return _write(out, robot, parts, header, executor, progress, log, overwrite)
    finally:
        lock.release()
        remove_empty_folders(created)  # the folders this run made, when it wrote nothing there


def _write(out: Path, robot: Robot, parts: list[Shard], header: dict[str, Any], executor: Executor | None,
           progress: bool, log: Callable[[str], Any], overwrite: bool) -> dict[str, Any]:
    """:func:`write_dataset`'s work, the folder locked."""
    path = out / MANIFEST
    done: dict[int, dict[str, Any]] = {}
    listed = False  # whether the folder holds a manifest of this data set
    if path.exists():
        old = _read_manifest(path)
        diffs = _differences(old, header)
        if diffs and not overwrite:
            raise GenplanError(f"{out} holds another data set ({'; '.join(diffs)}): give another folder, or "
                               "--overwrite to replace it (overwrite=True)")
        if diffs:
            _remove_dataset(out, log)
        else:
            listed = True
            bad = 0
            records = old.get("shards")
            for rec in records if isinstance(records, list) else []:
                rec = rec if isinstance(rec, dict) else {}
                i, f = rec.get("index"), out / str(rec.get("file"))
                if (type(i) is int and 0 <= i < len(parts) and f.name == _shard_file(i) and f.is_file()
                        and sha256_file(f) == rec.get("sha256") and _is_shard(f, parts[i].count, robot.nq)):
                    done[i] = rec
                else:
                    bad += 1
            log(f"resuming {out}: {len(done)} of {len(parts)} shards finished and verified"
                + (f", {bad} listed but missing or not matching their sha256 (recomputed)" if bad else ""))
    elif overwrite and any(_OWN_FILES.fullmatch(f.name) for f in out.iterdir()):
        _remove_dataset(out, log)
    todo = [s for s in parts if s.index not in done]
    seed = header["seed"]
    last = [0.0]

    def manifest(complete: bool, digest: str | None = None) -> dict[str, Any]:
        return {**header, "complete": complete, "shards_done": len(done), "shards_total": len(parts),
                "sha256": digest, "shards": [done[i] for i in sorted(done)]}

    def finished(k: int, data: NDArray[np.float64]) -> None:
        i = todo[k].index  # k: the position in todo
        digest = write_npy(out / _shard_file(i), data)
        done[i] = {"index": i, "file": _shard_file(i), "count": int(len(data)), "seed": [seed, i], "sha256": digest}
        if time.monotonic() - last[0] > 1.0:
            write_text(path, json.dumps(manifest(False), indent=1))
            last[0] = time.monotonic()

    ex = executor or LocalExecutor()
    t0 = time.perf_counter()
    try:
        if todo:
            ex.map(project_shard, todo, desc=f"{robot.name} data", progress=progress, on_result=finished,
                   weights=[s.count for s in todo], unit="q")
    finally:
        if executor is None:
            ex.close()
        if len(done) < len(parts) and (done or listed):
            try:  # what finished, for a rerun; the run's own error is the one raised
                write_text(path, json.dumps(manifest(False), indent=1))
            except OSError:
                pass
    seconds = time.perf_counter() - t0
    digest = dataset_sha256(read_npy(out / done[i]["file"]) for i in sorted(done))
    result = manifest(True, digest)
    result["last_run"] = {**ex.describe(), "shards_computed": len(todo), "seconds": seconds}
    write_text(path, json.dumps(result, indent=1))
    return result


def read_dataset(folder: Path, robot: Robot | None = None, task: P.Task | None = None) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """The configurations of the data set in ``folder`` (its shards in order) and its manifest,
    every shard and the whole set checked against the manifest's sha256. Given ``robot`` (and
    ``task``: default the robot's ``<robot>_ik``), the data set must have been made for them
    (the robot's files and the task's manifold), else GenplanError naming both."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        raise FileNotFoundError(f"{folder}: no {MANIFEST} (a data set is written by `genplan data`)")
    m = _read_manifest(path)
    if m.get("format") != FORMAT:
        raise GenplanError(f"{path}: format {m.get('format')!r}, expected {FORMAT!r}")
    if not m.get("complete"):
        raise GenplanError(f"{folder}: an unfinished data set ({m.get('shards_done')} of {m.get('shards_total')} "
                           "shards): rerun the `genplan data` command to finish it")
    records = m.get("shards")
    size = m.get("data_size")
    if (not isinstance(records, list) or not all(isinstance(r, dict) and type(r.get("index")) is int
                                                 and isinstance(r.get("sha256"), str) for r in records)
            or type(size) is not int or size < 1 or type(m.get("nq")) is not int):
        raise GenplanError(f"{path}: not a data set manifest (its shards or data_size are malformed)")
    records = sorted(records, key=lambda r: r["index"])
    if [r["index"] for r in records] != list(range(len(records))) or any(r.get("file") != _shard_file(r["index"])
                                                                         for r in records):
        raise GenplanError(f"{path}: its shards are not shard_00000.npy, shard_00001.npy, ... in order")
    if robot is not None:
        mine = robot_record(robot)
        theirs = _record(m, "robot")
        if theirs.get("sha256") != mine["sha256"]:
            raise GenplanError(f"{folder} was made for robot '{theirs.get('name')}' (sha256 {str(theirs.get('sha256'))[:12]}), "
                               f"this run's robot is '{robot.name}' (sha256 {mine['sha256'][:12]}): its files or "
                               "description differ")
        manifold = _task(robot, task).to_dict()
        if not _same(m.get("manifold"), manifold):
            run_name = _run_task(robot, task).name
            raise GenplanError(f"{folder} was made for task '{_record(m, 'task').get('name')}' (manifold "
                               f"'{_record(m, 'manifold').get('name')}'), this run's task is '{run_name}' (manifold "
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
