"""Table I of the GAN paper: projection and IK from a given initialisation, N tasks per robot.

    genplan bench projection --robot panda --init uniform --tasks 500 --seed 0 --out F.json
    genplan bench projection --robot panda --solver scipy ...   # the baseline, same tasks
    genplan bench projection --robot my_robot.toml --task my_task.toml --init gan --model M.safetensors
    genplan bench projection --robot panda --seeds 0..9 --out F.json   # per-seed rows + medians

With ``--seeds A..B`` each seed is a run of its own (a shard on genplan.executor, one after the
other unless ``--workers K`` or ``--ray``): the JSON holds every seed's results (``per_seed``) and
their median across seeds (``aggregate``); see genplan.experiments.sweeps.

With ``--task`` (a task with a [condition], shipped name or file), the projection rows solve its
manifold (:func:`genplan.samplers.costs.manifold_task`) and the IK rows the task itself, its condition
term aimed at targets drawn in the condition's box; without it, the paper's two tasks of the robot.

The same seed gives the same tasks (initial configurations and IK targets) for every solver, so
ratios are measured, not guessed. Times are per task, one task after the other on one core.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import projection as P
import genplan
from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json

#: Table I of the GAN paper: (success %, T_ave ms, T*_ave ms, steps*).
PAPER_TABLE_I: dict[tuple[str, str, str], tuple[float, float, float, float]] = {
    ("panda", "projection", "uniform"): (98.6, 4.2, 3.6, 6.5),
    ("panda", "projection", "gan"): (100.0, 1.0, 1.0, 1.9),
    ("panda", "ik", "uniform"): (76.4, 29.3, 8.8, 7.9),
    ("panda", "ik", "gan"): (88.6, 12.5, 2.2, 2.9),
    ("talos", "projection", "uniform"): (84.4, 20.5, 10.5, 8.7),
    ("talos", "projection", "gan"): (100.0, 2.1, 2.1, 2.1),
    ("talos", "ik", "uniform"): (82.6, 28.7, 15.7, 10.4),
    ("talos", "ik", "gan"): (100.0, 2.8, 2.8, 2.5),
}

SOLVERS = ("gauss-newton", "scipy")
INITS = ("uniform", "gan")


def tasks_for(robot: genplan.Robot, task: str | Path | P.Task | None = None) -> dict[str, P.Task]:
    """The task of each row kind: ``task`` (its manifold for projection, itself for IK), or the
    paper's projection and IK tasks of the robot when ``task`` is None."""
    if task is None:
        return {kind: P.paper_task(robot, kind) for kind in P.TASK_KINDS}
    from genplan.samplers.costs import manifold_task

    t = P.load_task(task, robot)
    return {"projection": manifold_task(t, robot), "ik": t}


def ik_box(tasks: dict[str, P.Task]) -> NDArray[np.float64]:
    """The box the IK targets are drawn from: the IK task's [condition]."""
    condition = tasks["ik"].condition
    assert condition is not None, "an IK task has a [condition] (checked by manifold_task)"
    return np.array([condition.low, condition.high])


def make_problems(robot: genplan.Robot, n: int, seed: int, init: str = "uniform",
                  model_path: Path | None = None, tasks: dict[str, P.Task] | None = None,
                  task: str | Path | None = None) -> dict[str, Any]:
    """Seeded tasks: initial configurations for projection and for IK, and the IK targets.

    ``init="gan"``: the initial configurations come from the shipped GAN (or ``model_path``; a
    GAN for another robot or task is refused), conditioned on a random target in the GAN's box
    for projection and on the IK target for IK; the time to sample them is reported separately
    (``gan_sample_ms_per_task``). ``task``: the task as the command was given it (a shipped
    name or a task file), which the GAN is matched to and a missing GAN's hint names.
    """
    tasks = tasks_for(robot) if tasks is None else tasks
    rng = np.random.default_rng(seed)
    box = ik_box(tasks)
    problems: dict[str, Any] = {
        "projection": {"q0": robot.random_configurations(n, rng)},
        "ik": {"q0": robot.random_configurations(n, rng), "targets": rng.uniform(box[0], box[1], size=(n, 3))},
    }
    if init == "gan":
        from genplan.samplers.loading import load_sampler_model

        model = load_sampler_model(robot, model_path, task=tasks["ik"] if task is None else task)
        gbox = np.asarray(model.config.target_box)
        t0 = time.perf_counter()
        problems["projection"]["q0"] = model.sample(rng.uniform(gbox[0], gbox[1], size=(n, 3)), rng)
        problems["ik"]["q0"] = model.sample(problems["ik"]["targets"], rng)
        problems["gan_sample_ms_per_task"] = (time.perf_counter() - t0) * 1e3 / (2 * n)
        problems["gan_model"] = model.card.get("weights_sha256", "")[:12]
    return problems


