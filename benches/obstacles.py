"""Collision checks and GAN plans as the scene grows: the Panda in the GAN paper's shelf scene
(``environment("panda_shelf")``) with 0 and with N extra random boxes out of the robot's reach.

    python benches/obstacles.py [--extra 200] [--n 10000] [--queries 20] [--repeats 5]
                                [--out benches/results/obstacles.json]

The extra boxes (seeded) have centres 1.6 to 3 m from the base horizontally, z in [-0.4, 1.6],
half extents 0.03 to 0.15 m and random rotations: the Panda reaches about 1.2 m from its base, so
they never change an answer (checked here: the same collision flags, the same plans). The figures:

* collision check: ``world.in_collision`` on n uniform random configurations in one batched call
  (the native batch, default threads), microseconds per configuration;
* GAN plan: ``Planner(panda, world=..., sampler="gan")`` on ``environment("panda_shelf")
  .queries(panda, n=20, seed=1)``, wall time per query (a fresh planner per repeat, seed 0).

The two scenes alternate within each repeat; medians of the repeats. The 1-minute load average is
recorded before and after (the machine may be shared). Prints the figures and the ratios (with /
without the extra boxes); writes JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

import genplan
from genplan.experiments.benchmarks.peers import add_extra_boxes  # the one definition
from genplan.planning import Planner
from genplan.planning.environments import environment

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--extra", type=int, default=200, help="extra boxes in the second scene")
    parser.add_argument("--n", type=int, default=10_000, help="configurations per collision batch")
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "obstacles.json")
    args = parser.parse_args()

    load_before = os.getloadavg()[0]
    panda = genplan.load("panda")
    env = environment("panda_shelf")
    worlds = {0: env.world(panda), args.extra: env.world(panda)}
    add_extra_boxes(worlds[args.extra], args.extra, args.seed + 11)
    qs = panda.random_configurations(args.n, args.seed)
    queries = env.queries(panda, n=args.queries, seed=1)

    check = {k: [] for k in worlds}
    plan = {k: [] for k in worlds}
    flags, outcomes = {}, {}
    for _ in range(args.repeats):
        for k, world in worlds.items():
            t0 = time.perf_counter()
            flags[k] = np.asarray(world.in_collision(qs))
            check[k].append((time.perf_counter() - t0) / args.n)
        for k, world in worlds.items():
            planner = Planner(panda, world=world, sampler="gan", seed=0)
            t0 = time.perf_counter()
            results = [planner.plan(q.start, q.goals) for q in queries]
            plan[k].append((time.perf_counter() - t0) / len(queries))
            outcomes[k] = [(r.success, len(r.path)) for r in results]
    load_after = os.getloadavg()[0]

    base, more = 0, args.extra
    if not np.array_equal(flags[base], flags[more]):
        raise SystemExit("the extra boxes changed a collision answer: they are not out of reach")
    entry = {
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "loadavg_1min_before": load_before, "loadavg_1min_after": load_after},
        "n_configurations": args.n, "queries": args.queries, "repeats": args.repeats,
        "extra_boxes": args.extra, "obstacles": {str(k): len(w.obstacle_names) for k, w in worlds.items()},
        "collision_fraction": float(flags[base].mean()),
        "same_plans": outcomes[base] == outcomes[more],
        "plan_success": {str(k): sum(s for s, _ in outcomes[k]) for k in worlds},
        "check_us_per_config": {str(k): statistics.median(v) * 1e6 for k, v in check.items()},
        "check_us_per_config_all": {str(k): [x * 1e6 for x in v] for k, v in check.items()},
        "plan_ms_per_query": {str(k): statistics.median(v) * 1e3 for k, v in plan.items()},
        "plan_ms_per_query_all": {str(k): [x * 1e3 for x in v] for k, v in plan.items()},
    }
    entry["check_ratio"] = entry["check_us_per_config"][str(more)] / entry["check_us_per_config"][str(base)]
    entry["plan_ratio"] = entry["plan_ms_per_query"][str(more)] / entry["plan_ms_per_query"][str(base)]
    for k in worlds:
        print(f"panda_shelf +{k:<4} obstacles {len(worlds[k].obstacle_names):4d}   "
              f"check {entry['check_us_per_config'][str(k)]:7.2f} us/config   "
              f"GAN plan {entry['plan_ms_per_query'][str(k)]:8.2f} ms/query   "
              f"solved {entry['plan_success'][str(k)]}/{args.queries}")
    print(f"ratio (+{more} / +0): check {entry['check_ratio']:.2f}x   plan {entry['plan_ratio']:.2f}x   "
          f"same plans: {entry['same_plans']}   load {load_before:.2f} -> {load_after:.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(entry, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
