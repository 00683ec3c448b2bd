"""``genplan plan``: one plan for any robot, task and scene (genplan.planning.plan): in free
space by default, or on a task's constraint manifold.

    genplan plan --robot panda --scene panda_shelf --goal "0 -0.3 0 -2.2 0 2 0.8" --out plan.json

    genplan plan --robot examples/xarm7/xarm7.toml --task examples/xarm7/upright_cup.toml \\
        --scene examples/xarm7/table_box.toml --start default --target 0.4 -0.3 0.3 \\
        --sampler gan --model cup.safetensors --out plan.json --html plan.html

Without ``--task`` the plan is in free space (the shipped ``free`` task: the joint limits alone,
nothing projected; the start and goal must be within the limits as they are), by RRT-Connect with
the path simplified (genplan.planning.FREE_SPACE_SETTINGS; ``--algorithm crrt``, ``--no-simplify``
change them). With a task, the
start (``default`` or nq numbers) is projected onto its manifold, or found by IK for
``--start-target`` (as the goals for ``--target``). The goal is a configuration
(``--goal``, nq numbers) or IK solutions for ``--target``: X Y Z, a target of the task's
condition, or a pose of ``--frame`` (X Y Z QX QY QZ QW; or X Y Z, its position alone). The JSON
holds the query, the path and the planner's statistics; the HTML view draws the robot, the scene
and the trail of the target's frame (or the task's condition frame). ``--trajectory
F.npz|.json|.csv`` writes the path time-parameterised at 1 kHz (``PlanResult.trajectory``), which
the HTML view then plays in real time; a trajectory that fails its check (a sample in collision,
off the manifold, ...) is not written, the first bad sample is named and the exit status is 3. ``--edge-check certified`` certifies every motion between
the path's states collision-free, not only the states (PlannerSettings.edge_check).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from genplan.cli import args as A


def _numbers(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by spaces or commas, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("expected numbers, got none")
    return values


def _start(text: str) -> str | list[float]:
    return "default" if text == "default" else _numbers(text)


class _Target(argparse.Action):
    """``--target`` (``--start-target``): 3 numbers (a position) or 7 (a position and a
    quaternion), else a usage error naming the option."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        if len(values) not in (3, 7):
            parser.error(f"argument {option_string}: expected 3 numbers (X Y Z) or 7 (X Y Z QX QY QZ QW), "
                         f"got {len(values)}")
        setattr(namespace, self.dest, values)


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.planning import ALGORITHMS, EDGE_CHECKS, SAMPLERS

    A.add_robot_and_task(p, "free (free space: the joint limits alone, nothing projected)")
    A.add_allow_python(p)
    p.add_argument("--scene", default=None, help="obstacles: a shipped scene's name or a scene file (.toml)")
    start = p.add_mutually_exclusive_group()
    start.add_argument("--start", type=_start, default="default",
                       help="'default' (the robot's default configuration) or nq numbers; projected onto the manifold")
    start.add_argument("--start-target", type=float, nargs="+", metavar="X", default=None, action=_Target,
                       help="a start by IK instead, as --target finds goals: X Y Z (a target of the task's condition, "
                            "or a position of --frame) or X Y Z QX QY QZ QW (a pose of --frame)")
    goal = p.add_mutually_exclusive_group(required=True)
    goal.add_argument("--goal", type=_numbers, default=None, help="a goal configuration (nq numbers)")
    goal.add_argument("--target", type=float, nargs="+", metavar="X", default=None, action=_Target,
                      help="goals by IK: X Y Z, a target of the task's condition term (or a position of --frame); "
                           "X Y Z QX QY QZ QW, a pose of --frame")
    p.add_argument("--frame", default=None,
                   help="the frame --target places (a frame role such as 'hand', or a link); default: the task's "
                        "condition frame (a task without a [condition], such as free, needs it)")
    p.add_argument("--goals", type=A.positive_int, default=10, help="IK goals for --target (default 10)")
    p.add_argument("--sampler", choices=SAMPLERS, default="uniform")
    p.add_argument("--algorithm", choices=ALGORITHMS, default=None,
                   help="crrt: the GAN paper's constrained RRT (the default on a task's manifold); rrt_connect: "
                        "bidirectional RRT-Connect (the default in free space, where the other free-space "
                        "defaults of genplan.planning.FREE_SPACE_SETTINGS stay whichever is chosen)")
    p.add_argument("--edge-check", choices=EDGE_CHECKS, default="sampled",
                   help="sampled: edge states checked 0.025 rad apart (default); certified: every motion between "
                        "them certified collision-free as well (PlannerSettings.edge_check; slower)")
    p.add_argument("--model", type=A.existing_file, default=None, help="the learned sampler's file (a GAN or a flow) for --sampler gan, hybrid or adaptive")
    p.add_argument("--simplify", action=argparse.BooleanOptionalAction, default=None,
                   help="shorten the path: shortcuts (and, in free space, B-spline smoothing) between checked states "
                        "(default: on in free space, off on a task's manifold)")
    p.add_argument("--time-limit", type=A.non_negative_float, default=0.0, metavar="S",
                   help="seconds the search may take (PlannerSettings.time_limit; default 0: no limit but the "
                        "iteration budget); a plan out of time is reported as not found (exit status 3)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--out", type=A.output_file, required=True, help="the plan as JSON")
    p.add_argument("--html", type=A.output_file, default=None,
                   help="a self-contained HTML view of the plan (needs the viewer extra: pip install genplan[viewer])")
    p.add_argument("--trajectory", type=A.output_file, default=None,
                   help="the path as a time-optimal trajectory at 1 kHz (TOPP-RA; .npz, .json or .csv by suffix); "
                        "with --html, the view plays it in real time")


