"""``genplan data trajectories``: a family of planned trajectories of one robot (a seq2seq model's
training set) as a folder of shards and a manifest.json
(:func:`genplan.seq2seq.data.write_planned_trajectories`).

    genplan data trajectories --robot panda --task panda_projection --scene panda_shelf \\
        --count 2000 --steps 64 --out data/shelf --start-box 0.45 -0.3 0.15 0.75 0.3 0.3 \\
        --goal-box 0.45 -0.3 0.35 0.75 0.3 0.45 --spread 0.3
    genplan train seq2seq --data data/shelf --out shelf.safetensors

Each trajectory: a start and a goal configuration on the task's manifold (uniform in the joint
limits, or with --frame's position in --start-box / --goal-box), collision-free, planned
(RRT-Connect), shortcut, timed (TOPP-RA) and resampled to --steps samples; failures are counted
(the manifest's ``failures``), not kept. The data set depends on the arguments only (not on
--workers): rerunning an interrupted command keeps the shards it finished (checked by their
sha256) and computes the rest, giving the same data set bit for bit. One run writes a folder at a
time (its lock file, genplan.lock; --force takes another run's); a folder holding another data
set is refused, --overwrite replaces it.
"""

from __future__ import annotations

import argparse

from genplan.cli import args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True, help="a preset name (genplan info lists them), a robot file (.toml) or a URDF")
    p.add_argument("--task", required=True,
                   help="the task whose manifold the trajectories stay on: a shipped task's name or a task file "
                        "(.toml); its [condition], if any, is dropped")
    p.add_argument("--scene", default=None, help="a shipped scene's name or a scene file (.toml): the obstacles")
    p.add_argument("--count", type=A.positive_int, required=True, help="trajectories in the data set")
    p.add_argument("--steps", type=A.positive_int, default=64,
                   help="samples per trajectory, in normalised time (K, at least 2; default 64)")
    p.add_argument("--out", type=A.output_folder, required=True,
                   help="the data set's folder (created; a folder of the same run is resumed)")
    p.add_argument("--seed", type=A.seed, default=0, help="the data set's seed (default 0)")
    p.add_argument("--shard-size", type=A.positive_int, default=50, help="trajectories per shard (default 50)")
    for which in ("start", "goal"):
        p.add_argument(f"--{which}-box", type=float, nargs=6, default=None, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
                       help=f"the box (low corner, high corner; m) --frame lies in at the {which} (default: anywhere "
                            "on the manifold)")
    p.add_argument("--frame", default=None,
                   help="the frame the boxes bound (default: the task's condition frame, else the robot's tool)")
    p.add_argument("--spread", type=A.non_negative_float, default=None,
                   help="solve the ends from seeds around the robot's default configuration (this standard "
                        "deviation, rad), keeping one arm posture across the family (default: seeds uniform in the "
                        "joint limits)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the data set --out holds when it is another one (its manifest and shards only)")
    p.add_argument("--force", action="store_true",
                   help="take the folder's lock from another run (one on another host that is gone)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    A.add_executor_arguments(p, "local workers (threads, one core each; default: every core), or Ray CPUs "
                                "with --ray auto")


def _box(values: list[float] | None, option: str) -> list[list[float]] | None:
    if values is None:
        return None
    lo, hi = values[:3], values[3:]
    if any(v != v or abs(v) == float("inf") for v in values) or any(a > b for a, b in zip(lo, hi)):
        raise A.UsageError(f"{option}: expected X0 Y0 Z0 X1 Y1 Z1, finite, low corner <= high corner; got {values}")
    return [lo, hi]


def main(args: argparse.Namespace) -> int:
    from genplan.executor import executor
    from genplan.seq2seq.data import write_planned_trajectories

    if args.steps < 2:
        raise A.UsageError(f"--steps: at least 2 samples per trajectory, got {args.steps}")
    start_box, goal_box = _box(args.start_box, "--start-box"), _box(args.goal_box, "--goal-box")
    with executor(args.workers, args.ray) as ex:
        m = write_planned_trajectories(args.out, args.robot, args.task, args.scene, count=args.count, steps=args.steps,
                                       seed=args.seed, start_box=start_box, goal_box=goal_box, frame=args.frame,
                                       spread=args.spread, shard_size=args.shard_size, executor=ex,
                                       progress=not args.no_progress, overwrite=args.overwrite, force=args.force,
                                       names=("--count", "--shard-size"))
    run = m["last_run"]
    failures = m.get("failures", {})
    print(f"{args.out}: {m['count']} trajectories of {m['robot']['name']} on '{m['task'].get('name')}' "
          f"({m['K']} samples each) in {m['shards_total']} shards ({run['shards_computed']} computed in "
          f"{run['seconds']:.1f} s on {run['executor']} x{run['workers']}); {m.get('attempts', 0)} attempts, "
          f"failures not kept: {failures}")
    print(f"sha256 {m['sha256']}")
    return 0
