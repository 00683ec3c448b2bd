"""Table II of the GAN paper: constrained RRT with uniform, GAN and hybrid sampling, and OMPL.

    genplan bench plan --env panda_shelf --sampler gan --queries 100 --seed 0 --out F.json
    genplan bench plan --env all --sampler all --planner all --queries 100 --out F.json
    genplan bench plan --env panda_shelf --sampler gan --seeds 0..4 --out F.json   # per-seed + medians
    genplan bench plan --env all --sampler all --algorithm all --queries 100 --out F.json
    genplan bench plan --env all --model panda=P.safetensors --model talos=T.safetensors --out F.json

``--model ROBOT=FILE`` plans that robot's environments with another learned sampler's file (a GAN
or a flow, genplan.samplers.load_sampler_model) for the gan, hybrid and adaptive rows; the JSON names
each file and its weights' hash.

``--algorithm`` picks genplan's search: ``crrt`` (the paper's constrained RRT, default),
``rrt_connect`` (bidirectional, on the same constrained space and components) or ``all`` (both,
on the same queries; each row names its ``algorithm``, and ``ratios_by_algorithm`` holds the
ratios of each, ``ratios`` those of the first).

With ``--seeds A..B`` each seed is a run of its own (its queries and planner seeds; a shard on
genplan.executor, one after the other unless ``--workers K`` or ``--ray``): the JSON holds every
seed's rows (``per_seed``) and, per (env, planner, sampler), their median across seeds
(``aggregate``); see genplan.experiments.sweeps.

Every row of one run plans the same seeded queries (start + K = 10 goal configurations by IK,
the same for every sampler and planner), on one core, with the same constraint (the paper's
projection task) and the same collision model (parry, self-collision included). Columns as the
paper's: success %, T_ave (s, all queries, retries included), Opt. Steps (projection iterations
of samples and extension steps) and E (extension steps); genplan also validates every edge of
the returned path (projected states 0.025 rad apart), counted separately; ``--edge-resolution 0``
times the paper's protocol (tree nodes checked, edges not validated); ``--edge-check certified``
certifies every motion between those states collision-free as well (conservative advancement,
``PlannerSettings.edge_check``; the settings go into the JSON).

``--checker`` picks genplan's validity checker (``genplan.planning.CHECKERS``): ``exact`` (the
world's geometry, default), ``spheres`` (the robot's covering spheres; ``--sphere-max-error M``
for a cover other than ``genplan.spheres``' default), ``hybrid`` (the spheres, each collision
they find confirmed by the exact geometry), several joined by commas (``exact,hybrid``) or
``all`` (every one on the same queries, the
checkers alternating query by query, the first of a query's plans taking turns). A query whose
start, or every goal, a sphere checker refuses (the cover reaches up to ``max_error`` beyond the
geometry, so a configuration millimetres from an obstacle collides) is not planned: the row lists
it in ``refused_queries`` and counts it as failed; its times and counts are over the queries
planned. With ``all``, each sphere row's ``vs_exact`` holds both checkers' mean and median times
on the queries both planned and their ratios (exact over spheres).

The peer (``--planner ompl``) is OMPL's ProjectedStateSpace with RRTConnect (PyPI ``ompl``),
whose constraint and validity callbacks run in Python (genplan's Pinocchio terms and parry
world): its time is reported in full and without the callbacks' share. Its "projections" are
calls to OMPL's Newton projection, not iterations.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from genplan.cli import args as A
from genplan.experiments.common import geometric_mean, machine, table, write_json

#: Table II of the GAN paper: (success %, T_ave s, Opt. Steps, E).
PAPER_TABLE_II: dict[tuple[str, str], tuple[float, float, float, float]] = {
    ("panda_shelf", "uniform"): (100.0, 1.44, 2065.7, 116.5),
    ("panda_shelf", "gan"): (99.0, 0.74, 902.5, 59.7),
    ("panda_shelf", "hybrid"): (100.0, 0.90, 1200.3, 68.1),
    ("talos_task1", "uniform"): (100.0, 1.20, 464.4, 16.2),
    ("talos_task1", "gan"): (100.0, 0.28, 74.0, 10.2),
    ("talos_task1", "hybrid"): (100.0, 0.43, 131.4, 13.5),
    ("talos_task2", "uniform"): (100.0, 0.92, 327.8, 13.9),
    ("talos_task2", "gan"): (100.0, 0.60, 127.0, 36.7),
    ("talos_task2", "hybrid"): (100.0, 0.66, 182.3, 25.9),
    ("talos_task3", "uniform"): (100.0, 3.94, 1154.0, 98.7),
    ("talos_task3", "gan"): (100.0, 1.05, 179.0, 52.1),
    ("talos_task3", "hybrid"): (100.0, 1.11, 228.7, 40.8),
}

ENVS = ("panda_shelf", "talos_task1", "talos_task2", "talos_task3")
SAMPLERS = ("uniform", "gan", "hybrid")
#: beyond the paper: the adaptive hybrid and the data set's rows (genplan.planning.make_sampler,
#: data_sampler); --sampler adaptive or data, or --sampler all+ for the paper's three and these
EXTRA_SAMPLERS = ("adaptive", "data")
PLANNERS = ("genplan", "ompl")


def checker_list(value: str) -> list[str]:
    """``--checker``: one of ``genplan.planning.CHECKERS``, several joined by commas (taking turns
    on the same queries), or ``all``; argparse's error names an unknown one with the known ones."""
    from genplan.planning import CHECKERS

    if value == "all":
        return list(CHECKERS)
    names = value.split(",")
    unknown = [n for n in names if n not in CHECKERS]
    if unknown or len(set(names)) != len(names) or not names:
        raise argparse.ArgumentTypeError(
            f"{value!r}: expected one of {', '.join(CHECKERS)}, several joined by commas (each once), or all")
    return names


