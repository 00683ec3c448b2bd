"""Training data: configurations on the constraint manifold.

Uniform samples within the joint limits, projected with the paper's projection task (Panda:
gripper horizontal; Talos: feet fixed, static stability, left arm at its default); successes are
kept until ``n`` are collected. Seeded, cached on disk (``$GENPLAN_CACHE`` or
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
from genplan.errors import SettingsError
from genplan.robots import Robot

CHUNK = 2000


def _key(robot: Robot, n: int, seed: int) -> str:
    task = P.paper_task(robot, "projection")
    desc = json.dumps({"robot": robot.name, "n": n, "seed": seed, "version": _core.__version__,
                       "terms": [t.to_native(robot) for t in task.primary]}, sort_keys=True, default=str)
    return hashlib.sha256(desc.encode()).hexdigest()[:16]


def cache_path(robot: Robot, n: int, seed: int) -> Path:
    """Where :func:`valid_configurations` caches its result."""
    return cache_dir() / "data" / f"{robot.name}_valid_{n}_{seed}_{_key(robot, n, seed)}.npy"


def valid_configurations(robot: Robot, n: int = 25_000, seed: int = 0, use_cache: bool = True,
                         progress: bool = True) -> NDArray[np.float64]:
    """``n`` configurations on ``robot``'s projection manifold (shape (n, nq)), reproducible."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    path = cache_path(robot, n, seed)
    cached = load_array(path, (n, robot.nq)) if use_cache else None
    if cached is not None:
        return cached
    solver = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection"))
    rng = np.random.default_rng(seed)
    kept: list[NDArray[np.float64]] = []
    count = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc=f"{robot.name} data (projecting)", unit="q")
    while count < n:
        res = solver.solve_batch(robot.random_configurations(CHUNK, rng), parallel=True)
        good = res.q[res.success]
        kept.append(good)
        count += len(good)
        if bar is not None:
            bar.update(min(len(good), n - (count - len(good))))
    if bar is not None:
        bar.close()
    data = np.concatenate(kept)[:n]
    if use_cache:
        save_array(path, data)
    return data
