"""Training data: configurations on a task's constraint manifold.

Uniform samples within the joint limits, projected onto the task's manifold (the task without
its condition term, or the task its [condition] names: for the paper's robots, the projection
task: Panda gripper horizontal; Talos feet fixed, static stability, left arm at its default);
successes are kept until ``n`` are collected. Seeded, cached on disk (``$GENPLAN_CACHE`` or
``~/.cache/genplan``), batched on all cores by the native projector, with a progress bar.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan import projection as P
from genplan.cache import cache_dir, load_array, save_array
from genplan.errors import GenplanError, SettingsError
from genplan.robots import Robot

CHUNK = 2000


def _task(robot: Robot, task: P.Task | None) -> P.Task:
    from genplan.gan.costs import default_task_name, manifold_task

    return manifold_task(P.load_task(default_task_name(robot), robot) if task is None else task, robot)


def _key(robot: Robot, n: int, seed: int, manifold: P.Task) -> str:
    desc = json.dumps({"robot": robot.name, "n": n, "seed": seed, "version": _core.__version__,
                       "terms": [t.to_native(robot) for t in manifold.primary]}, sort_keys=True, default=str)
    return hashlib.sha256(desc.encode()).hexdigest()[:16]


def cache_path(robot: Robot, n: int, seed: int, task: P.Task | None = None) -> Path:
    """Where :func:`valid_configurations` caches its result."""
    return cache_dir() / "data" / f"{robot.name}_valid_{n}_{seed}_{_key(robot, n, seed, _task(robot, task))}.npy"


def valid_configurations(robot: Robot, n: int = 25_000, seed: int = 0, use_cache: bool = True,
                         progress: bool = True, task: P.Task | None = None) -> NDArray[np.float64]:
    """``n`` configurations on the manifold of ``task`` (default: the robot's shipped
    ``<robot>_ik``; see :func:`genplan.gan.costs.manifold_task`), shape (n, nq), reproducible.

    Raises GenplanError when fewer than 1 % of the projections succeed (after 10 chunks): the
    task's manifold is then out of reach of the joint limits, or nearly so."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    manifold = _task(robot, task)
    path = cache_path(robot, n, seed, task)
    cached = load_array(path, (n, robot.nq)) if use_cache else None
    if cached is not None:
        return cached
    solver = P.GaussNewtonProjector(robot, manifold)
    rng = np.random.default_rng(seed)
    kept: list[NDArray[np.float64]] = []
    count = tried = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc=f"{robot.name} data (projecting)", unit="q")
    while count < n:
        res = solver.solve_batch(robot.random_configurations(CHUNK, rng), parallel=True)
        tried += CHUNK
        good = res.q[res.success]
        kept.append(good)
        count += len(good)
        if bar is not None:
            bar.update(min(len(good), n - (count - len(good))))
        if tried >= 10 * CHUNK and count < 0.01 * tried:
            if bar is not None:
                bar.close()
            raise GenplanError(f"{robot.name}: only {count} of {tried} uniform samples project onto the manifold of "
                               f"task '{manifold.name}': is it reachable within the joint limits?")
    if bar is not None:
        bar.close()
    data = np.concatenate(kept)[:n]
    if use_cache:
        save_array(path, data)
    return data