def checkers(args: argparse.Namespace) -> list[str]:
    """genplan's validity checkers of ``--checker``."""
    return list(args.checker)


def algorithms(args: argparse.Namespace) -> list[str]:
    """genplan's search algorithms of ``--algorithm``: one, or every one for ``all``."""
    from genplan.planning import ALGORITHMS

    return list(ALGORITHMS) if args.algorithm == "all" else [args.algorithm]


def _summary(times: list[float], success: list[bool], **extra: list[float]) -> dict[str, Any]:
    t = np.asarray(times, dtype=np.float64)
    out: dict[str, Any] = {
        "queries": len(t),
        "success_rate": 100.0 * float(np.mean(success)),
        # which queries failed (their indices in the environment's seeded query list), so a
        # failure can be replayed: benches/hard_queries.py, Planner.plan(queries[i].start, ...)
        "failed_queries": [i for i, ok in enumerate(success) if not ok],
        "t_ave_s": float(t.mean()),
        "t_std_s": float(t.std()),
        "t_median_s": float(np.median(t)),
    }
    for k, v in extra.items():
        a = np.asarray(v, dtype=np.float64)
        out[k] = float(a.mean())
        out[f"{k}_std"] = float(a.std())
    return out


def run_genplan(env_name: str, sampler: str, queries: list[Any], seed: int, settings: Any, progress: bool,
                algorithm: str = "crrt", model: str | None = None, checker: str = "exact",
                sphere_max_error: float | None = None) -> dict[str, Any]:
    """One Table II row: ``sampler``'s plans of ``queries`` with ``checker``."""
    return run_checkers(env_name, sampler, queries, seed, settings, progress, algorithm, model, [checker],
                        sphere_max_error)[0]


def _checker(robot: Any, world: Any, checker: str, sphere_max_error: float | None) -> Any:
    """What ``Planner(checker=)`` takes for ``checker``: its name, or the sphere checker of a cover
    at ``sphere_max_error``."""
    if checker == "exact" or sphere_max_error is None:
        return checker
    from genplan.planning import sphere_checker
    from genplan.spheres import robot_spheres

    return sphere_checker(robot, world, spheres=robot_spheres(robot, max_error=sphere_max_error), confirm=checker == "hybrid")


