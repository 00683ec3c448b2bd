"""Adapt a learned family of motions to new goals and obstacles: the seq2seq
paper's latent adjustment on a robot's joint-space family, against direct optimisation of the same
objective, replanning from scratch, and ProMP conditioning.

    genplan bench adapt --model M.safetensors --data DIR --held-out DIR2 --problems 200 --out benches/results/adapt_panda.json

Problems: the end targets are the family's frame at the ends of ``--held-out`` trajectories (a
data set made like the training data with another seed: goals inside the data's range, each one
reachable and collision-free, none seen in training; the first ``--problems`` of them, or those
after the first ``--skip``: a check on problems a tuning run did not see); each
problem's input is the training data's trajectory whose end is nearest its target, and starts
where that trajectory starts. Rows:

* **latent**: ``genplan.seq2seq.adjust`` (method "latent", ``--updates`` updates, the batch of
  all problems at once) on the objective end position + joint limits + staying near the input,
  then ``result.finish()`` (projection onto the task's manifold with the end target, dense checks
  against the data's scene, TOPP-RA). A success is a finished trajectory: end within 1 mm, the
  task's residual within its tolerance along the timed samples, no collision. Time per problem:
  (adjustment + finish) / problems.
* **direct**: the same objective, the same starts, optimising the decoder's output itself (the
  paper's case 3) for ``--direct-updates``; the updates (and time) each problem needs to reach the
  objective value the latent method reached, as a ratio to the latent's (the paper's Fig. 5).
* **replanning**: genplan's constrained RRT-Connect from the same start to the goal configuration
  the latent method reached, then TOPP-RA (``--replan`` problems): success and time per problem.
* **ProMP** (movement-primitives, ``pip install movement-primitives``): trained on the same data,
  conditioned on the same start and goal configurations; its mean trajectory densified linearly
  to the finish's resolution and checked as genplan's are (residual, collisions, end).
* **obstacle**: a sphere of ``--obstacle-radius`` placed on each input's path at mid-time (the
  frame's position there), the target the input's own end; the objective adds the clearance from
  that sphere; success: finished (as above) against the scene plus the sphere. The row records how
  many inputs cross the sphere, how many start inside it (another link than the frame there at
  the start: no motion from that start is clear of it) and how many end inside it (the input's
  last configuration: the frame's target is outside the sphere, but the arm must reach it another
  way). Such an input is bent (``genplan.seq2seq.adjust.aim_inputs``) to end at a clear
  configuration with the frame at the same position (``clear_ends``: the end walked along its
  self-motion, or IK from guesses around it and uniform ones), and the adjustment starts from the
  bent input: ``ends_reaimed`` of them (``reaimed_success_percent`` of those succeed,
  ``median_end_move_rad`` the joint distance to the new end; ``ends_without_clear_configuration``:
  none found), ``clear_ends_ms_per_problem`` its time over all problems, inside
  ``ms_per_problem``. The trajectory is still the latent adjustment's. ``success_percent`` counts
  every problem (those starting inside the sphere as failures); ``free_success_percent`` counts
  only the problems whose input starts and ends clear of it (``free_problems`` of them). A problem
  its first start leaves inside the sphere runs ``--obstacle-starts`` starts in all; with
  ``--obstacle-pool data`` (the default) its restarts start from the ``--data`` trajectories
  near its input that score best on the objective (``genplan.adjust``'s ``pool``), with ``none``
  from the random spread around the first start (``restarted_problems``, ``success_from_restart``).
"""

from __future__ import annotations

import argparse
import os
import re
import time
from typing import Any

import numpy as np

from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json

