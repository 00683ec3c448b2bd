"""What free space saves: the same free-space queries planned with no projector
in the loop (``Planner(robot, world, task="free")``) and with the projector of the same
JointLimits-only task in it (what such a task cost before free space was first-class: the native
projector of the task at a tenth of its tolerances, the chords held to the task's own), in
alternating rounds so that both see the same load.

    python benches/free_space_plan.py --queries 40 --rounds 5 --seed 0 --out benches/results/free_space_plan.json

Queries: pairs of collision-free uniform configurations of the Panda in the shelf environment
(seeded) whose straight edge is blocked (a clear one is joined directly in free space). Both arms call the native planner (``genplan._core.Planner.plan``) with the same
sampler seed per query, so they grow the same trees: a projector that has nothing to project
leaves every sample, step and edge state where it is (``same_path`` counts the queries whose
paths are equal to the last bit). Per algorithm: success, the median plan time of each arm
(``stats.time_s``, the core's own clock), the ratio of the medians (projected / free) and the
median of the per-query ratios, the projector's median share of the projected plans.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan import _core
from genplan import projection as P
from genplan.experiments.common import machine, write_json
from genplan.planning import ALGORITHMS, PlannerSettings, environment
from genplan.planning.queries import TOLERANCE_FACTOR

ARMS = ("free", "projected")


def queries(robot: genplan.Robot, world: Any, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` pairs (start, goal) of collision-free uniform configurations, the goal at least 1 rad
    from the start and the straight edge between them blocked: free space joins a goal in plain
    view by that edge before any search (the projected arm would grow a tree), so only blocked
    edges give both arms the same search to compare."""
    rng = np.random.default_rng(seed)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    step = PlannerSettings().edge_resolution
    while len(out) < n:
        q = robot.random_configurations(64, rng)
        q = q[~np.asarray(world.in_collision(q), dtype=bool)]
        for a, b in zip(q[0::2], q[1::2]):
            if len(out) >= n or np.linalg.norm(a - b) < 1.0:
                continue
            t = np.linspace(0.0, 1.0, int(np.ceil(np.max(np.abs(b - a)) / step)) + 1)[:, None]
            if np.asarray(world.in_collision(a + t * (b - a)), dtype=bool).any():
                out.append((a, b))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--queries", type=int, default=40)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--algorithms", default=",".join(ALGORITHMS))
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    algorithms = args.algorithms.split(",")
    robot = genplan.load("panda")
    world = environment("panda_shelf").world(robot)
    free = P.load_task("free", robot)
    projector = P.GaussNewtonProjector(robot, free.with_tolerances_scaled(TOLERANCE_FACTOR))
    chord_tolerance = 1.0 / TOLERANCE_FACTOR
    qs = queries(robot, world, args.queries, args.seed)
    load0 = os.getloadavg()
    t_start = time.time()
    rows: list[dict[str, Any]] = []
    for algorithm in algorithms:
        native = _core.Planner(robot.kinematics, PlannerSettings(algorithm=algorithm))
        rec: dict[str, list[list[float]]] = {a: [[] for _ in qs] for a in ARMS}
        share: list[float] = []
        ok = {a: 0 for a in ARMS}
        same = 0
        for r in range(args.rounds):
            for i, (start, goal) in enumerate(qs):
                results = {}
                # alternate which arm runs first, round by round and query by query
                order = ARMS if (r + i) % 2 == 0 else ARMS[::-1]
                for arm in order:
                    sampler = _core.UniformSampler(robot.kinematics, None, args.seed + i, None)
                    res = native.plan(list(map(float, start)), goal[None], sampler,
                                      None if arm == "free" else projector.native, world.native, False,
                                      None if arm == "free" else chord_tolerance)
                    results[arm] = res
                    rec[arm][i].append(res.stats.time_s)
                if r == 0:
                    for arm in ARMS:
                        ok[arm] += int(results[arm].success)
                    same += int(results["free"].success and results["projected"].success
                                and np.array_equal(results["free"].path, results["projected"].path))
                    assert results["free"].stats.projector_s == 0.0
                    if results["projected"].stats.time_s > 0:
                        share.append(results["projected"].stats.projector_s / results["projected"].stats.time_s)
        med = {a: float(np.median([t for ts in rec[a] for t in ts])) for a in ARMS}
        per_query = [np.median(rec["projected"][i]) / np.median(rec["free"][i]) for i in range(len(qs))]
        rows.append(dict(algorithm=algorithm, queries=len(qs), rounds=args.rounds,
                         success_free=ok["free"], success_projected=ok["projected"], same_path=same,
                         free_median_ms=1e3 * med["free"], projected_median_ms=1e3 * med["projected"],
                         ratio_of_medians=med["projected"] / med["free"],
                         median_per_query_ratio=float(np.median(per_query)),
                         projector_share_median=float(np.median(share)) if share else None))
    load1 = os.getloadavg()
    print(f"{'algorithm':<12} {'ok free':>8} {'ok proj':>8} {'same':>5} {'free ms':>8} {'proj ms':>8} {'ratio':>6} "
          f"{'q ratio':>8} {'proj share':>10}")
    for r in rows:
        print(f"{r['algorithm']:<12} {r['success_free']:>8} {r['success_projected']:>8} {r['same_path']:>5} "
              f"{r['free_median_ms']:8.3f} {r['projected_median_ms']:8.3f} {r['ratio_of_medians']:6.2f} "
              f"{r['median_per_query_ratio']:8.2f} {100 * (r['projector_share_median'] or 0):9.1f}%")
    print(f"load average (1 min) {load0[0]:.2f} at the start, {load1[0]:.2f} at the end")
    payload = dict(benchmark="free_space_plan", env="panda_shelf", queries=args.queries, rounds=args.rounds,
                   seed=args.seed, rows=rows, wall_s=time.time() - t_start, load_1min_start=load0[0],
                   load_1min_end=load1[0], machine=machine())
    write_json(args.out, payload)


if __name__ == "__main__":
    main()
