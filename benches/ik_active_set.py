"""Why IK from uniform random starts fails, and whether joint limits as bounds of the step help
([core-speed] item 4: ``SolverSettings(active_set=True)``), on tuning targets (seed 1; the
tables report seed 0).

    python benches/ik_active_set.py --targets 500 --seed 1 --out benches/results/ik_active_set.json

For each robot's paper IK task: reachable targets (as ``genplan bench ik``: the condition frame at
configurations on the task's manifold, seed 3000 + seed), one attempt each from the same uniform
random starts, with the paper's clipped step and with the active set, across iterations (50,
200), damping ``mu`` (1e-4: the paper's, 1e-3, 1e-2, 1e-1, 1) and the task with and without its
``JointLimits`` term. Then, for the paper's settings, what the failures look like: each primary
term's residual (median) and the share of failed answers with a joint at a limit. Success rates
only (deterministic for a seed); no timings.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan.experiments.benchmarks.ik import TASKS, reachable_targets
from genplan.experiments.common import write_json
from genplan.ik import solve_ik
from genplan.projection import SolverSettings, load_task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=sorted(TASKS), choices=sorted(TASKS))
    parser.add_argument("--targets", type=int, default=500)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out: dict[str, Any] = {"benchmark": "ik_active_set", "seed": args.seed, "targets": args.targets, "robots": {}}
    for name in args.robots:
        robot = genplan.load(name)
        task = load_task(TASKS[name], robot)
        no_limits = dataclasses.replace(task, primary=[t for t in task.primary if type(t).__name__ != "JointLimits"])
        targets = reachable_targets(robot, task, args.targets, 3000 + args.seed)
        starts = robot.random_configurations(args.targets, np.random.default_rng(args.seed))
        rows = []

        def attempt(tk: Any, iterations: int, mu: float, active: bool) -> Any:
            return solve_ik(robot, tk, targets, init=starts, restarts=0, iterations=iterations, parallel=False,
                            settings=SolverSettings(mu=mu, active_set=active), nominal="start")

        for label, tk in (("paper task", task), ("without JointLimits", no_limits)):
            for iterations in (50, 200):
                for mu in (1e-4, 1e-3, 1e-2, 1e-1, 1.0):
                    if label != "paper task" and (iterations, mu) != (50, 1e-4):
                        continue
                    for active in (False, True):
                        res = attempt(tk, iterations, mu, active)
                        rows.append({"task": label, "iterations": iterations, "mu": mu, "active_set": active,
                                     "success_percent": 100.0 * float(res.success.mean())})
                        print(f"{name:6s} {label:20s} it {iterations:3d} mu {mu:g} active_set {active!s:5s} "
                              f"success {rows[-1]['success_percent']:.1f} %", flush=True)
        res = attempt(task, 50, 1e-4, False)
        failed = ~res.success
        at_limit = (np.abs(res.q - robot.lower) < 1e-3) | (np.abs(res.q - robot.upper) < 1e-3)
        failures = {"count": int(failed.sum()),
                    "residual_median": {k: float(np.median(v[failed])) for k, v in res.residuals.items()},
                    "with_a_joint_at_a_limit_percent": 100.0 * float(at_limit[failed].any(axis=1).mean()),
                    "solved_with_a_joint_at_a_limit_percent": 100.0 * float(at_limit[~failed].any(axis=1).mean())}
        print(f"{name}: failures {json.dumps(failures)}")
        out["robots"][name] = {"task": task.name, "target_seed": 3000 + args.seed, "rows": rows, "failures": failures}
    out["load"] = list(os.getloadavg())
    write_json(args.out, out)

if __name__ == "__main__":
    main()