#: EM iterations of ProMP's imitation and the demonstrations it sees (movement-primitives' EM inverts two
#: (7 x 20)-square matrices per demonstration and iteration: its default of 1000 iterations on 2,000
#: demonstrations would take hours here; the mean and covariance that conditioning uses settle in a few
#: iterations on a few hundred)
PROMP_ITERATIONS = 10
PROMP_DEMONSTRATIONS = 300
#: the obstacle case's Adam learning rate (latent units)
OBSTACLE_LR = 0.02
#: the obstacle case's starts per problem (see genplan.seq2seq.adjust.adjust's ``starts``)
OBSTACLE_STARTS = 8
#: the benchmark's rows (``--rows`` runs some of them)
ROWS = ("latent", "direct", "replanning", "promp", "obstacle")
#: the targets on held-out problems (printed beside the rows)
TARGETS = {"success_percent": 95.0, "end_error_mm": 1.0, "ms_per_problem": 20.0, "obstacle_success_percent": 90.0}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", type=A.existing_file, required=True, help="a joint-space seq2seq model (.safetensors)")
    p.add_argument("--data", type=A.existing_folder, required=True, help="its trajectory data set (genplan data trajectories)")
    p.add_argument("--held-out", type=A.existing_folder, required=True,
                   help="a trajectory data set made like --data with another seed: the problems' goals (tune on another)")
    p.add_argument("--problems", type=A.positive_int, default=200)
    p.add_argument("--skip", type=A.non_negative_int, default=0,
                   help="leave out the first SKIP held-out trajectories (problems SKIP .. SKIP+PROBLEMS-1: a run on "
                        "problems another run did not see)")
    p.add_argument("--updates", type=A.positive_int, default=40, help="latent updates")
    p.add_argument("--direct-updates", type=A.positive_int, default=400, help="updates of the direct method")
    p.add_argument("--replan", type=A.non_negative_int, default=50, help="problems replanned from scratch")
    p.add_argument("--obstacle-radius", type=A.positive_float, default=0.05, help="the obstacle sphere's radius (m)")
    p.add_argument("--obstacle-updates", type=A.positive_int, default=400,
                   help="updates of the obstacle case (Adam, lr OBSTACLE_LR: a detour is a larger change than a new goal)")
    p.add_argument("--obstacle-starts", type=A.positive_int, default=OBSTACLE_STARTS,
                   help="starts per problem of the obstacle case (genplan.adjust's starts: a problem whose first start "
                        "leaves a clearance term positive runs again from the others)")
    p.add_argument("--obstacle-start-spread", type=A.positive_float, default=None,
                   help="the spread of the obstacle case's other starts around the first (latent units; default "
                        "genplan.adjust's start_spread)")
    p.add_argument("--obstacle-pool", choices=("data", "none"), default="data",
                   help="what the obstacle case's restarts may start from besides the random spread: 'data' the "
                        "--data trajectories (genplan.adjust's pool), 'none' the spread alone")
    p.add_argument("--no-promp", action="store_true", help="skip the ProMP row")
    p.add_argument("--rows", type=_rows, default=ROWS,
                   help=f"the rows to run, comma-separated, of {','.join(ROWS)} (default: all; replanning and ProMP "
                        "start from the latent row's goals and run only with it)")
    p.add_argument("--out", type=A.output_file, default=None)


def _rows(text: str) -> tuple[str, ...]:
    rows = tuple(r.strip() for r in text.split(",") if r.strip())
    unknown = sorted(set(rows) - set(ROWS))
    if unknown or not rows:
        raise argparse.ArgumentTypeError(f"rows must be some of {','.join(ROWS)}, got {text!r}")
    return rows


def objective(frame: str, *, obstacle: bool = False) -> Any:
    """The benchmark's objective: the frame's end position (1e4 / m^2), the joint limits, staying
    near the input (the family's shape); with ``obstacle`` also the clearance from a sphere given
    per problem (4 cm), from the scene (3 cm) and of the arm from itself (1 cm), and the task's
    residuals (the arm leaves its family there, and the finish's projection must not undo the
    detour)."""
    from genplan.seq2seq.objectives import (AvoidSpheres, Clearance, Constraint, EndPosition, JointLimits, Objective,
                                            SelfClearance, StayNear)

    terms = [EndPosition(1e4, frame=frame), JointLimits(100.0, margin=0.01), StayNear(0.1)]
    if obstacle:
        terms += [Constraint(10.0), AvoidSpheres(1e4, margin=0.04), Clearance(1e4, margin=0.03),
                  SelfClearance(1e4, margin=0.01)]
    return Objective(terms, name="reach" + ("_avoid" if obstacle else ""))