def run_checkers(env_name: str, sampler: str, queries: list[Any], seed: int, settings: Any, progress: bool,
                 algorithm: str = "crrt", model: str | None = None, checkers: list[str] | None = None,
                 sphere_max_error: float | None = None) -> list[dict[str, Any]]:
    """One Table II row per checker of ``checkers`` (default exact): ``sampler``'s plans of
    ``queries``, the checkers alternating query by query (each with its own planner and seed),
    the first to plan a query taking turns, so that a change of the machine's load falls on every
    checker alike. A query a non-exact checker refuses (its start, or every goal, invalid) is
    listed in the row's ``refused_queries`` and counted as failed; the exact checker refusing one
    is an error (the queries are made valid for it). GenplanError when a checker refuses them all."""
    import genplan
    from genplan.errors import InvalidGoalError, InvalidStartError
    from genplan.planning import Planner, environment
    from genplan.samplers.loading import load_sampler_model

    checkers = checkers or ["exact"]
    env = environment(env_name)
    robot = genplan.load(env.robot)
    learned = None if model is None or sampler in ("uniform", "data") else load_sampler_model(robot, model)
    planners = {}
    for c in checkers:
        world = env.world(robot)
        planners[c] = Planner(robot, world=world, sampler=sampler, settings=settings, seed=seed, algorithm=algorithm,
                              gan_model=learned, checker=_checker(robot, world, c, sphere_max_error))
    results: dict[str, dict[int, Any]] = {c: {} for c in checkers}
    refused: dict[str, list[int]] = {c: [] for c in checkers}
    refusal: dict[str, Exception] = {}
    it: Any = queries
    if progress:
        from tqdm import tqdm

        it = tqdm(queries, desc=f"{env_name} {algorithm} {sampler} {'/'.join(checkers)}", unit="query", leave=False)
    for i, q in enumerate(it):
        turn = i % len(checkers)
        for c in checkers[turn:] + checkers[:turn]:
            try:
                results[c][i] = planners[c].plan(q.start, q.goals)
            except (InvalidStartError, InvalidGoalError) as e:
                if c == "exact":
                    raise
                refused[c].append(i)
                refusal[c] = e
    rows = []
    for c in checkers:
        if not results[c]:
            raise InvalidStartError(f"checker {c!r}: every query of {env_name} refused ({len(queries)}), "
                                    f"the last: {refusal[c]}")
        planned = sorted(results[c])
        row = summarize_plans([results[c][i] for i in planned])
        row.update(env=env_name, planner="genplan", sampler=sampler, algorithm=algorithm, checker=c)
        if c != "exact":
            row.update(queries=len(queries), planned=len(planned), refused_queries=refused[c],
                       success_rate=100.0 * sum(results[c][i].success for i in planned) / len(queries),
                       failed_queries=sorted([planned[j] for j in row["failed_queries"]] + refused[c]))
            if c != "exact" and sphere_max_error is not None:
                row["sphere_max_error_m"] = sphere_max_error
        rows.append(row)
    if "exact" in checkers:
        for row in rows:
            if row["checker"] != "exact":
                both = sorted(set(results["exact"]) & set(results[row["checker"]]))
                te = np.array([results["exact"][i].time_s for i in both])
                tc = np.array([results[row["checker"]][i].time_s for i in both])
                row["vs_exact"] = {
                    "queries": len(both),
                    "exact_success_rate": 100.0 * float(np.mean([results["exact"][i].success for i in both])),
                    "success_rate": 100.0 * float(np.mean([results[row["checker"]][i].success for i in both])),
                    "exact_t_ave_s": float(te.mean()), "t_ave_s": float(tc.mean()),
                    "exact_t_median_s": float(np.median(te)), "t_median_s": float(np.median(tc)),
                    "exact_over_checker_t_ave": float(te.mean() / tc.mean()),
                    "exact_over_checker_t_median": float(np.median(te) / np.median(tc)),
                }
    return rows


