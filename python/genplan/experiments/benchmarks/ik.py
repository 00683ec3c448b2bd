"""IK for users and executable plans ([planner] items 4 and 5): ``genplan.solve_ik`` on reachable
targets, and ``PlanResult.trajectory`` on Panda shelf plans.

    genplan bench ik --targets 1000 --seed 0 --out benches/results/ik.json
    genplan bench ik --robots panda --targets 50 --plans 2          # quick

IK: the targets are the condition frame's positions (forward kinematics) of configurations on the
IK task's manifold drawn with seed 2000 + seed (genplan.samplers.data.valid_configurations; the GANs
were trained on seed 0, the coverage benchmark holds out 1000 + seed), hence reachable and never
seen in training. Rows: one GAN-initialised attempt of 50 iterations with the paper's solver (the
paper's protocol: ``settings=SolverSettings(), nominal="start"``) and with solve_ik's own
(``IK_SETTINGS``, the posture towards the joint-range middle), and ``solve_ik`` with retries and a
per-target time budget; the same from the rows of the IK task's data set nearest each target
(``init="data"``: the data a GAN is trained on, seed 0, no model); the same from uniform random
starts (one attempt of 50 iterations with the
paper's solver, with ``SolverSettings(active_set=True)`` (the joint limits as bounds of the step)
and with solve_ik's: the peers' protocol; ``solve_ik(init="uniform")`` with retries). Times are per target, one target after the other on one
core (``parallel=False``): its solves plus its share of the GAN sampling; "within budget" counts a
target solved with its time at most the budget.

Trajectory: ``--plans`` queries of the Panda shelf environment (seed ``seed``), planned with the
GAN sampler and shortcuts, each parameterised at 1 kHz (after one untimed warm-up that imports
scipy's spline module): the parameterisation time (TOPP-RA and sampling), the duration, the uniform time scaling
the sample check applied, the largest velocity / acceleration ratio to the limits over the
samples and the largest constraint residual / tolerance.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

import genplan
from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json

#: The robots and their paper IK tasks.
TASKS = {"panda": "panda_ik", "talos": "talos_ik"}
#: [planner]'s targets (issue 17): IK success and mean time, trajectory parameterisation time.
TARGETS = {"ik_success_within_budget_percent": 99.9, "ik_mean_ms_panda": 0.2, "trajectory_parameterisation_ms": 5.0}
#: The IK rows of each robot: GAN warm starts (one attempt with the paper's solver; with
#: solve_ik's; solve_ik's retries), the nearest rows of the task's data set (the same three),
#: uniform random starts (one attempt with the paper's solver;
#: with the joint limits as an active set; with solve_ik's; solve_ik's uniform retries).
IK_ROWS = ("gan_one_attempt", "gan_one_attempt_ik_solver", "solve_ik", "data_one_attempt",
           "data_one_attempt_ik_solver", "solve_ik_data", "uniform_one_attempt",
           "uniform_one_attempt_active_set", "uniform_one_attempt_ik_solver", "solve_ik_uniform")


def reachable_targets(robot: genplan.Robot, task: Any, n: int, seed: int) -> np.ndarray:
    """``n`` positions of the task's condition frame at configurations on its manifold drawn with
    ``seed`` (each reachable)."""
    from genplan.projection import condition_term
    from genplan.samplers.data import valid_configurations

    q = valid_configurations(robot, n, seed, progress=False, task=task)
    return robot.frame_positions(q, condition_term(task).frame)


def _summary(res: Any, budget_s: float | None) -> dict[str, Any]:
    t_ms = res.solve_s * 1e3  # each target's own solves, not the batch's elapsed time
    within = res.success if budget_s is None else res.success & (res.solve_s <= budget_s)
    return {"success_rate": 100.0 * float(res.success.mean()),
            "success_within_budget": 100.0 * float(within.mean()),
            "t_mean_ms": float(t_ms.mean()), "t_median_ms": float(np.median(t_ms)),
            "t_p99_ms": float(np.percentile(t_ms, 99)), "t_max_ms": float(t_ms.max()),
            "attempts_mean": float(res.attempts.mean()), "attempts_max": int(res.attempts.max()),
            "rounds": res.rounds, "wall_ms_per_target": res.wall_s * 1e3 / len(res)}


def run_ik(robots: list[str], n: int, seed: int, budget_s: float, restarts: int) -> dict[str, Any]:
    from genplan.projection import SolverSettings, load_task
    from genplan.samplers.gan import load_model

    out: dict[str, Any] = {}
    for name in robots:
        robot = genplan.load(name)
        task = load_task(TASKS[name], robot)
        targets = reachable_targets(robot, task, n, 2000 + seed)
        model = load_model(robot, None, task=task)
        paper = {"settings": SolverSettings(), "nominal": "start"}
        # the paper's protocol: one attempt, the solver's 50 iterations; then solve_ik's solver
        once = genplan.solve_ik(robot, task, targets, restarts=0, model=model, seed=seed, iterations=50,
                                parallel=False, **paper)
        once_ik = genplan.solve_ik(robot, task, targets, restarts=0, model=model, seed=seed, iterations=50,
                                   parallel=False)
        # solve_ik's budget is the call's wall clock: budget_s per target of the batch
        retried = genplan.solve_ik(robot, task, targets, restarts=restarts, time_budget_s=budget_s * n, model=model,
                                   seed=seed, parallel=False)
        # from the data set's row nearest each target (no model), as from the GAN
        data = {"data_one_attempt": _summary(genplan.solve_ik(robot, task, targets, init="data", restarts=0, seed=seed,
                                                              iterations=50, parallel=False, **paper), budget_s),
                "data_one_attempt_ik_solver": _summary(genplan.solve_ik(robot, task, targets, init="data", restarts=0,
                                                                        seed=seed, iterations=50, parallel=False),
                                                       budget_s),
                "solve_ik_data": {**_summary(genplan.solve_ik(robot, task, targets, init="data", restarts=restarts,
                                                              time_budget_s=budget_s * n, seed=seed, parallel=False),
                                             budget_s), "restarts": restarts, "time_budget_ms": budget_s * 1e3}}
        # from uniform random starts, one attempt of the solver's 50 iterations ([core-speed] item 4:
        # the paper's clipped step, the joint limits as an active set, solve_ik's solver; the
        # peers' protocol), and solve_ik's uniform retries within the budget
        uniform = {f"uniform_one_attempt{suffix}": _summary(
            genplan.solve_ik(robot, task, targets, init="uniform", restarts=0, seed=seed, iterations=50,
                             parallel=False, **kw), budget_s)
            for suffix, kw in (("", paper), ("_active_set", {**paper, "settings": SolverSettings(active_set=True)}),
                               ("_ik_solver", {}))}
        uniform_retried = genplan.solve_ik(robot, task, targets, init="uniform", restarts=restarts,
                                           time_budget_s=budget_s * n, seed=seed, parallel=False)
        out[name] = {"task": task.name, "targets": n, "target_seed": 2000 + seed,
                     "gan_one_attempt": _summary(once, budget_s),
                     "gan_one_attempt_ik_solver": _summary(once_ik, budget_s),
                     "solve_ik": {**_summary(retried, budget_s), "restarts": restarts, "time_budget_ms": budget_s * 1e3},
                     **data, **uniform,
                     "solve_ik_uniform": {**_summary(uniform_retried, budget_s), "restarts": restarts,
                                          "time_budget_ms": budget_s * 1e3}}
    return out


def run_trajectory(plans: int, seed: int) -> dict[str, Any]:
    from genplan.planning import Planner, PlannerSettings, environment

    panda = genplan.load("panda")
    env = environment("panda_shelf")
    planner = Planner(panda, world=env.world(panda), sampler="gan", settings=PlannerSettings(simplify=True), seed=seed)
    from genplan.errors import InvalidTrajectoryError

    rows = []
    refused: list[str] = []  # trajectories that fail their check (a sample in collision, ...): not timed
    warm = False
    for query in env.queries(panda, n=plans, seed=seed):
        res = planner.plan(query.start, query.goals)
        if not res.success:
            continue
        try:
            if not warm:
                res.trajectory()  # imports scipy.interpolate (about half a second), not timed
                warm = True
            traj = res.trajectory()
        except InvalidTrajectoryError as e:
            refused.append(str(e))
            continue
        rows.append({"parameterisation_ms": traj.stats["parameterisation_s"] * 1e3,
                     "check_ms": traj.stats["check_s"] * 1e3,
                     "collision_check_ms": traj.stats["collision_check_s"] * 1e3, "gridpoints": traj.stats["gridpoints"],
                     "path_states": traj.stats["path_states"], "duration_s": traj.duration,
                     "time_scaling": traj.stats["time_scaling"], "samples": len(traj),
                     "max_velocity_ratio": traj.max_velocity_ratio,
                     "max_acceleration_ratio": traj.max_acceleration_ratio,
                     "max_residual_ratio": traj.max_residual_ratio, "residuals": traj.residuals})
    keys = ("parameterisation_ms", "check_ms", "collision_check_ms", "duration_s", "time_scaling", "max_velocity_ratio",
            "max_acceleration_ratio", "max_residual_ratio")
    summary = {k: {"median": float(np.median([r[k] for r in rows])), "mean": float(np.mean([r[k] for r in rows])),
                   "max": float(np.max([r[k] for r in rows]))} for k in keys} if rows else {}
    return {"environment": "panda_shelf", "sampler": "gan", "simplify": True, "plans": plans, "planned": len(rows),
            "refused": refused,
            "rate_hz": 1000.0, "acceleration_limits": "2 x the URDF velocity limits (genplan.trajectory default)",
            "summary": summary, "rows": rows}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robots", nargs="+", choices=sorted(TASKS), default=sorted(TASKS), help="IK robots (default both)")
    p.add_argument("--targets", type=A.positive_int, default=1000, help="IK targets per robot (default 1000)")
    p.add_argument("--budget-ms", type=A.positive_float, default=5.0, help="per-target IK time budget (default 5 ms)")
    p.add_argument("--restarts", type=A.non_negative_int, default=20, help="IK retries per target (default 20)")
    p.add_argument("--plans", type=A.non_negative_int, default=10,
                   help="Panda shelf plans to parameterise (default 10; 0: no trajectory part)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


def main(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    ik = run_ik(args.robots, args.targets, args.seed, args.budget_ms * 1e-3, args.restarts)
    traj = run_trajectory(args.plans, args.seed) if args.plans else None
    rows = []
    for name, r in ik.items():
        for kind in IK_ROWS:
            s = r[kind]
            rows.append([name, kind, f"{s['success_rate']:.1f}", f"{s['success_within_budget']:.1f}",
                         f"{s['t_mean_ms']:.3f}", f"{s['t_p99_ms']:.3f}", s["attempts_max"]])
    print(table(["robot", "IK", "success %", f"within {args.budget_ms:g} ms %", "mean ms", "p99 ms", "attempts max"],
                rows))
    if traj is not None and traj["summary"]:
        s = traj["summary"]
        print(table(["trajectory (Panda shelf)", "median", "mean", "max"],
                    [[k, f"{v['median']:.4g}", f"{v['mean']:.4g}", f"{v['max']:.4g}"] for k, v in s.items()]))
    payload = {"benchmark": "ik", "seed": args.seed, "targets": TARGETS, "ik": ik, "trajectory": traj,
               "machine": machine(), "wall_s": time.perf_counter() - t0}
    write_json(args.out, payload)
    return 0
