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
  its verified shards (``genplan data``, ``genplan train gan --data``).
"""

from __future__ import annotations

import hashlib
import json
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan import projection as P
from genplan._files import atomic_path, write_text
from genplan.cache import cache_dir, load_array, save_array
from genplan.errors import GenplanError, SettingsError
from genplan.executor import Executor, LocalExecutor, chunks, shard_rng
from genplan.robots import Robot

#: uniform samples projected per call (fewer for a shard of fewer configurations)
CHUNK = 2000
#: configurations per shard (default)
SHARD_SIZE = 5000
#: the manifest's format
FORMAT = "genplan-dataset/1"
MANIFEST = "manifest.json"


def _task(robot: Robot, task: P.Task | None) -> P.Task:
    from genplan.gan.costs import default_task_name, manifold_task

    return manifold_task(P.load_task(default_task_name(robot), robot) if task is None else task, robot)


def _run_task(robot: Robot, task: P.Task | None) -> P.Task:
    from genplan.gan.costs import default_task_name

    return P.load_task(default_task_name(robot), robot) if task is None else task


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
        res = solver.solve_batch(robot.random_configurations(chunk, rng), parallel=False)
        tried += chunk
        good = res.q[res.success]
        kept.append(good)
        count += len(good)
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


def valid_configurations(robot: Robot, n: int = 25_000, seed: int = 0, use_cache: bool = True,
                         progress: bool = True, task: P.Task | None = None, *, shard_size: int = SHARD_SIZE,
                         executor: Executor | None = None) -> NDArray[np.float64]:
    """``n`` configurations on the manifold of ``task`` (default: the robot's shipped
    ``<robot>_ik``; see :func:`genplan.gan.costs.manifold_task`), shape (n, nq), reproducible:
    :func:`generate`, cached. The same array as ``genplan data`` writes for the same seed and
    shard size (:func:`read_dataset`).

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold is then out of reach of the joint limits, or nearly so."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    path = cache_path(robot, n, seed, task, shard_size)
    cached = load_array(path, (n, robot.nq)) if use_cache else None
    if cached is not None:
        return cached
    data = generate(robot, n, seed, task, shard_size=shard_size, executor=executor, progress=progress)
    if use_cache:
        save_array(path, data)
    return data