def summarize_plans(results: list[Any]) -> dict[str, Any]:
    """One Table II row of a sampler's plans (``PlanResult``s): success rate, time statistics and
    the means (and standard deviations) of the search's counts."""
    return _summary(
        [r.time_s for r in results],
        [r.success for r in results],
        projections=[r.projections for r in results],
        extensions=[r.extensions for r in results],
        edge_projections=[r.stats.edge_projections for r in results],
        retries=[r.retries for r in results],
        nodes=[r.stats.nodes for r in results],
        path_states=[len(r.path) for r in results if r.success] or [0],
        projector_s=[r.stats.projector_s for r in results],
        checker_s=[r.stats.checker_s for r in results],
        sampler_s=[r.stats.sampler_s for r in results],
        motion_certificates=[r.stats.motion_certificates for r in results],
    )


def run_ompl(env_name: str, queries: list[Any], seed: int, time_limit: float, progress: bool) -> dict[str, Any]:
    import genplan
    from genplan.experiments.peers.ompl import plan_ompl
    from genplan.planning import environment
    from genplan.projection import paper_task

    env = environment(env_name)
    robot = genplan.load(env.robot)
    world = env.world(robot)
    task = paper_task(robot, "projection")
    results = []
    it = queries
    if progress:
        from tqdm import tqdm

        it = tqdm(queries, desc=f"{env_name} ompl", unit="query", leave=False)
    for i, q in enumerate(it):
        results.append(plan_ompl(robot, world, task, q.start, q.goals, time_limit=time_limit, seed=seed + i))
    row = _summary(
        [r.time_s for r in results],
        [r.success for r in results],
        projections=[r.projections for r in results],
        callback_s=[r.callback_s for r in results],
        setup_s=[r.setup_s for r in results],
    )
    row.update(env=env_name, planner="ompl", sampler="ProjectedStateSpace+RRTConnect", time_limit_s=time_limit,
               t_ave_without_callbacks_s=float(np.mean([r.time_s - r.callback_s for r in results])),
               extensions=None, statuses=sorted({r.status for r in results}))
    return row


def _ratios(rows: list[dict[str, Any]], envs: list[str], algorithm: str, checker: str = "exact") -> dict[str, Any]:
    """Per environment: uniform / GAN, uniform / hybrid (and adaptive, data) of ``algorithm``'s rows
    with ``checker``, OMPL over each sampler."""
    ratios: dict[str, Any] = {}
    for env_name in envs:
        by = {(r["planner"], r["sampler"]): r for r in rows
              if r["env"] == env_name and (r["planner"] == "ompl" or (r.get("algorithm", "crrt") == algorithm
                                                                     and r.get("checker", "exact") == checker))}
        u, g, h = (by.get(("genplan", s)) for s in SAMPLERS)
        o = next((r for r in rows if r["env"] == env_name and r["planner"] == "ompl"), None)
        ratios[env_name] = {
            "uniform_over_gan": None if not (u and g) else u["t_ave_s"] / g["t_ave_s"],
            "uniform_over_hybrid": None if not (u and h) else u["t_ave_s"] / h["t_ave_s"],
            "ompl_over_gan": None if not (o and g) else o["t_ave_s"] / g["t_ave_s"],
            "ompl_over_hybrid": None if not (o and h) else o["t_ave_s"] / h["t_ave_s"],
            "ompl_over_uniform": None if not (o and u) else o["t_ave_s"] / u["t_ave_s"],
        }
        for extra in EXTRA_SAMPLERS:
            x = by.get(("genplan", extra))
            if x is not None:
                ratios[env_name][f"uniform_over_{extra}"] = None if not u else u["t_ave_s"] / x["t_ave_s"]
    return ratios


