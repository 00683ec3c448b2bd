"""solve_ik's solver for IK ([core-speed] item 4, [planner] item 5): the paper's damped Gauss-Newton
(Armijo line search, posture towards the warm start) against whole steps (``max_backtracks=1``)
and the posture towards the middle of the joint ranges (``solve_ik(nominal="mid")``), across the
damping ``mu``, on tuning targets (seeds 1 and 2; the tables report seed 0).

    python benches/ik_settings.py --seeds 1 2 --out benches/results/ik_settings.json

For each robot's paper IK task: reachable targets (as ``genplan bench ik``: the condition frame at
configurations on the task's manifold, seed 3000 + seed), one attempt each from the same warm
starts (uniform random, seed ``seed``; the task's shipped GAN, seed ``seed``), of each of
``--iterations`` iterations (20: solve_ik's attempts; 100: the peers'), rows solved on all cores.
Prints and writes the success rate and the mean solve time per target (on all cores, so
indicative only).
"""

from __future__ import annotations

import argparse
import itertools
import os
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan.experiments.benchmarks.ik import TASKS, reachable_targets
from genplan.experiments.common import write_json
from genplan.ik import solve_ik
from genplan.projection import SolverSettings, load_task

#: (label, settings, nominal): the paper's solver, each change alone, both (and with the joint
#: limits as bounds of the step).
VARIANTS = [("paper", {}, "start"), ("mid_posture", {}, "mid"),
            *[(f"whole_steps_mu_{mu:g}", {"mu": mu, "max_backtracks": 1}, "start") for mu in (1e-4, 1e-3)],
            *[(f"whole_steps_mid_posture_mu_{mu:g}", {"mu": mu, "max_backtracks": 1}, "mid")
              for mu in (1e-4, 3e-4, 1e-3, 3e-3)],
            ("whole_steps_mid_posture_active_set_mu_0.001", {"mu": 1e-3, "max_backtracks": 1, "active_set": True}, "mid")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=sorted(TASKS), choices=sorted(TASKS))
    parser.add_argument("--targets", type=int, default=500)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--iterations", type=int, nargs="+", default=[20, 100])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if 0 in args.seeds:
        parser.error("--seeds: seed 0 is the tables' (genplan bench peers, genplan bench ik): tune on others")
    out: dict[str, Any] = {"benchmark": "ik_settings", "targets": args.targets,
                           "seeds": args.seeds, "rows": []}
    for name in args.robots:
        robot = genplan.load(name)
        task = load_task(TASKS[name], robot)
        for seed in args.seeds:
            targets = reachable_targets(robot, task, args.targets, 3000 + seed)
            uniform = robot.random_configurations(args.targets, np.random.default_rng(seed))
            for init, starts in (("uniform", uniform), ("gan", "gan")):
                for (label, changes, nominal), iterations in itertools.product(VARIANTS, args.iterations):
                    res = solve_ik(robot, task, targets, init=starts, restarts=0, iterations=iterations, seed=seed,
                                   settings=SolverSettings(**changes), nominal=nominal)
                    row = {"robot": name, "seed": seed, "init": init, "variant": label, "iterations": iterations,
                           "settings": changes,
                           "nominal": nominal, "success_percent": 100.0 * float(res.success.mean()),
                           "t_mean_ms": 1e3 * float(res.time_s.mean())}
                    out["rows"].append(row)
                    print(f"{name:6s} seed {seed} {init:8s} it {iterations:3d} {label:34s} success {row['success_percent']:5.1f} % "
                          f"mean {row['t_mean_ms']:.3f} ms", flush=True)
    out["load"] = list(os.getloadavg())
    write_json(args.out, out)


if __name__ == "__main__":
    main()