def main(args: argparse.Namespace) -> int:
    from genplan._files import write_text
    from genplan.errors import InvalidTrajectoryError
    from genplan import projection as P
    from genplan.planning import default_settings, plan
    from genplan.planning.queries import query_manifold
    from genplan.robots import load

    if args.trajectory is not None and args.trajectory.suffix.lower() not in (".npz", ".json", ".csv"):
        raise A.UsageError(f"--trajectory {args.trajectory}: expected a .npz, .json or .csv file")
    robot = load(args.robot)
    # the file's python terms imported only on request
    task = P.load_task("free" if args.task is None else args.task, robot,
                       allow_python=bool(args.allow_python and args.task is not None))
    # the defaults of free space (RRT-Connect, simplified) or of the constrained planner, by the
    # manifold plan() plans on (as Planner chooses them), with the options given
    changes: dict[str, Any] = {"edge_check": args.edge_check, "time_limit": args.time_limit}
    if args.simplify is not None:
        changes["simplify"] = args.simplify
    settings = default_settings(query_manifold(task, robot).free).replace(**changes)
    outcome = plan(robot, task, args.scene, start=args.start,
                   goal=args.goal, target=args.target, frame=args.frame, sampler=args.sampler, model=args.model,
                   k=args.goals, seed=args.seed, algorithm=args.algorithm, settings=settings,
                   start_target=args.start_target)
    r = outcome.result
    write_text(args.out, json.dumps(outcome.to_dict(), indent=1) + "\n")
    found = "found" if r.success else "no path found within --time-limit" if r.stats.timed_out else "no path found"
    print(f"{found}: {len(r.path)} states, {r.stats.extensions} extensions, "
          f"{r.time_s * 1e3:.1f} ms ({outcome.algorithm}, {args.sampler} sampler, {args.edge_check} edges); wrote {args.out}")
    traj = None
    if args.trajectory is not None:
        if not r.success:
            print("no path: no trajectory written")
            return A.FAILED
        try:
            traj = r.trajectory()
        except InvalidTrajectoryError as e:  # a path found, but its timed samples fail their check
            print(f"{e}; no trajectory written")
            return A.FAILED
        traj.save(args.trajectory)
        print(f"trajectory: {traj.duration:.3f} s at {traj.rate_hz:g} Hz, max velocity ratio {traj.max_velocity_ratio:.3f}, "
              f"max residual ratio {traj.max_residual_ratio:.3f}, parameterised in "
              f"{traj.stats['parameterisation_s'] * 1e3:.1f} ms; wrote {args.trajectory}")
    if args.html is not None:
        if not r.success:
            print("no path: no HTML view written")
            return A.FAILED
        from genplan.viewer import export_html

        export_html(outcome.robot, r.path if traj is None else traj, args.html, scene=outcome.scene,
                    trail_frame=outcome.trail_frame,
                    title=f"genplan plan: {outcome.robot.name}, task {outcome.task.name}, {args.sampler} sampler")
        print(f"wrote {args.html}")
    return 0 if r.success else A.FAILED
