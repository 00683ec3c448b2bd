"""Can a one-step distilled flow be both precise and covering? ([sampler]: coverage >= 0.9 with
projection steps <= 1.3 on the Panda) A many-step teacher flow (pure flow matching, 8 steps) is
trained once; one-step students are distilled from it with the constraint and joint-limit costs
added at each weight of --w-cost (the target cost left out, so no cost pulls the samples
together towards their target), and each model is measured as `genplan bench coverage` measures
its variants: cluster coverage and MMD against held-out valid data, projection success and steps
from one sample per held-out target, native microseconds per sample.

    python benches/distill_constraint_sweep.py --robot panda --seed 1 --w-cost 0,0.01,0.1,1 \
        --iterations 10000 --out benches/results/coverage_tuning/distill_constraint_panda_seed1.json

Seed 1 is a tuning seed (the tables report seed 0). One thread (torch and the native sampler).
Training times and the native cost vary with the machine's load (recorded per row).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

import genplan
from genplan import projection as P
from genplan.experiments.benchmarks.coverage import cluster_coverage, mmd, native_sample_us
from genplan.experiments.common import machine, write_json
from genplan.samplers import flow
from genplan.samplers.base import Codec
from genplan.samplers.data import valid_configurations
from genplan.samplers.gan import default_config


def weights(text: str) -> list[float]:
    values = [float(v) for v in text.split(",") if v.strip()]
    if not values or any(not np.isfinite(v) or v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated non-negative weights, got {text!r}")
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", choices=["panda", "talos"])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--w-cost", type=weights, default=[0.0, 0.01, 0.1, 1.0],
                        help="the students' cost weights (FlowConfig.w_cost; w_target 0)")
    parser.add_argument("--iterations", type=int, default=10000, help="teacher and student training steps")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.iterations < 1:
        parser.error("--iterations must be positive")
    torch.set_num_threads(1)
    robot = genplan.load(args.robot)
    data = valid_configurations(robot, 25_000, 0, progress=True)
    held_out = valid_configurations(robot, 3000, 1000 + args.seed, progress=True)  # as genplan bench coverage
    targets = robot.frame_positions(held_out, default_config(args.robot).target_frame)
    feats = Codec.features(robot, held_out)
    scale = np.maximum(feats.std(0), 0.05)
    ref = feats / scale
    solver = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection"))

    def measure(sampler: Any, **row: Any) -> dict[str, Any]:
        q = sampler.sample(targets, np.random.default_rng(args.seed), threads=1)
        res = solver.solve_batch(q)
        s = Codec.features(robot, q) / scale
        row.update(cluster_coverage=cluster_coverage(ref, s, np.random.default_rng(args.seed)),
                   mmd=mmd(ref, s, np.random.default_rng(args.seed)),
                   projection_success=float(res.success.mean()),
                   projection_steps_mean=float(res.iterations[res.success].mean()) if res.success.any() else None,
                   native_sample_us=native_sample_us(sampler, args.seed))
        print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
        return row

    rows = []
    load, t0 = os.getloadavg()[0], time.perf_counter()
    cfg = flow.default_config(args.robot, w_cost=0.0, steps=8, iterations=args.iterations, seed=args.seed)
    teacher = flow.train(cfg, data=data, progress=True, threads=1)
    rows.append(measure(teacher, model="teacher", steps=8, w_cost=0.0, train_s=time.perf_counter() - t0,
                        load_average_1min_start_end=[load, os.getloadavg()[0]]))
    for w in args.w_cost:
        load, t0 = os.getloadavg()[0], time.perf_counter()
        cfg = flow.default_config(args.robot, w_cost=w, w_target=0.0, steps=1, iterations=args.iterations,
                                  seed=args.seed, teacher="flow_pure")
        student = flow.distill(cfg, teacher, progress=True, threads=1)
        rows.append(measure(student, model="student", steps=1, w_cost=w, train_s=time.perf_counter() - t0,
                            load_average_1min_start_end=[load, os.getloadavg()[0]]))
    write_json(args.out, {
        "benchmark": "distill_constraint_sweep", "robot": args.robot, "seed": args.seed,
        "iterations": args.iterations, "held_out_size": len(held_out), "w_target": 0.0, "rows": rows,
        "machine": machine(),
        "command": f"python benches/distill_constraint_sweep.py --robot {args.robot} --seed {args.seed} "
                   f"--w-cost {','.join(map(str, args.w_cost))} --iterations {args.iterations}"
                   + (f" --out {args.out}" if args.out else ""),
    })


if __name__ == "__main__":
    main()
