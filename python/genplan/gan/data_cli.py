"""``genplan data``: a GAN's training set (configurations on a task's manifold) as a folder of
shards and a manifest.json (:func:`genplan.gan.data.write_dataset`), on the local cores or on Ray.

    genplan data --robot panda --data-size 200000 --out data/panda            # every local core
    genplan data --robot talos --data-size 10000000 --out data/talos --ray ray://head:10001
    genplan train gan --robot panda --data data/panda --out models/p.safetensors

The data set depends on the robot, the task, --data-size, --seed and --shard-size only: the same
bit for bit with any --workers or --ray. Rerunning a command that was interrupted (or whose
shards failed) keeps the shards it finished (checked by their sha256) and computes the rest.
"""

from __future__ import annotations

import argparse

from genplan import _cli_args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.gan.data import SHARD_SIZE

    A.add_robot_and_task(p, "the robot's shipped <robot>_ik (the data lie on the task's manifold)")
    p.add_argument("--data-size", type=A.positive_int, required=True, help="configurations in the data set")
    p.add_argument("--out", type=A.output_folder, required=True,
                   help="the data set's folder (created; a folder of the same run is resumed)")
    p.add_argument("--seed", type=A.seed, default=0, help="the data set's seed (default 0)")
    p.add_argument("--shard-size", type=A.positive_int, default=SHARD_SIZE,
                   help=f"configurations per shard (default {SHARD_SIZE})")
    A.add_executor_arguments(p, "local workers (threads, one core each; default: every core), or Ray CPUs "
                                "with --ray auto")


def main(args: argparse.Namespace) -> int:
    from genplan import projection as P
    from genplan.executor import executor
    from genplan.gan.data import write_dataset
    from genplan.robots import load

    robot = load(args.robot)
    task = None if args.task is None else P.load_task(args.task, robot)
    with executor(args.workers, args.ray) as ex:
        m = write_dataset(args.out, robot, args.data_size, args.seed, task, shard_size=args.shard_size, executor=ex)
    run = m["last_run"]
    rate = ""
    if run["shards_computed"] == m["shards_total"]:  # a fresh run: its rate
        rate = f", {m['data_size'] / max(run['seconds'], 1e-9):.0f} configurations/s"
    print(f"{args.out}: {m['data_size']} configurations of {robot.name} on '{m['manifold']['name']}' in "
          f"{m['shards_total']} shards ({run['shards_computed']} computed in {run['seconds']:.1f} s on "
          f"{run['executor']} x{run['workers']}{rate})")
    print(f"sha256 {m['sha256']}")
    return 0