def problems(data: Any, held_out: Any, robot: Any, frame: str, n: int,
             skip: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(targets (n, 3), inputs (n, K, nq), indices into the data) of ``n`` problems: the frame's
    positions at the ends of the held-out trajectories ``skip`` .. ``skip + n - 1``, each with the
    data's trajectory whose end is nearest."""
    from scipy.spatial import cKDTree

    if skip + n > len(held_out):
        raise A.UsageError(f"--problems, --skip: the held-out set has {len(held_out)} trajectories, fewer than "
                           f"{skip} + {n}")
    targets = robot.frame_positions(held_out.positions[skip:skip + n, -1], frame)
    _, idx = cKDTree(robot.frame_positions(data.positions[:, -1], frame)).query(targets)
    return targets, data.positions[idx], np.asarray(idx)


def main(args: argparse.Namespace) -> int:
    from genplan.seq2seq.adjust import START_SPREAD, adjust, aim_inputs, clear_ends
    from genplan.seq2seq.data import read_trajectories
    from genplan.seq2seq.model import load_model

    model = load_model(args.model)
    data = read_trajectories(args.data)
    held_out = read_trajectories(args.held_out)
    if held_out.sha256 == data.sha256:
        raise A.UsageError("--held-out: give trajectories the model was not trained on (another seed)")
    res_ctx = adjust(model, data.positions[:1], objective(data.source.get("frame") or "hand"),
                     targets={"end_position": np.zeros((1, 3))}, updates=0, scene=data.scene)
    robot, task, scene = res_ctx.context.robot, res_ctx.context.task, res_ctx.context.scene
    frame = data.source.get("frame") or "hand"
    targets, x_in, idx = problems(data, held_out, robot, frame, args.problems, args.skip)
    rows: dict[str, Any] = {}

    if set(args.rows) & {"latent", "direct", "replanning", "promp"}:
        # latent adjustment + finish
        t0 = time.perf_counter()
        lat = adjust(model, x_in, objective(frame), targets={"end_position": targets}, updates=args.updates, scene=scene)
        t_adjust = time.perf_counter() - t0
        t0 = time.perf_counter()
        fin = lat.finish()
        t_finish = time.perf_counter() - t0
        rows["latent"] = _finish_row(fin, (t_adjust + t_finish) / args.problems, args.updates)
        rows["latent"].update(adjust_ms_per_problem=1e3 * t_adjust / args.problems,
                              finish_ms_per_problem=1e3 * t_finish / args.problems, finish_stages_s=fin.seconds,
                              failure_reasons=_reasons(fin.reasons))
        _say("latent", rows["latent"])

        if "direct" in args.rows:
            # direct optimisation of the same objective from the same starts
            t0 = time.perf_counter()
            dire = adjust(model, x_in, objective(frame), targets={"end_position": targets}, method="direct",
                          updates=args.direct_updates, scene=scene)
            t_direct = time.perf_counter() - t0
            level = lat.objective_history[-1]
            reach = np.array([np.argmax(dire.objective_history[:, i] <= level[i]) if (dire.objective_history[:, i] <= level[i]).any()
                              else -1 for i in range(args.problems)])
            reached = reach >= 0
            rows["direct"] = {
                "updates": args.direct_updates, "reached_latent_level_percent": 100.0 * float(reached.mean()),
                "median_updates_to_latent_level": float(np.median(reach[reached])) if reached.any() else None,
                "update_ratio_to_latent": (float(np.median(reach[reached])) / args.updates) if reached.any() else None,
                "ms_per_update_per_problem": 1e3 * t_direct / args.direct_updates / args.problems,
                "latent_ms_per_update_per_problem": 1e3 * t_adjust / args.updates / args.problems,
                "median_objective_final": float(np.median(dire.objective_history[-1])),
                "latent_median_objective_final": float(np.median(level)),
            }

            _say("direct", rows["direct"])

        if "replanning" in args.rows:
            # replanning from scratch to the goal the latent method reached
            rows["replanning"] = _replan(robot, task, scene, x_in, fin, args.replan)
            _say("replanning", rows["replanning"])

        if "promp" in args.rows and not args.no_promp:
            # ProMP on the same data, conditioned on the same start and goal configurations
            rows["promp"] = _promp(data, robot, task, scene, x_in, fin, frame, targets)
            _say("promp", rows["promp"])

    if "obstacle" in args.rows:
        # a new obstacle on each original path at mid-time
        mid = robot.frame_positions(x_in[:, x_in.shape[1] // 2], frame)
        spheres = np.concatenate([mid, np.full((args.problems, 1), args.obstacle_radius)], 1)[:, None, :]
        own_end = robot.frame_positions(x_in[:, -1], frame)
        worlds = []
        for i in range(args.problems):
            w = robot.collision_world()
            if scene is not None:
                w.add_scene(scene)
            w.add_sphere("obstacle", args.obstacle_radius, mid[i])
            worlds.append(w)
        t0 = time.perf_counter()
        # an input whose last configuration is in the sphere cannot keep it: it is bent towards a clear
        # configuration with the frame at the same end position, and the adjustment starts from that
        ends = clear_ends(robot, x_in[:, -1], worlds, frame, task=task)
        t_clear_ends = time.perf_counter() - t0
        obs = adjust(model, aim_inputs(x_in, ends.q), objective(frame, obstacle=True),
                     targets={"end_position": own_end, "avoid_spheres": spheres},
                     updates=args.obstacle_updates, step="adam", lr=OBSTACLE_LR, scene=scene, starts=args.obstacle_starts,
                     pool=data.positions if args.obstacle_pool == "data" and args.obstacle_starts > 1 else None,
                     **({} if args.obstacle_start_spread is None else {"start_spread": args.obstacle_start_spread}))
        t_obs_adjust = time.perf_counter() - t0 - t_clear_ends
        obs_spread = START_SPREAD if args.obstacle_start_spread is None else args.obstacle_start_spread
        fin_obs = obs.finish(world=worlds)
        t_obs = time.perf_counter() - t0
        inputs_hit = sum(bool(np.any(worlds[i].in_collision(x_in[i]))) for i in range(args.problems))
        # a start in the sphere (another link than the frame passing through it) leaves no motion clear of it
        starts_hit = np.array([bool(worlds[i].in_collision(x_in[i, 0])) for i in range(args.problems)])
        ends_hit = np.array([bool(worlds[i].in_collision(x_in[i, -1])) for i in range(args.problems)])
        free = ~starts_hit & ~ends_hit
        rows["obstacle"] = _finish_row(fin_obs, t_obs / args.problems, args.obstacle_updates)
        rows["obstacle"].update(radius_m=args.obstacle_radius, inputs_in_collision_percent=100.0 * inputs_hit / args.problems,
                                starts_in_collision_percent=100.0 * float(starts_hit.mean()),
                                ends_in_collision_percent=100.0 * float(ends_hit.mean()),
                                free_problems=int(free.sum()),
                                free_success_percent=100.0 * float(fin_obs.success[free].mean()) if free.any() else float("nan"),
                                ends_reaimed=int(ends.found.sum()), ends_without_clear_configuration=int((ends.blocked & ~ends.found).sum()),
                                reaimed_success_percent=(100.0 * float(fin_obs.success[ends.found].mean()) if ends.found.any()
                                                         else float("nan")),
                                median_end_move_rad=float(np.median(ends.moved[ends.found])) if ends.found.any() else float("nan"),
                                clear_ends_ms_per_problem=1e3 * t_clear_ends / args.problems,
                                starts=args.obstacle_starts, start_spread=obs_spread, pool=args.obstacle_pool,
                                restarted_problems=int((obs.starts_run > 1).sum()),
                                success_from_restart=int((fin_obs.success & (fin_obs.start_index > 0)).sum()),
                                starts_run_mean=float(obs.starts_run.mean()),
                                adjust_ms_per_problem=1e3 * t_obs_adjust / args.problems, finish_stages_s=fin_obs.seconds,
                                failure_reasons=_reasons(fin_obs.reasons))
        _say("obstacle", rows["obstacle"])

    print(table(["row", "success %", "end error mm (max)", "residual / tol (max)", "ms / problem"],
                [[k, f"{r.get('success_percent', float('nan')):.1f}", f"{r.get('max_end_error_mm', float('nan')):.3f}",
                  f"{r.get('max_residual_ratio', float('nan')):.3g}", f"{r.get('ms_per_problem', float('nan')):.1f}"]
                 for k, r in rows.items() if "success_percent" in r]))
    if "obstacle" in rows:
        o = rows["obstacle"]
        print(f"obstacle: {o['success_percent']:.1f} % of all {args.problems} problems, {o['free_success_percent']:.1f} % of the "
              f"{o['free_problems']} whose input starts and ends clear of the sphere; {o['ends_reaimed']} inputs ending in it "
              f"re-aimed at a clear end ({o['reaimed_success_percent']:.1f} % of them succeed)")
    if "direct" in rows:
        d = rows["direct"]
        print(f"direct: {d['reached_latent_level_percent']:.0f} % reach the latent's objective level, median "
              f"{d['median_updates_to_latent_level']} updates ({d['update_ratio_to_latent']}x the latent's {args.updates})")
    out = {"benchmark": "adapt", "machine": machine(), "args": {k: str(v) for k, v in vars(args).items() if k != "func"},
           "model": {"path": str(args.model), "weights_sha256": model.card.get("weights_sha256"),
                     "config": model.config.to_dict(), "training_seconds": model.card.get("training", {}).get("seconds")},
           "data": {"folder": str(args.data), "trajectories": len(data), "sha256": data.sha256},
           "held_out": {"folder": str(args.held_out), "sha256": held_out.sha256, "seed": held_out.source.get("seed")},
           "targets": TARGETS, "rows": rows,
           # the 1/5/15-minute load when the rows were done: times on a shared machine read against it
           "load_average": list(os.getloadavg())}
    if args.out is not None:
        write_json(args.out, out)
        print(f"wrote {args.out}")
    return 0


def _say(name: str, row: dict[str, Any]) -> None:
    """One row as it is measured (the whole table is printed at the end)."""
    brief = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items() if not isinstance(v, dict)}
    print(f"{name}: {brief}", flush=True)


def _reasons(reasons: list[str | None]) -> dict[str, int]:
    """How many problems failed for each kind of reason (the reason's text with each number as N;
    a timing failure by its first clause)."""
    out: dict[str, int] = {}
    for r in reasons:
        if r is not None:
            key = r.split(":")[0] if r.startswith("timing") else re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "N", r).strip()
            out[key] = out.get(key, 0) + 1
    return out


def _finish_row(fin: Any, seconds_per_problem: float, updates: int) -> dict[str, Any]:
    ok = fin.success
    end = fin.end_error_m[ok] * 1e3
    return {"problems": fin.batch, "updates": updates, "success_percent": 100.0 * float(ok.mean()),
            "max_end_error_mm": float(end.max()) if ok.any() else float("nan"),
            "median_end_error_mm": float(np.median(end)) if ok.any() else float("nan"),
            "max_residual_ratio": float(np.nanmax(fin.max_residual_ratio)) if ok.any() else float("nan"),
            "ms_per_problem": 1e3 * seconds_per_problem}


def _replan(robot: Any, task: Any, scene: Any, x_in: np.ndarray, fin: Any, n: int) -> dict[str, Any]:
    from genplan.planning import Planner, PlannerSettings

    world = robot.collision_world()
    if scene is not None:
        world.add_scene(scene)
    planner = Planner(robot, world, task, sampler="uniform",
                      settings=PlannerSettings(algorithm="rrt_connect", simplify=True, max_extensions=2000))
    done = [i for i in range(len(x_in)) if fin.success[i]][:n]
    ok, times = 0, []
    for i in done:
        t0 = time.perf_counter()
        res = planner.plan(x_in[i, 0], fin.paths[i][-1][None])
        if res.success:
            try:
                res.trajectory()
                ok += 1
            except Exception:  # a plan whose trajectory fails its check is a failure here
                pass
        times.append(time.perf_counter() - t0)
    return {"problems": len(done), "success_percent": 100.0 * ok / max(len(done), 1),
            "ms_per_problem": 1e3 * float(np.mean(times)) if times else float("nan"),
            "median_ms": 1e3 * float(np.median(times)) if times else float("nan")}


def _promp(data: Any, robot: Any, task: Any, scene: Any, x_in: np.ndarray, fin: Any, frame: str,
           targets: np.ndarray) -> dict[str, Any]:
    try:
        from movement_primitives.promp import ProMP
    except ImportError:
        return {"skipped": "movement-primitives is not installed (pip install movement-primitives)"}
    from genplan.projection import GaussNewtonProjector, SolverSettings, Task
    from genplan.seq2seq.finish import DEFAULT_RESOLUTION, densify
    from genplan.seq2seq.objectives import constraint_terms

    k = data.K
    ts = np.linspace(0.0, 1.0, k)
    t0 = time.perf_counter()
    promp = ProMP(n_dims=robot.nq, n_weights_per_dim=20)
    demos = np.random.default_rng(0).permutation(len(data))[:PROMP_DEMONSTRATIONS]
    promp.imitate(np.tile(ts, (len(demos), 1)), data.positions[demos], n_iter=PROMP_ITERATIONS)
    t_train = time.perf_counter() - t0
    terms = constraint_terms(task, robot)
    check = GaussNewtonProjector(robot, Task(primary=terms, name="check"),
                                 SolverSettings(max_iterations=0, clip_to_limits=False))
    tol = {t.label(): float(t.tolerance) for t in terms}
    world = robot.collision_world()
    if scene is not None:
        world.add_scene(scene)
    ratios, gen_ratios, ends, ok, times = [], [], [], 0, []
    done = [i for i in range(len(x_in)) if fin.success[i]]
    for i in done:
        goal = fin.paths[i][-1]
        t0 = time.perf_counter()
        cond = promp.condition_position(x_in[i, 0], y_cov=np.eye(robot.nq) * 1e-10, t=0.0, t_max=1.0)
        cond = cond.condition_position(goal, y_cov=np.eye(robot.nq) * 1e-10, t=1.0, t_max=1.0)
        q = cond.mean_trajectory(ts)
        times.append(time.perf_counter() - t0)
        dense, _ = densify(q, DEFAULT_RESOLUTION)
        res = check.solve_batch(dense).residuals
        ratio = max(float(np.max(v)) / tol[name] for name, v in res.items())
        end = float(np.linalg.norm(robot.frame_positions(q[-1:], frame)[0] - targets[i]))
        free = not np.any(world.in_collision(dense))
        lo, hi = np.asarray(robot.lower), np.asarray(robot.upper)
        within = bool(np.all((dense >= lo) & (dense <= hi)))
        ratios.append(ratio)
        gen_ratios.append(float(fin.max_residual_ratio[i]))
        ends.append(end)
        ok += int(ratio <= 1.0 and end <= 1e-3 and free and within)
    return {"problems": len(done), "success_percent": 100.0 * ok / max(len(done), 1),
            "max_end_error_mm": 1e3 * float(np.max(ends)) if ends else float("nan"),
            "max_residual_ratio": float(np.max(ratios)) if ratios else float("nan"),
            "median_residual_ratio": float(np.median(ratios)) if ratios else float("nan"),
            "genplan_median_residual_ratio": float(np.median(gen_ratios)) if gen_ratios else float("nan"),
            "residual_ratio_genplan_over_promp": (float(np.max(gen_ratios)) / float(np.max(ratios))) if ratios else None,
            "ms_per_problem": 1e3 * float(np.mean(times)) if times else float("nan"), "train_seconds": t_train,
            "weights_per_dim": 20, "em_iterations": PROMP_ITERATIONS, "demonstrations": int(len(demos))}
