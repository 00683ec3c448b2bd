"""What certified edges cost ([planner] item 3): the same queries planned with
``edge_check="sampled"`` (states at 0.025 rad checked, the default) and ``"certified"`` (every motion
between those states certified collision-free by conservative advancement, states added where a
chord cannot be), interleaved query by query so that both see the same load.

    python benches/certified_edges.py --queries 30 --seed 0 --out benches/results/certified_edges.json

Per environment (the paper's four), sampler and edge check: success %, median and mean plan time,
median time in the checker and the projector, median path states and motion certificates; the
summary is each environment's ratio of median plan times (certified / sampled). The planner
seed is the same for both checks, so the searches differ only where a certificate refuses an
edge that the sampled check accepts (or the reverse).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

import genplan
from genplan.experiments.common import machine, write_json
from genplan.planning import ENVIRONMENT_NAMES, Planner, PlannerSettings, environment

CHECKS = ("sampled", "certified")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--queries", type=int, default=30)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--env", default="all", choices=[*ENVIRONMENT_NAMES, "all"])
    p.add_argument("--sampler", default="gan")
    p.add_argument("--algorithm", default="rrt_connect")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    envs = list(ENVIRONMENT_NAMES) if args.env == "all" else [args.env]
    rows: list[dict[str, Any]] = []
    summary: dict[str, float] = {}
    t_start = time.time()
    for env_name in envs:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        world = env.world(robot)
        queries = env.queries(robot, n=args.queries, seed=args.seed)
        planners = {c: Planner(robot, world=world, sampler=args.sampler, seed=args.seed,
                               settings=PlannerSettings(edge_check=c, algorithm=args.algorithm)) for c in CHECKS}
        rec: dict[str, list[dict[str, float]]] = {c: [] for c in CHECKS}
        for q in tqdm(queries, desc=env_name, unit="query", leave=False):
            for c in CHECKS:
                r = planners[c].plan(q.start, q.goals)
                st = r.stats
                rec[c].append(dict(success=float(r.success), time_s=st.time_s, checker_s=st.checker_s,
                                   projector_s=st.projector_s, path_states=float(len(r.path)),
                                   motion_certificates=float(st.motion_certificates)))
        for c in CHECKS:
            xs = rec[c]
            col = lambda k: np.array([x[k] for x in xs])  # noqa: E731
            ok = col("success") > 0
            rows.append(dict(env=env_name, sampler=args.sampler, algorithm=args.algorithm, edge_check=c,
                             queries=len(xs), success_rate=100.0 * ok.mean(),
                             t_median_s=float(np.median(col("time_s"))), t_ave_s=float(col("time_s").mean()),
                             checker_median_s=float(np.median(col("checker_s"))),
                             projector_median_s=float(np.median(col("projector_s"))),
                             path_states_median=float(np.median(col("path_states")[ok])) if ok.any() else None,
                             motion_certificates_median=float(np.median(col("motion_certificates")))))
        by = {r["edge_check"]: r for r in rows if r["env"] == env_name}
        summary[env_name] = by["certified"]["t_median_s"] / by["sampled"]["t_median_s"]
    print(f"{'env':<12} {'check':<10} {'ok %':>6} {'T med s':>9} {'checker s':>10} {'proj s':>8} {'states':>7} {'certs':>6}")
    for r in rows:
        print(f"{r['env']:<12} {r['edge_check']:<10} {r['success_rate']:6.1f} {r['t_median_s']:9.4f} "
              f"{r['checker_median_s']:10.4f} {r['projector_median_s']:8.4f} {r['path_states_median'] or 0:7.0f} "
              f"{r['motion_certificates_median']:6.0f}")
    for env_name, ratio in summary.items():
        print(f"{env_name}: certified / sampled median plan time {ratio:.2f}x")
    payload = dict(benchmark="certified_edges", queries=args.queries, seed=args.seed, sampler=args.sampler,
                   algorithm=args.algorithm, rows=rows, certified_over_sampled_median_time=summary,
                   wall_s=time.time() - t_start, load_1min=os.getloadavg()[0], machine=machine())
    write_json(args.out, payload)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