def run(envs: list[str], samplers: list[str], planners: list[str], n: int, seed: int, ompl_time_limit: float,
        settings: Any = None, progress: bool = True, algorithms: list[str] | None = None,
        models: dict[str, str] | None = None, checkers: list[str] | None = None,
        sphere_max_error: float | None = None) -> dict[str, Any]:
    """Table II's rows for ``envs``; ``models`` maps a robot's name to the learned sampler's file
    its environments use (default: the shipped GAN); ``checkers``: genplan's validity checkers
    (default exact; several: :func:`run_checkers`)."""
    import genplan
    from genplan.planning import PlannerSettings, environment

    settings = settings or PlannerSettings()
    algorithms = algorithms or [settings.algorithm]
    checkers = checkers or ["exact"]
    rows = []
    query_s = {}
    for env_name in envs:
        env = environment(env_name)
        robot = genplan.load(env.robot)
        t0 = time.perf_counter()
        queries = env.queries(robot, n, seed=seed, progress=progress)
        query_s[env_name] = time.perf_counter() - t0
        if "genplan" in planners:
            for alg in algorithms:
                for s in samplers:
                    rows.extend(run_checkers(env_name, s, queries, seed, settings, progress, alg,
                                             (models or {}).get(env.robot), checkers, sphere_max_error))
        if "ompl" in planners:
            rows.append(run_ompl(env_name, queries, seed, ompl_time_limit, progress))
    for r in rows:
        paper = PAPER_TABLE_II.get((r["env"], r["sampler"]))
        r["paper"] = None if paper is None else dict(zip(("success_rate", "t_ave_s", "projections", "extensions"), paper))
    by_algorithm = {alg: _ratios(rows, envs, alg, checkers[0]) for alg in algorithms}
    return {
        "benchmark": "plan",
        "queries": n,
        "seed": seed,
        "goals_per_query": 10,
        "settings": settings.to_dict(),
        "algorithms": algorithms,
        "checkers": checkers,
        "sphere_max_error_m": sphere_max_error,
        "models": model_files(models or {}),
        "ompl_time_limit_s": ompl_time_limit,
        "query_generation_s": query_s,
        "units": {"t_*": "seconds per query (all queries, retries included)", "success_rate": "percent",
                  "projections": "genplan: projection iterations (samples + extension steps); ompl: projection calls",
                  "extensions": "extension steps (iterations)"},
        "machine": machine(),
        "rows": rows,
        "ratios": by_algorithm[algorithms[0]],
        "ratios_by_algorithm": by_algorithm,
    }


def print_table(payload: dict[str, Any]) -> None:
    out = []
    for r in payload["rows"]:
        p = r["paper"]
        out.append([r["env"], r.get("algorithm", "-"), r.get("checker", "-"), r["planner"] if r["planner"] == "ompl" else r["sampler"], f"{r['success_rate']:.1f}",
                    f"{r['t_ave_s']:.3f} ± {r['t_std_s']:.3f}", f"{r['t_median_s']:.3f}", f"{r['projections']:.1f}",
                    "-" if r.get("extensions") is None else f"{r['extensions']:.1f}",
                    "-" if p is None else f"{p['success_rate']} / {p['t_ave_s']} / {p['projections']} / {p['extensions']}"])
    print(table(["env", "algorithm", "checker", "sampler", "success %", "T_ave s", "T_median s", "Opt. steps", "E",
                 "paper: success / T_ave / steps / E"], out))
    for r in payload["rows"]:
        v = r.get("vs_exact")
        if v:
            print(f"{r['env']} {r['sampler']} {r.get('algorithm', '-')}: {r['checker']} on the {v['queries']} queries "
                  f"both planned: mean {v['exact_t_ave_s']:.4f} -> {v['t_ave_s']:.4f} s "
                  f"({v['exact_over_checker_t_ave']:.2f}x), median {v['exact_t_median_s']:.4f} -> {v['t_median_s']:.4f} s "
                  f"({v['exact_over_checker_t_median']:.2f}x); {len(r['refused_queries'])} refused")
    for alg, ratios in payload["ratios_by_algorithm"].items():
        for env, rat in ratios.items():
            parts = [f"{k} {v:.2f}x" for k, v in rat.items() if v is not None]
            if parts:
                print(f"{alg} {env}: " + ", ".join(parts))
        gm = [rat["uniform_over_gan"] for rat in ratios.values() if rat.get("uniform_over_gan")]
        if len(gm) > 1:
            print(f"{alg}: uniform_over_gan geometric mean over {len(gm)} environments {geometric_mean(gm):.2f}x")


