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
import json
import math
import os
from pathlib import Path

import numpy as np

import genplan
from genplan.planning import ENVIRONMENT_NAMES, Planner, PlannerSettings, environment


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
    rows = []
    for env_name in ENVIRONMENT_NAMES:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        world = env.world(robot)
        queries = env.queries(robot, n=args.queries, seed=args.seed)
        for protocol, resolution in (("nodes", 0.0), ("edges", PlannerSettings().edge_resolution)):
            settings = PlannerSettings(edge_resolution=resolution)
            for label, kind, half_life in samplers:
                kw = {} if half_life is None else {"half_life": half_life}
                planner = Planner(robot, world=world, sampler=kind, settings=settings, seed=args.seed, **kw)
                res = [planner.plan(q.start, q.goals) for q in queries]
                row = {"env": env_name, "protocol": protocol, "sampler": label,
                       "success_rate": 100.0 * float(np.mean([r.success for r in res])),
                       "extensions": float(np.mean([r.extensions for r in res])),
                       "t_ave_s": float(np.mean([r.time_s for r in res]))}
                rows.append(row)
                print(f"{env_name:12s} {protocol:5s} {label:14s} {row['success_rate']:5.1f} % "
                      f"E {row['extensions']:7.1f}  T {row['t_ave_s'] * 1e3:8.2f} ms", flush=True)
    summary = summarize(rows, [label for label, _, _ in samplers], list(ENVIRONMENT_NAMES))
    if args.out:
        write_json(args.out, {"queries": args.queries, "seed": args.seed, "half_lives": args.half_lives,
                              "load_average": os.getloadavg(), "rows": rows, "summary": summary})


def summarize(rows: list[dict], labels: list[str], envs: list[str]) -> dict[str, dict]:
    """Per protocol and sampler label: uniform time / its time in each environment, their
    geometric mean and its lowest success rate (printed as well)."""
    summary = {}
    for protocol in ("nodes", "edges"):
        for label in labels:
            ratios = []
            for env_name in envs:
                by = {r["sampler"]: r for r in rows if r["env"] == env_name and r["protocol"] == protocol}
                ratios.append(by["uniform"]["t_ave_s"] / by[label]["t_ave_s"])
            gm = math.exp(float(np.mean(np.log(ratios))))
            summary[f"{protocol}/{label}"] = {"per_env": ratios, "geometric_mean": gm,
                                              "min_success": min(r["success_rate"] for r in rows
                                                                 if r["sampler"] == label and r["protocol"] == protocol)}
            print(f"{protocol:5s} {label:16s} uniform/this: " + ", ".join(f"{x:.2f}" for x in ratios)
                  + f"  geometric mean {gm:.2f}")
    return summary


def write_json(out: Path, payload: dict) -> None:
    """``payload`` to ``out`` through a temporary name (never half-written)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(payload, indent=1) + "\n")
    os.replace(tmp, out)
    print(f"wrote {out}")

if __name__ == "__main__":
    main()
