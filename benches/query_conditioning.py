"""Does conditioning the GAN sampler on the query pay off? ([sampler] item 2, the GAN paper's future
work), on tuning queries: seed 1 (Table II reports seed 0), the four paper environments, the
paper's protocol (tree nodes checked, --edge-resolution 0) and edges checked.

    python benches/query_conditioning.py --queries 20 --out benches/results/query_conditioning.json

The GAN is conditioned on end-effector targets. ``gan`` draws them uniformly in the model's box
(the paper's planning sampler); ``query_M_W`` draws them, with probability W, in the box spanned by
the condition frame's positions at the query's start and goals widened by M metres (clipped to the
model's target limits), else in the model's box, which keeps the whole manifold reachable. Per
environment and sampler: success %, mean extensions and mean plan time; the summary is each
sampler's geometric mean over the four environments of uniform time / its time. Extensions are
deterministic for a seed; times vary with the machine's load (recorded).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan import _core
from genplan.samplers.sampler import GanSampler
from genplan.experiments.common import write_json
from genplan.planning import ENVIRONMENT_NAMES, Planner, environment

from adaptive_half_life import PROTOCOLS, record, summarize  # benches/: run as python benches/<script>.py


def query_box(robot: genplan.Robot, gan: GanSampler, start: np.ndarray, goals: np.ndarray, margin: float) -> np.ndarray:
    """The box of the condition frame's positions at the start and goals, widened by ``margin``,
    within the model's target limits."""
    p = robot.frame_positions(np.vstack([start[None], goals]), gan.model.config.target_frame)
    lo, hi = p.min(axis=0) - margin, p.max(axis=0) + margin
    limits = np.asarray(gan.model.target_limits(), dtype=np.float64)
    return np.array([np.clip(lo, limits[0], limits[1]), np.clip(hi, limits[0], limits[1])])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--margins", type=float, nargs="+", default=[0.1, 0.3])
    parser.add_argument("--weights", type=float, nargs="+", default=[0.5, 0.9])
    parser.add_argument("--envs", nargs="+", default=list(ENVIRONMENT_NAMES), choices=list(ENVIRONMENT_NAMES))
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    variants = [(f"query_{m:g}_{w:g}", m, w) for m in args.margins for w in args.weights]
    rows: list[dict] = []
    for env_name in args.envs:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        world = env.world(robot)
        queries = env.queries(robot, n=args.queries, seed=args.seed)
        for protocol, settings in PROTOCOLS:
            planners = {kind: Planner(robot, world=world, sampler=kind, settings=settings, seed=args.seed)
                        for kind in ("uniform", "gan")}
            gan = GanSampler(robot, seed=args.seed)
            results: dict[str, list[Any]] = {"uniform": [], "gan": [], **{v[0]: [] for v in variants}}
            for i, q in enumerate(queries):
                results["uniform"].append(planners["uniform"].plan(q.start, q.goals))
                results["gan"].append(planners["gan"].plan(q.start, q.goals))
                for label, margin, weight in variants:
                    box = query_box(robot, gan, np.asarray(q.start), np.asarray(q.goals), margin)
                    seed = args.seed * 100_003 + i
                    focused = gan.model.native_sampler(box, seed)
                    whole = gan.model.native_sampler(gan.box, seed + 1)
                    sampler = _core.MixtureSampler(focused, whole, weight, seed + 2)
                    results[label].append(planners["gan"].plan(q.start, q.goals, sampler=sampler))
            for label, res in results.items():
                record(rows, res, env=env_name, protocol=protocol, sampler=label)
    summary = summarize(rows, ["gan"] + [v[0] for v in variants], args.envs)
    if args.out:
        write_json(args.out, {"queries": args.queries, "seed": args.seed, "envs": args.envs, "margins": args.margins,
                              "weights": args.weights, "load_average": os.getloadavg(), "rows": rows,
                              "summary": summary})

if __name__ == "__main__":
    main()