def summarize(success: NDArray[np.bool_], times_s: NDArray[np.float64], steps: NDArray[np.int64]) -> dict[str, Any]:
    ok = success.astype(bool)
    t_ms = times_s * 1e3
    return {
        "success_rate": 100.0 * float(ok.mean()),  # percent, as in the paper
        "t_ave_ms": float(t_ms.mean()),
        "t_std_ms": float(t_ms.std()),
        "t_median_ms": float(np.median(t_ms)),
        "t_star_ave_ms": float(t_ms[ok].mean()) if ok.any() else None,
        "steps_star": float(steps[ok].mean()) if ok.any() else None,
        "steps_star_std": float(steps[ok].std()) if ok.any() else None,
        "tasks": int(len(ok)),
    }


def target_term(task: P.Task) -> str:
    """The IK task's per-query term: its [condition]'s."""
    assert task.condition is not None, "the shipped IK tasks have a [condition]"
    return task.condition.term


def run_gauss_newton(robot: genplan.Robot, problems: dict[str, Any], backend: str,
                     tasks: dict[str, P.Task], progress: bool = True) -> dict[str, Any]:
    out = {}
    for kind in P.TASK_KINDS:
        task = tasks[kind]
        solver = P.GaussNewtonProjector(robot, task, backend=backend)
        targets = {target_term(task): problems[kind]["targets"]} if kind == "ik" else None
        t0 = time.perf_counter()
        res = solver.solve_batch(problems[kind]["q0"], targets=targets, parallel=False, progress=progress)
        wall = time.perf_counter() - t0
        out[kind] = summarize(res.success, res.time_s, res.iterations)
        out[kind]["wall_s"] = wall
    return out


def run_scipy(robot: genplan.Robot, problems: dict[str, Any], tasks: dict[str, P.Task],
              progress: bool = True) -> dict[str, Any]:
    from tqdm import tqdm

    from genplan.experiments.peers.scipy import scipy_solve

    out = {}
    for kind in P.TASK_KINDS:
        base = tasks[kind]
        q0s = problems[kind]["q0"]
        rows = []
        t0 = time.perf_counter()
        for i in tqdm(range(len(q0s)), desc=f"scipy {kind}", unit="task", leave=False, disable=not progress):
            task = base.with_targets(**{target_term(base): problems[kind]["targets"][i]}) if kind == "ik" else base
            rows.append(scipy_solve(robot, task, q0s[i]))
        wall = time.perf_counter() - t0
        ok, ts, nfev = (np.array(c) for c in zip(*rows))
        out[kind] = summarize(ok, ts, nfev)
        out[kind]["wall_s"] = wall
    return out


def task_description(tasks: dict[str, P.Task]) -> dict[str, Any]:
    """Weights and thresholds of the tasks that were run."""
    desc = {}
    for kind in P.TASK_KINDS:
        task = tasks[kind]
        desc[kind] = {t.label(): {"type": type(t).__name__, "weight": t.weight, "tolerance": t.tolerance}
                      for t in [*task.primary, *task.secondary]}
    return desc


def run(robot_name: str, init: str, tasks: int, seed: int, solver: str, backend: str,
        model_path: Path | None = None, task: str | Path | None = None, progress: bool = True) -> dict[str, Any]:
    robot = genplan.load(robot_name)
    kinds = tasks_for(robot, task)
    problems = make_problems(robot, tasks, seed, init, model_path, kinds, task)
    if solver == "gauss-newton":
        results = run_gauss_newton(robot, problems, backend, kinds, progress)
    else:
        results = run_scipy(robot, problems, kinds, progress)
    paper = task is None and (robot.name, "ik", init) in PAPER_TABLE_I
    payload: dict[str, Any] = {
        "benchmark": "projection",
        "robot": robot.name,
        "robot_argument": str(robot_name),
        "task": None if task is None else kinds["ik"].name,
        "init": init,
        "solver": solver,
        "backend": backend if solver == "gauss-newton" else "scipy.optimize.least_squares(trf)",
        "tasks": tasks,
        "seed": seed,
        "units": {"success_rate": "percent", "t_*": "milliseconds per task", "steps_star": "solver iterations"
                  + (" (function evaluations for scipy)" if solver == "scipy" else "")},
        "ik_target_box": ik_box(kinds).tolist(),
        **({k: problems[k] for k in ("gan_sample_ms_per_task", "gan_model") if k in problems}),
        "settings": P.SolverSettings().to_dict(),
        "task_terms": task_description(kinds),
        "machine": machine(),
        **results,
        "paper": {kind: dict(zip(("success_rate", "t_ave_ms", "t_star_ave_ms", "steps_star"),
                                 PAPER_TABLE_I[(robot.name, kind, init)])) for kind in P.TASK_KINDS} if paper else None,
    }
    return payload