def model_files(models: dict[str, str]) -> dict[str, Any]:
    """``--model``'s files as the JSON records them: robot -> file and weights' sha256 (its card's)."""
    from genplan.model_files import peek_card

    out: dict[str, Any] = {}
    for robot, path in models.items():
        card = peek_card(path) or {}  # the planner loaded the file: its card was checked then
        out[robot] = {"file": str(path), "format": card.get("format"), "weights_sha256": card.get("weights_sha256")}
    return out


def model_option(text: str) -> tuple[str, str]:
    """``--model ROBOT=FILE``: a preset robot of the environments and an existing file."""
    from genplan.planning import environment

    robot, sep, path = text.partition("=")
    robots = sorted({environment(e).robot for e in ENVS})
    if not sep or robot not in robots:
        raise argparse.ArgumentTypeError(f"expected ROBOT=FILE with ROBOT among {', '.join(robots)}, got {text!r}")
    return robot, str(A.existing_file(path))


def run_seed(job: dict[str, Any]) -> dict[str, Any]:
    """One seed of a sweep (a shard: module-level, so that a process or Ray worker can run it)."""
    return run(**job, progress=False)


def sweep(envs: list[str], samplers: list[str], planners: list[str], args: argparse.Namespace,
          settings: Any) -> dict[str, Any]:
    """``--seeds A..B``: :func:`run` per seed on the execution layer; per-seed rows and, per
    (env, planner, sampler), their median across seeds."""
    from genplan.experiments.sweeps import median_of, run_seeds

    jobs = [dict(envs=envs, samplers=samplers, planners=planners, n=args.queries, seed=s,
                 ompl_time_limit=args.ompl_time_limit, settings=settings, algorithms=algorithms(args),
                 models=dict(args.model or []), checkers=checkers(args), sphere_max_error=args.sphere_max_error)
            for s in args.seeds]
    # genplan's planner releases the GIL (threads); OMPL's callbacks run in Python (processes)
    runs, ex = run_seeds(run_seed, jobs, workers=args.workers, ray=args.ray,
                         kind="process" if "ompl" in planners else "thread", desc="bench plan")
    def key_of(r: dict[str, Any]) -> tuple[str, str, str, str, str]:
        return r["env"], r["planner"], r["sampler"], r.get("algorithm", "-"), r.get("checker", "-")

    keys = [key_of(r) for r in runs[0]["rows"]]
    aggregate = []
    for key in keys:
        same = [next(r for r in run_["rows"] if key_of(r) == key) for run_ in runs]
        row = {**median_of(same), "env": key[0], "planner": key[1], "sampler": key[2], "paper": same[0]["paper"]}
        if key[3] != "-":
            row["algorithm"] = key[3]
        if key[4] != "-":
            row["checker"] = key[4]
        aggregate.append(row)
    shared = ("benchmark", "queries", "goals_per_query", "settings", "ompl_time_limit_s", "units", "machine")
    return {**{k: runs[0][k] for k in shared}, "seeds": list(args.seeds), "executor": ex,
            "per_seed": [{k: v for k, v in r.items() if k not in shared} for r in runs],
            "aggregate_rule": "median across seeds", "aggregate": aggregate,
            "aggregate_ratios": {env: median_of([r["ratios"][env] for r in runs]) for env in envs}}