# -- data sets on disk


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def robot_record(robot: Robot) -> dict[str, Any]:
    """The robot as a manifest records it: its name, description, the sha256 of each of its
    files (robot file, URDF, collision URDF, SRDF), and ``sha256``: one hash of the name, the
    files' contents and the description's other fields (not its paths, so that a data set made
    on another machine matches)."""
    description = _plain(robot.description)
    files = {role: {"path": str(p), "sha256": _sha256_file(Path(p))}
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


def dataset_sha256(parts: list[NDArray[np.float64]]) -> str:
    """The sha256 of a data set: of its configurations' float64 bytes, row after row (the same as
    ``hashlib.sha256(np.ascontiguousarray(data, np.float64).tobytes())`` of the whole array)."""
    h = hashlib.sha256()
    for a in parts:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


def write_dataset(out: Path, robot: Robot, n: int, seed: int = 0, task: P.Task | None = None, *,
                  shard_size: int = SHARD_SIZE, executor: Executor | None = None, progress: bool = True,
                  log: Callable[[str], Any] = print) -> dict[str, Any]:
    """Write the data set of ``n`` configurations to the folder ``out`` (created if missing): its
    shards and ``manifest.json``; returns the manifest.

    Resumes: a shard the folder's manifest lists and whose file has the listed sha256 is kept;
    any other is (re)computed. The manifest is rewritten as shards finish (at most once a second)
    and when the run ends, failed or not, so an interrupted run keeps what it finished. A folder
    holding another data set (another robot, task, size, seed, shard size or genplan version) is
    refused (GenplanError naming the differences)."""
    out = Path(out)
    run_task = _run_task(robot, task)
    parts = shards(robot, n, seed, run_task, shard_size)
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
    done: dict[int, dict[str, Any]] = {}
    if path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise GenplanError(f"{path}: not a readable manifest ({exc}); remove it or give another folder") from None
        keys = ("format", "genplan_version", "nq", "data_size", "seed", "shard_size", "chunk", "manifold")
        diffs = [f"{k} {json.dumps(old.get(k))[:80]} there, {json.dumps(header[k])[:80]} here" for k in keys
                 if not _same(old.get(k), header[k])]
        if old.get("robot", {}).get("sha256") != header["robot"]["sha256"]:
            diffs.insert(0, f"robot '{old.get('robot', {}).get('name')}' (sha256 "
                            f"{str(old.get('robot', {}).get('sha256'))[:12]}) there, '{robot.name}' "
                            f"(sha256 {header['robot']['sha256'][:12]}) here")
        if diffs:
            raise GenplanError(f"{out} holds another data set ({'; '.join(diffs)}): give another folder or remove it")
        bad = 0
        for rec in old.get("shards", []):
            i, f = rec.get("index"), out / str(rec.get("file"))
            if isinstance(i, int) and 0 <= i < len(parts) and f.is_file() and _sha256_file(f) == rec.get("sha256"):
                done[i] = rec
            else:
                bad += 1
        log(f"resuming {out}: {len(done)} of {len(parts)} shards finished and verified"
            + (f", {bad} listed but missing or not matching their sha256 (recomputed)" if bad else ""))
    todo = [s for s in parts if s.index not in done]
    last = [0.0]

    def manifest(complete: bool, digest: str | None = None) -> dict[str, Any]:
        return {**header, "complete": complete, "shards_done": len(done), "shards_total": len(parts),
                "sha256": digest, "shards": [done[i] for i in sorted(done)]}

    def finished(k: int, data: NDArray[np.float64]) -> None:
        i = todo[k].index  # k: the position in todo
        with atomic_path(out / _shard_file(i)) as tmp:
            np.save(tmp, data)
        f = out / _shard_file(i)
        done[i] = {"index": i, "file": f.name, "count": int(len(data)), "seed": [seed, i],
                   "sha256": _sha256_file(f)}
        if time.monotonic() - last[0] > 1.0:
            write_text(path, json.dumps(manifest(False), indent=1))
            last[0] = time.monotonic()

    out.mkdir(parents=True, exist_ok=True)
    ex = executor or LocalExecutor()
    t0 = time.perf_counter()
    try:
        if todo:
            ex.map(project_shard, todo, desc=f"{robot.name} data", progress=progress, on_result=finished,
                   weights=[s.count for s in todo], unit="q")
    finally:
        if executor is None:
            ex.close()
        if len(done) < len(parts):
            write_text(path, json.dumps(manifest(False), indent=1))
    seconds = time.perf_counter() - t0
    digest = dataset_sha256([np.load(out / done[i]["file"], allow_pickle=False) for i in sorted(done)])
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
    try:
        m = json.loads(path.read_text())
        shards_ = sorted(m["shards"], key=lambda r: r["index"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise GenplanError(f"{path}: not a data set manifest ({exc})") from None
    if m.get("format") != FORMAT:
        raise GenplanError(f"{path}: format {m.get('format')!r}, expected {FORMAT!r}")
    if not m.get("complete"):
        raise GenplanError(f"{folder}: an unfinished data set ({m.get('shards_done')} of {m.get('shards_total')} "
                           "shards): rerun the `genplan data` command to finish it")
    if robot is not None:
        mine = robot_record(robot)
        theirs = m.get("robot", {})
        if theirs.get("sha256") != mine["sha256"]:
            raise GenplanError(f"{folder} was made for robot '{theirs.get('name')}' (sha256 {str(theirs.get('sha256'))[:12]}), "
                               f"this run's robot is '{robot.name}' (sha256 {mine['sha256'][:12]}): its files or "
                               "description differ")
        manifold = _task(robot, task).to_dict()
        if not _same(m.get("manifold"), manifold):
            run_name = _run_task(robot, task).name
            raise GenplanError(f"{folder} was made for task '{m.get('task', {}).get('name')}' (manifold "
                               f"'{m.get('manifold', {}).get('name')}'), this run's task is '{run_name}' (manifold "
                               f"'{manifold.get('name')}'): their manifolds differ")
    parts = []
    for rec in shards_:
        f = folder / rec["file"]
        if not f.is_file() or _sha256_file(f) != rec["sha256"]:
            raise GenplanError(f"{f}: missing or not matching the manifest's sha256: rerun `genplan data` to repair it")
        parts.append(np.load(f, allow_pickle=False))
    if [r["index"] for r in shards_] != list(range(len(shards_))) or sum(len(a) for a in parts) != m["data_size"]:
        raise GenplanError(f"{path}: shards do not add up to {m['data_size']} configurations")
    if dataset_sha256(parts) != m.get("sha256"):
        raise GenplanError(f"{folder}: the data set's sha256 does not match its manifest")
    return np.concatenate(parts), m
