"""Two builds of genplan plan the same Table II queries alternately, for a before/after of a
native change on plan times (one `genplan bench plan` run after the other drifts with the
machine's load by more than most changes: Table II times move 15-35 % while the counts stay).

    python benches/plan_ab.py --before /tmp/old_py --env talos_task1 talos_task2 \
        --sampler gan uniform --algorithm rrt_connect crrt --queries 100 --seed 0 --rounds 3 \
        --out benches/results/plan_ab_F.json

``--before``: a folder holding the "before" build's ``genplan`` package (``git archive <rev>``,
``maturin build --release``, the wheel's ``genplan/_core.abi3.so`` copied into a copy of
python/genplan); "after" is the installed package. The queries are drawn once, by the installed
package (as `genplan bench plan` draws them: same seed, same queries), and planned by each build in
a subprocess of its own, the builds' order alternating per round, every row with the table's
settings and planner seed. Prints and writes per row the median over rounds of the mean plan time
and projector time for each build, their ratio, and whether both builds gave the same
extension and projection counts (a change that only speeds things up keeps them).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

SAMPLERS = ("uniform", "gan", "hybrid")
ALGORITHMS = ("crrt", "rrt_connect")


def worker(args: argparse.Namespace) -> None:
    """Plan the saved queries of one environment with every sampler and algorithm asked for;
    print the rows as JSON (run in a subprocess, with the build under test first on the path)."""
    import genplan
    from genplan.experiments.benchmarks.plan import run_genplan
    from genplan.planning import PlannerSettings
    from genplan.planning.environments import Query

    data = np.load(args.worker)
    queries = [Query(start=s, goals=g, start_target=np.zeros(0), goal_target=np.zeros(0))
               for s, g in zip(data["starts"], data["goals"])]
    rows = []
    for alg in args.algorithm:
        for s in args.sampler:
            row = run_genplan(args.env[0], s, queries, args.seed, PlannerSettings(), False, alg)
            row["package"] = str(Path(genplan.__file__).parent)
            rows.append(row)
    print(json.dumps(rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", help="folder holding the before build's genplan package")
    parser.add_argument("--env", nargs="+", default=["talos_task1", "talos_task2"])
    parser.add_argument("--sampler", nargs="+", default=["gan"], choices=SAMPLERS)
    parser.add_argument("--algorithm", nargs="+", default=["rrt_connect"], choices=ALGORITHMS)
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", help="also write the JSON here")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args)
        return
    if not args.before or not (Path(args.before) / "genplan" / "__init__.py").is_file():
        parser.error(f"--before: expected a folder holding a genplan package, got {args.before!r}")
    if args.rounds < 1 or args.queries < 1:
        parser.error("--rounds and --queries must be at least 1")

    import genplan
    from genplan.experiments.common import machine, write_json
    from genplan.planning import environment

    load_start = os.getloadavg()
    runs: dict[tuple[str, str, str, str], list[dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for env_name in args.env:
            env = environment(env_name)
            robot = genplan.load(env.robot)
            queries = env.queries(robot, args.queries, seed=args.seed, progress=True)
            qfile = Path(tmp) / f"{env_name}.npz"
            np.savez(qfile, starts=np.stack([q.start for q in queries]), goals=np.stack([q.goals for q in queries]))
            for r in range(args.rounds):
                order = ["before", "after"] if r % 2 == 0 else ["after", "before"]
                for side in order:
                    env_vars = dict(os.environ)
                    if side == "before":
                        env_vars["PYTHONPATH"] = os.pathsep.join(filter(None, [args.before, env_vars.get("PYTHONPATH")]))
                    cmd = [sys.executable, __file__, "--worker", str(qfile), "--env", env_name, "--seed", str(args.seed),
                           "--sampler", *args.sampler, "--algorithm", *args.algorithm]
                    proc = subprocess.run(cmd, env=env_vars, capture_output=True, text=True)
                    if proc.returncode != 0:
                        raise SystemExit(f"the {side} build failed on {env_name} (exit {proc.returncode}):\n"
                                         + proc.stderr[-2000:])
                    out = proc.stdout
                    for row in json.loads(out.strip().splitlines()[-1]):
                        runs.setdefault((env_name, row["sampler"], row["algorithm"], side), []).append(row)
                    print(f"{env_name} round {r + 1}/{args.rounds} {side}: done", file=sys.stderr)
                if r == 0:
                    # after the first round, not after all of them: a --before the interpreter
                    # does not import from is refused before the remaining rounds run
                    imported = {side: rs[0]["package"] for (e, _, _, side), rs in runs.items() if e == env_name}
                    if imported["before"] == imported["after"]:
                        raise SystemExit(f"--before: both builds imported genplan from {imported['after']}")
    rows = []
    for env_name in args.env:
        for alg in args.algorithm:
            for s in args.sampler:
                b, a = runs[(env_name, s, alg, "before")], runs[(env_name, s, alg, "after")]
                med = lambda rs, k: statistics.median(x[k] for x in rs)  # noqa: E731
                same = all(x[k] == y[k] for x in b for y in a for k in ("extensions", "projections", "edge_projections"))
                row = {
                    "env": env_name, "sampler": s, "algorithm": alg,
                    "t_ave_s": {"before": med(b, "t_ave_s"), "after": med(a, "t_ave_s")},
                    "projector_s": {"before": med(b, "projector_s"), "after": med(a, "projector_s")},
                    "checker_s": {"before": med(b, "checker_s"), "after": med(a, "checker_s")},
                    "success_rate": {"before": b[0]["success_rate"], "after": a[0]["success_rate"]},
                    "extensions": {"before": b[0]["extensions"], "after": a[0]["extensions"]},
                    "projections": {"before": b[0]["projections"], "after": a[0]["projections"]},
                    "same_counts": same,
                    "t_ave_s_rounds": {"before": [x["t_ave_s"] for x in b], "after": [x["t_ave_s"] for x in a]},
                    "packages": {"before": b[0]["package"], "after": a[0]["package"]},
                }
                row["t_ratio_before_over_after"] = row["t_ave_s"]["before"] / row["t_ave_s"]["after"]
                row["projector_ratio_before_over_after"] = row["projector_s"]["before"] / row["projector_s"]["after"]
                rows.append(row)
                print(f"{env_name:12s} {alg:11s} {s:8s} t {row['t_ave_s']['before'] * 1e3:7.1f} -> "
                      f"{row['t_ave_s']['after'] * 1e3:7.1f} ms ({row['t_ratio_before_over_after']:.2f}x), projector "
                      f"{row['projector_s']['before'] * 1e3:7.1f} -> {row['projector_s']['after'] * 1e3:7.1f} ms "
                      f"({row['projector_ratio_before_over_after']:.2f}x), same counts: {same}")
    payload = {
        "benchmark": "plan_ab",
        "queries": args.queries,
        "seed": args.seed,
        "rounds": args.rounds,
        "rows": rows,
        "load_average_1min_start_end": [load_start[0], os.getloadavg()[0]],
        "machine": machine(),
        "command": "python benches/plan_ab.py --before BEFORE --env " + " ".join(args.env) + " --sampler "
                   + " ".join(args.sampler) + " --algorithm " + " ".join(args.algorithm)
                   + f" --queries {args.queries} --seed {args.seed} --rounds {args.rounds}",
    }
    if args.out:
        write_json(Path(args.out), payload)


if __name__ == "__main__":
    main()