def print_sweep(payload: dict[str, Any]) -> None:
    out = []
    for r in [*payload["per_seed"], {"seed": "median", "rows": payload["aggregate"]}]:
        for x in r["rows"]:
            out.append([r["seed"], x["env"], x.get("algorithm", "-"), x["planner"] if x["planner"] == "ompl" else x["sampler"],
                        f"{x['success_rate']:.1f}", f"{x['t_ave_s']:.3f}", f"{x['projections']:.1f}",
                        "-" if x.get("extensions") is None else f"{x['extensions']:.1f}"])
    print(table(["seed", "env", "algorithm", "sampler", "success %", "T_ave s", "Opt. steps", "E"], out))


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.planning import ALGORITHMS, CHECKERS, EDGE_CHECKS

    p.add_argument("--env", default="all", choices=[*ENVS, "all"])
    p.add_argument("--sampler", default="all", choices=[*SAMPLERS, *EXTRA_SAMPLERS, "all", "all+"],
                   help="all: the paper's uniform, gan and hybrid; all+: those, adaptive and data (default all)")
    p.add_argument("--planner", default="genplan", choices=[*PLANNERS, "all"])
    p.add_argument("--algorithm", default="crrt", choices=[*ALGORITHMS, "all"],
                   help="genplan's search: crrt (the paper's constrained RRT, default), rrt_connect, or all (both)")
    p.add_argument("--queries", type=A.positive_int, default=100, help="queries per environment (the paper: 100)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--seeds", type=A.seed_range, default=None, metavar="A..B",
                   help="a sweep: one run per seed A..B (both included), per-seed rows and their median")
    A.add_executor_arguments(p, "with --seeds: seeds run at once (default 1: one after the other, so that "
                                "times are not shared)")
    p.add_argument("--ompl-time-limit", type=A.positive_float, default=30.0, help="seconds per OMPL query")
    p.add_argument("--edge-resolution", type=A.non_negative_float, default=None,
                   help="genplan edge validation spacing (0: off)")
    p.add_argument("--edge-check", default="sampled", choices=EDGE_CHECKS,
                   help="genplan edges: states checked at the resolution (sampled, default) or every motion between "
                        "them certified collision-free (certified, PlannerSettings.edge_check)")
    p.add_argument("--checker", default=["exact"], type=checker_list, metavar="|".join([*CHECKERS, "all"]),
                   help="genplan's validity checker: exact (the world's geometry, default), spheres (the robot's "
                        "covering spheres), hybrid (the spheres, their collisions confirmed by the exact geometry), "
                        "several joined by commas, or all (each on the same queries, alternating)")
    p.add_argument("--sphere-max-error", type=A.positive_float, default=None, metavar="M",
                   help="with --checker spheres or all: the sphere cover's max_error in m (default: genplan.spheres')")
    p.add_argument("--model", type=model_option, action="append", default=None, metavar="ROBOT=FILE",
                   help="the learned sampler's file (GAN or flow) for ROBOT's environments (repeatable; default: "
                        "the shipped GAN)")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


def main(args: argparse.Namespace) -> int:
    from genplan.planning import PlannerSettings

    envs = list(ENVS) if args.env == "all" else [args.env]
    samplers = {"all": list(SAMPLERS), "all+": [*SAMPLERS, *EXTRA_SAMPLERS]}.get(args.sampler, [args.sampler])
    planners = list(PLANNERS) if args.planner == "all" else [args.planner]
    if args.sphere_max_error is not None and checkers(args) == ["exact"]:
        raise A.UsageError("--sphere-max-error: it sets the sphere checker's cover; give --checker spheres, hybrid or all")
    if args.edge_check == "certified" and checkers(args) != ["exact"]:
        raise A.UsageError("--edge-check certified: it needs the exact checker (the spheres certify no motion); "
                           "give --checker exact")
    settings = PlannerSettings(edge_check=args.edge_check)
    if args.edge_resolution is not None:
        settings = settings.replace(edge_resolution=args.edge_resolution)
    if args.seeds is not None:
        payload = sweep(envs, samplers, planners, args, settings)
        print_sweep(payload)
        write_json(args.out, payload)
        return 0
    if args.workers is not None or args.ray is not None:
        raise A.UsageError("--workers/--ray: they run the seeds of --seeds A..B; give --seeds")
    payload = run(envs, samplers, planners, args.queries, args.seed, args.ompl_time_limit, settings,
                  algorithms=algorithms(args), models=dict(args.model or []), checkers=checkers(args),
                  sphere_max_error=args.sphere_max_error)
    print_table(payload)
    write_json(args.out, payload)
    return 0
