"""Choose the adaptive hybrid sampler's half-life (genplan.planning.ADAPTIVE_HALF_LIFE) on tuning
queries: seed 1 (Table II reports seed 0), the four paper environments, the paper's protocol
(tree nodes checked, --edge-resolution 0) and edges checked.

    python benches/adaptive_half_life.py --queries 20 --out benches/results/adaptive_half_life.json

Per environment and sampler (uniform, gan, hybrid, adaptive with each half-life): success %,
mean extensions and mean plan time; the summary is each sampler's geometric mean over the four
environments of uniform time / its time. Extensions are deterministic for a seed; times vary
with the machine's load (printed).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

import genplan
from genplan.experiments.benchmarks.plan import summarize_plans
from genplan.experiments.common import geometric_mean, write_json
from genplan.planning import ENVIRONMENT_NAMES, Planner, PlannerSettings, environment

#: The two protocols of Table II: the paper's (tree nodes checked, edges not validated) and
#: genplan's default (every edge validated).
PROTOCOLS = (("nodes", PlannerSettings(edge_resolution=0.0)), ("edges", PlannerSettings()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--half-lives", type=float, nargs="+", default=[25.0, 100.0, 400.0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    samplers: list[tuple[str, str, float | None]] = [("uniform", "uniform", None), ("gan", "gan", None),
                                                     ("hybrid", "hybrid", None)]
    samplers += [(f"adaptive_{h:g}", "adaptive", h) for h in args.half_lives]
    rows: list[dict] = []
    for env_name in ENVIRONMENT_NAMES:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        world = env.world(robot)
        queries = env.queries(robot, n=args.queries, seed=args.seed)
        for protocol, settings in PROTOCOLS:
            for label, kind, half_life in samplers:
                kw = {} if half_life is None else {"half_life": half_life}
                planner = Planner(robot, world=world, sampler=kind, settings=settings, seed=args.seed, **kw)
                record(rows, [planner.plan(q.start, q.goals) for q in queries], env=env_name, protocol=protocol,
                       sampler=label)
    summary = summarize(rows, [label for label, _, _ in samplers], list(ENVIRONMENT_NAMES))
    if args.out:
        write_json(args.out, {"queries": args.queries, "seed": args.seed, "half_lives": args.half_lives,
                              "load_average": os.getloadavg(), "rows": rows, "summary": summary})


def record(rows: list[dict], results: list, **keys: str) -> dict:
    """Append (and print) the Table II summary of ``results`` (``genplan bench plan``'s
    ``summarize_plans``) labelled with ``keys``; returns the row."""
    row = {**keys, **summarize_plans(results)}
    rows.append(row)
    print(" ".join(f"{v:12s}" for v in keys.values()) + f" {row['success_rate']:5.1f} %  E {row['extensions']:7.1f}  "
          f"P {row['projections']:8.1f}  T {row['t_ave_s'] * 1e3:8.2f} ms", flush=True)
    return row


def summarize(rows: list[dict], labels: list[str], envs: list[str]) -> dict[str, dict]:
    """Per protocol and sampler label: uniform time / its time in each environment, their
    geometric mean and its lowest success rate (printed as well)."""
    summary = {}
    for protocol, _ in PROTOCOLS:
        for label in labels:
            ratios = []
            for env_name in envs:
                by = {r["sampler"]: r for r in rows if r["env"] == env_name and r["protocol"] == protocol}
                ratios.append(by["uniform"]["t_ave_s"] / by[label]["t_ave_s"])
            gm = geometric_mean(ratios)
            summary[f"{protocol}/{label}"] = {"per_env": ratios, "geometric_mean": gm,
                                              "min_success": min(r["success_rate"] for r in rows
                                                                 if r["sampler"] == label and r["protocol"] == protocol)}
            print(f"{protocol:5s} {label:16s} uniform/this: " + ", ".join(f"{x:.2f}" for x in ratios)
                  + f"  geometric mean {gm:.2f}")
    return summary

if __name__ == "__main__":
    main()