def print_table(payload: dict[str, Any]) -> None:
    rows = []
    for kind in P.TASK_KINDS:
        r, p = payload[kind], (payload["paper"] or {}).get(kind)
        rows.append([payload["robot"], kind, f"{payload['init']} ({payload['solver']})",
                     f"{r['success_rate']:.1f}", f"{r['t_ave_ms']:.3f} ± {r['t_std_ms']:.3f}",
                     "-" if r["t_star_ave_ms"] is None else f"{r['t_star_ave_ms']:.3f}",
                     "-" if r["steps_star"] is None else f"{r['steps_star']:.1f}",
                     "-" if p is None else f"{p['success_rate']} / {p['t_ave_ms']} / {p['t_star_ave_ms']} / {p['steps_star']}"])
    print(table(["robot", "task", "init (solver)", "success %", "T_ave ms", "T*_ave ms", "steps*",
                 "paper: success / T_ave / T* / steps*"], rows))


def add_arguments(p: argparse.ArgumentParser) -> None:
    A.add_robot_and_task(p, "the paper's two tasks (panda, talos)")
    p.add_argument("--init", choices=INITS, default="uniform", help="initial configurations")
    p.add_argument("--tasks", type=A.positive_int, default=500, help="tasks per kind (projection, IK)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--seeds", type=A.seed_range, default=None, metavar="A..B",
                   help="a sweep: one run per seed A..B (both included), per-seed rows and their median")
    A.add_executor_arguments(p, "with --seeds: seeds run at once (default 1: one after the other, so that "
                                "times are not shared)")
    p.add_argument("--solver", choices=SOLVERS, default="gauss-newton")
    p.add_argument("--backend", choices=P.BACKENDS, default="native", help="Gauss-Newton implementation")
    p.add_argument("--model", type=A.existing_file, default=None,
                   help="GAN model file for --init gan (default: the shipped one)")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


#: what a sweep keeps once (the same for every seed) rather than in each seed's row
SHARED = ("benchmark", "robot", "robot_argument", "task", "init", "solver", "backend", "tasks", "units",
          "ik_target_box", "settings", "task_terms", "machine", "paper")


def run_seed(job: dict[str, Any]) -> dict[str, Any]:
    """One seed of a sweep (a shard: module-level, so that a process or Ray worker can run it)."""
    return run(**job, progress=False)


def sweep(args: argparse.Namespace) -> dict[str, Any]:
    """``--seeds A..B``: :func:`run` per seed on the execution layer, the per-seed results and
    their median across seeds."""
    from genplan.experiments.sweeps import median_of, run_seeds

    jobs = [dict(robot_name=args.robot, init=args.init, tasks=args.tasks, seed=s, solver=args.solver,
                 backend=args.backend, model_path=args.model, task=args.task) for s in args.seeds]
    # the native Gauss-Newton releases the GIL (threads); scipy and the Python backend hold it
    kind = "thread" if args.solver == "gauss-newton" and args.backend == "native" else "process"
    runs, ex = run_seeds(run_seed, jobs, workers=args.workers, ray=args.ray, kind=kind,
                         desc=f"bench projection ({args.robot})")
    per_seed = [{k: v for k, v in r.items() if k not in SHARED} for r in runs]
    return {**{k: runs[0][k] for k in SHARED}, "seeds": list(args.seeds), "executor": ex,
            "per_seed": per_seed, "aggregate_rule": "median across seeds",
            "aggregate": {kind: median_of([r[kind] for r in runs]) for kind in P.TASK_KINDS}}


def print_sweep(payload: dict[str, Any]) -> None:
    rows = []
    for r in [*payload["per_seed"], {"seed": "median", **payload["aggregate"]}]:
        for kind in P.TASK_KINDS:
            x = r[kind]
            rows.append([r["seed"], kind, f"{x['success_rate']:.1f}", f"{x['t_ave_ms']:.3f}",
                         "-" if x.get("t_star_ave_ms") is None else f"{x['t_star_ave_ms']:.3f}",
                         "-" if x.get("steps_star") is None else f"{x['steps_star']:.1f}"])
    print(f"{payload['robot']}, {payload['init']} ({payload['solver']}), {payload['tasks']} tasks per seed")
    print(table(["seed", "task", "success %", "T_ave ms", "T*_ave ms", "steps*"], rows))


def main(args: argparse.Namespace) -> int:
    if args.seeds is not None:
        payload = sweep(args)
        print_sweep(payload)
        write_json(args.out, payload)
        return 0
    if args.workers is not None or args.ray is not None:
        raise A.UsageError("--workers/--ray: they run the seeds of --seeds A..B; give --seeds")
    payload = run(args.robot, args.init, args.tasks, args.seed, args.solver, args.backend, args.model, args.task)
    print_table(payload)
    write_json(args.out, payload)
    return 0
