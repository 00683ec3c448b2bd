"""What checking a trajectory's samples costs: ``PlanResult.trajectory()`` on the Panda shelf
queries planned with the default settings (GAN sampler, ``edge_check="sampled"``, no shortcuts),
at 1 kHz.

    python benches/trajectory_check.py --plans 20 --seed 0 --out benches/results/trajectory_check.json

Per plan: samples, the parameterisation (TOPP-RA and the native sampling), the whole check
(joint, velocity and acceleration limits, the task's residuals, the world) and its collision part
(``in_collision`` on every sample: genplan.trajectory._invalid_samples), or the refusal
(InvalidTrajectoryError, naming the first bad sample); the summary has their medians. Each
trajectory is made once untimed first (scipy's import, the evaluator's construction), then
``--repeats`` times, the fastest of each time kept (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan.errors import InvalidTrajectoryError
from genplan.experiments.common import machine, write_json
from genplan.planning import Planner, environment


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plans", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    panda = genplan.load("panda")
    env = environment("panda_shelf")
    planner = Planner(panda, world=env.world(panda), sampler="gan", seed=args.seed)
    rows: list[dict[str, Any]] = []
    t_start = time.time()
    for i, q in enumerate(env.queries(panda, n=args.plans, seed=args.seed)):
        res = planner.plan(q.start, q.goals)
        if not res.success:
            rows.append({"query": i, "planned": False})
            continue
        try:
            res.trajectory()  # warm-up
            trajs = [res.trajectory() for _ in range(max(1, args.repeats))]
        except InvalidTrajectoryError as e:
            rows.append({"query": i, "planned": True, "refused": str(e)})
            print(f"query {i}: refused: {e}")
            continue

        def fastest(key: str) -> float:
            return 1e3 * min(t.stats[key] for t in trajs)

        rows.append({"query": i, "planned": True, "samples": len(trajs[0]), "parameterisation_ms": fastest("parameterisation_s"),
                     "check_ms": fastest("check_s"), "collision_check_ms": fastest("collision_check_s"),
                     "samples_into_limits": trajs[0].stats["samples_into_limits"]})
        print(f"query {i}: {rows[-1]['samples']} samples, parameterisation {rows[-1]['parameterisation_ms']:.1f} ms, "
              f"check {rows[-1]['check_ms']:.1f} ms (collision {rows[-1]['collision_check_ms']:.1f} ms)")
    timed = [r for r in rows if "samples" in r]
    summary = {k: float(np.median([r[k] for r in timed])) for k in
               ("samples", "parameterisation_ms", "check_ms", "collision_check_ms")} if timed else {}
    summary["refused"] = sum("refused" in r for r in rows)
    summary["timed"] = len(timed)
    print("median:", ", ".join(f"{k} {v:.1f}" for k, v in summary.items()))
    if args.out is not None:
        write_json(args.out, {"command": f"python benches/trajectory_check.py --plans {args.plans} --seed {args.seed} "
                                         f"--repeats {args.repeats}",
                              "machine": machine(), "load_average": os.getloadavg(), "seconds": time.time() - t_start,
                              "summary": summary, "rows": rows})


if __name__ == "__main__":
    main()
