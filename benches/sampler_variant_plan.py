"""Does a GAN that covers more of the manifold plan faster? ([sampler]: Table II with a coverage
variant) One environment, the Table II queries (seed 0), uniform vs the shipped GAN vs a GAN file
given with --model (e.g. trained with `genplan train gan --robot panda --seed 0 --w-diversity 1.0
--member-init data --out M`), under the paper's protocol (tree nodes checked) and with edges
checked, the paper's cRRT; the samplers alternate query by query.

    python benches/sampler_variant_plan.py --env panda_shelf --model M --queries 100 --seed 0 \
        --out benches/results/sampler_variant_plan_panda.json

Per protocol and sampler: success %, mean extensions, mean projection steps and mean plan time;
uniform time / sampler time. Extensions and projections are deterministic for a seed; times vary
with the machine's load (recorded).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path

import numpy as np

import genplan
from genplan.samplers.loading import load_sampler_model
from genplan.experiments.common import write_json
from genplan.planning import ENVIRONMENT_NAMES, Planner, environment

from adaptive_half_life import PROTOCOLS, record  # benches/: run as python benches/<script>.py


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="panda_shelf", choices=list(ENVIRONMENT_NAMES))
    parser.add_argument("--model", type=Path, required=True,
                        help="the variant: a GAN or flow file (.safetensors with its card)")
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    env = environment(args.env)
    robot = genplan.load(env.robot)
    world = env.world(robot)
    queries = env.queries(robot, n=args.queries, seed=args.seed)
    variant = load_sampler_model(robot, args.model)
    rows: list[dict] = []
    for protocol, settings in PROTOCOLS:
        planners = {"uniform": Planner(robot, world=world, sampler="uniform", settings=settings, seed=args.seed),
                    "gan": Planner(robot, world=world, sampler="gan", settings=settings, seed=args.seed),
                    "gan_variant": Planner(robot, world=world, sampler="gan", settings=settings, seed=args.seed,
                                           gan_model=variant)}
        results: dict[str, list] = {k: [] for k in planners}
        for q in queries:
            for label, planner in planners.items():
                results[label].append(planner.plan(q.start, q.goals))
        by = {label: record(rows, res, protocol=protocol, sampler=label) for label, res in results.items()}
        for label, row in by.items():
            row["uniform_over_this"] = by["uniform"]["t_ave_s"] / row["t_ave_s"]
            print(f"{protocol:5s} {label:12s} uniform/this {row['uniform_over_this']:.2f}x")
    if args.out:
        write_json(args.out, {"env": args.env, "queries": args.queries, "seed": args.seed,
                              "model": str(args.model), "model_config": dataclasses.asdict(variant.config),
                              "load_average": os.getloadavg(), "rows": rows})


if __name__ == "__main__":
    main()
