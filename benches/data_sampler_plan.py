"""How much can a sampler that covers the manifold gain? ([sampler]: the 2.6x target) The learned
samplers are trained on valid configurations made by projecting uniform random configurations
onto the manifold (genplan.samplers.data), so a sampler matching its data perfectly draws what the
planner's uniform sampler draws after projecting, with less projection work. This bench plans
with that ideal, the data set itself ("data": each sample a random row of the 25,000 training
configurations, already on the manifold) and "data_box" (the same, only the rows whose target
frame lies in the box the shipped GAN draws its targets from when planning: the data conditioned
as the GAN is), beside uniform, the shipped GAN and, with --model, a
learned sampler's file, on the Table II queries of each environment, under the paper's protocol
(tree nodes checked) and with edges checked, the paper's cRRT; the samplers alternate query by
query.

    python benches/data_sampler_plan.py --queries 100 --seed 0 --model talos=models/talos_flow.safetensors \
        --out benches/results/data_sampler_plan.json

Prints and writes, per environment, protocol and sampler: success %, mean extensions, mean
projection steps and mean plan time; uniform time / sampler time and, per sampler and protocol,
the geometric mean over the environments. The data samplers are the library's
(genplan.planning.data_sampler, native). Extensions and projections are
deterministic for a seed; times vary with the machine's load (recorded).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

import genplan
from genplan.experiments.benchmarks.plan import model_option
from genplan.experiments.common import machine, write_json
from genplan.samplers.loading import load_sampler_model
from genplan.planning import ENVIRONMENT_NAMES, Planner, data_sampler, environment

from adaptive_half_life import PROTOCOLS, record, summarize  # benches/: run as python benches/<script>.py


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", nargs="+", default=list(ENVIRONMENT_NAMES), choices=list(ENVIRONMENT_NAMES))
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0, help="the queries' and the planners' seed")
    parser.add_argument("--model", type=model_option, action="append", default=None, metavar="ROBOT=FILE",
                        help="also plan with this learned sampler's file for ROBOT's environments (row 'model')")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.queries < 1:
        parser.error("--queries must be positive")
    models = dict(args.model or [])
    rows: list[dict[str, Any]] = []
    loads = [os.getloadavg()[0]]
    boxed: dict[str, int] = {}
    for env_name in args.env:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        world = env.world(robot)
        queries = env.queries(robot, n=args.queries, seed=args.seed)
        for protocol, settings in PROTOCOLS:
            # the shipped samplers' training data (25,000 rows, seed 0), all of it, and the rows whose
            # target frame lies in the box the shipped GAN draws its targets from when planning
            everything = data_sampler(robot, in_box=False, seed=args.seed, progress=True)
            in_box = data_sampler(robot, seed=args.seed)
            boxed[env_name] = len(in_box)
            kinds: dict[str, Any] = {"uniform": "uniform", "gan": "gan", "data": everything, "data_box": in_box}
            planners = {k: Planner(robot, world=world, sampler=s, settings=settings, seed=args.seed)
                        for k, s in kinds.items()}
            if robot.name in models:
                planners["model"] = Planner(robot, world=world, sampler="gan", settings=settings, seed=args.seed,
                                            gan_model=load_sampler_model(robot, models[robot.name]))
            results: dict[str, list[Any]] = {k: [] for k in planners}
            for q in queries:
                for label, planner in planners.items():
                    results[label].append(planner.plan(q.start, q.goals))
            by = {label: record(rows, res, env=env_name, protocol=protocol, sampler=label)
                  for label, res in results.items()}
            for row in by.values():
                row["uniform_over_this"] = by["uniform"]["t_ave_s"] / row["t_ave_s"]
        loads.append(os.getloadavg()[0])
    labels = ["uniform", "gan", "data", "data_box"]
    summary = summarize(rows, labels, args.env)
    if models:
        with_model = [e for e in args.env if environment(e).robot in models]
        summary.update({f"{k} ({', '.join(with_model)})": v
                        for k, v in summarize(rows, ["model"], with_model).items()})
    write_json(args.out, {
        "benchmark": "data_sampler_plan", "envs": args.env, "queries": args.queries, "seed": args.seed,
        "models": models, "data": "valid_configurations(robot, 25000, seed 0): the shipped samplers' training data",
        "data_box_rows": boxed,
        "load_average_1min_per_env": loads, "machine": machine(), "rows": rows, "summary": summary,
        "command": "python benches/data_sampler_plan.py " + " ".join(
            [f"--env {' '.join(args.env)}", f"--queries {args.queries}", f"--seed {args.seed}",
             *(f"--model {r}={f}" for r, f in models.items())]),
    })


if __name__ == "__main__":
    main()
