"""Which Table II queries fail, and are they solvable? ([planner]: success >= 99 % GAN, 100 %
hybrid) The Table II queries of one environment (seed 0 as the table), planned in the table's
order by every sampler and algorithm with the table's settings and planner seed, as
`genplan bench plan` plans them; then every query that failed anywhere, again with the hybrid
sampler and a larger extension budget (`--budget`, planner seed `--retry-seed`), each algorithm.

    python benches/hard_queries.py --env talos_task3 --queries 100 --seed 0 --budget 5000 \
        --out benches/results/hard_queries_talos_task3.json

Prints and writes: per sampler and algorithm the indices of the failed queries; per failed
query, success, extensions and time with the larger budget. The counts are deterministic for a
seed; the times vary with the machine's load.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import genplan
from genplan.experiments.common import write_json
from genplan.planning import ALGORITHMS, ENVIRONMENT_NAMES, Planner, PlannerSettings, environment

SAMPLERS = ("uniform", "gan", "hybrid")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="talos_task3", choices=list(ENVIRONMENT_NAMES))
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0, help="the queries' and the table's planner seed")
    parser.add_argument("--max-extensions", type=int, default=None,
                        help="max_extensions of the first pass (default: the table's, PlannerSettings())")
    parser.add_argument("--budget", type=int, default=5000, help="max_extensions of the second attempt")
    parser.add_argument("--retry-seed", type=int, default=1, help="planner seed of the second attempt")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.queries < 1 or args.budget < 1 or (args.max_extensions is not None and args.max_extensions < 1):
        parser.error("--queries, --max-extensions and --budget must be positive")
    env = environment(args.env)
    robot = genplan.load(env.robot)
    world = env.world(robot)
    queries = env.queries(robot, n=args.queries, seed=args.seed)
    table = PlannerSettings()
    if args.max_extensions is not None:
        table = table.replace(max_extensions=args.max_extensions)
    failed: dict[str, list[int]] = {}
    for algorithm in ALGORITHMS:
        for sampler in SAMPLERS:
            planner = Planner(robot, world=world, sampler=sampler, settings=table, seed=args.seed, algorithm=algorithm)
            bad = [i for i, q in enumerate(queries) if not planner.plan(q.start, q.goals).success]
            failed[f"{algorithm}/{sampler}"] = bad
            print(f"{algorithm:12s} {sampler:8s} failed: {bad}", flush=True)
    hard = sorted({i for bad in failed.values() for i in bad})
    larger = table.replace(max_extensions=args.budget)
    retried = []
    for i in hard:
        q = queries[i]
        for algorithm in ALGORITHMS:
            planner = Planner(robot, world=world, sampler="hybrid", settings=larger, seed=args.retry_seed, algorithm=algorithm)
            r = planner.plan(q.start, q.goals)
            retried.append({"query": i, "algorithm": algorithm, "success": bool(r.success),
                            "extensions": int(r.extensions), "time_s": float(r.time_s)})
            print(f"query {i} {algorithm:12s} hybrid, max_extensions {args.budget}: success {r.success}, "
                  f"{r.extensions} extensions, {r.time_s:.3f} s", flush=True)
    write_json(args.out, {
        "benchmark": "hard_queries", "env": args.env, "queries": args.queries, "seed": args.seed,
        "table_settings": {"max_extensions": table.max_extensions, "retries": table.retries},
        "failed": failed, "budget": args.budget, "retry_seed": args.retry_seed, "retried": retried,
        "command": "python benches/hard_queries.py " + " ".join(
            f"--{k.replace('_', '-')} {v}" for k, v in (("env", args.env), ("queries", args.queries), ("seed", args.seed),
                                                        ("budget", args.budget), ("retry_seed", args.retry_seed))),
    })


if __name__ == "__main__":
    main()
