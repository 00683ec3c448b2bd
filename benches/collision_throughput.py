"""Batched collision checking from Python: genplan (Rust/parry, GIL released, 2 threads) against
Pinocchio + coal (what users call today) on the same Panda configurations and geometry.

    python benches/collision_throughput.py [--n 20000] [--out benches/results/collision_throughput.json]

Prints microseconds per configuration and the ratio; writes JSON. Medians of --repeats runs.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import genplan

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "collision_throughput.json")
    args = parser.parse_args()

    results = {}
    for name in ("panda", "talos"):
        robot = genplan.load(name)
        world = robot.collision_world()
        qs = robot.random_configurations(args.n, args.seed)
        t_ours = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            ours = world.in_collision(qs)
            t_ours.append((time.perf_counter() - t0) / args.n)
        entry = {"n": args.n, "genplan_us_per_config": statistics.median(t_ours) * 1e6,
                 "collision_fraction": float(ours.mean())}
        if name == "panda":  # coal on Talos uses the raw meshes (not hulls): not the same geometry
            geom = robot.collision_model
            gdata = pin.GeometryData(geom)
            m = min(args.n, 5000)
            t_ref = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                ref = np.array([pin.computeCollisions(robot.model, robot.data, geom, gdata, q, True) for q in qs[:m]])
                t_ref.append((time.perf_counter() - t0) / m)
            entry["pinocchio_coal_us_per_config"] = statistics.median(t_ref) * 1e6
            entry["agreement"] = float((ref == ours[:m]).mean())
            entry["speedup"] = entry["pinocchio_coal_us_per_config"] / entry["genplan_us_per_config"]
        results[name] = entry
        line = f"{name:<6} genplan {entry['genplan_us_per_config']:7.2f} us/config"
        if "speedup" in entry:
            line += (f"   pinocchio+coal {entry['pinocchio_coal_us_per_config']:7.2f} us/config"
                     f"   ratio {entry['speedup']:.1f}x   agreement {entry['agreement']:.4f}")
        print(line)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
