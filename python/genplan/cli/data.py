"""``genplan data configurations`` (also its former name, ``genplan data``): a learned sampler's
training set (configurations on a task's manifold) as a folder of shards and a manifest.json
(:func:`genplan.samplers.data.write_dataset`), on the local cores or on Ray.

    genplan data configurations --robot panda --data-size 200000 --out data/panda   # every local core
    genplan data --robot talos --data-size 10000000 --out data/talos --ray ray://head:10001
    genplan train gan --robot panda --data data/panda --out models/p.safetensors
    genplan data --robot panda --task t.toml --allow-python --data-size 50000 --out data/t   # python terms

A task whose terms are Python (``kind = "python"``, imported only with --allow-python) runs its
shards in worker processes rather than threads (a Python term holds the GIL), each importing the
terms by their entry.

(``genplan data trajectories`` writes a trajectory family instead: see its --help.)

The data set depends on the robot, the task, --data-size, --seed and --shard-size only: the same
bit for bit with any --workers or --ray. Rerunning a command that was interrupted (or whose
shards failed) keeps the shards it finished (checked by their sha256) and computes the rest.

One run writes a folder at a time: its lock file (genplan.lock: the run's host, pid and start)
refuses a second run, naming the first; a lock whose process is gone (this host) is taken over,
and --force takes any (a run on another host, e.g. a Ray node or a shared file system, cannot be
checked from here). A folder holding another data set (another robot, task, size, seed or shard
size) is refused; --overwrite replaces it (removing only the files genplan wrote there: the
manifest and the shards). A run that fails before its first shard leaves nothing behind.
"""

from __future__ import annotations

import argparse
import os

from genplan.cli import args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.samplers.data import MAX_SHARDS, SHARD_SIZE

    A.add_robot_and_task(p, "the robot's shipped <robot>_ik (the data lie on the task's manifold)")
    A.add_allow_python(p)
    p.add_argument("--data-size", type=A.positive_int, required=True,
                   help="configurations in the data set: at most what the free space of --out holds (nq x 8 bytes "
                        "each), checked before any work")
    p.add_argument("--out", type=A.output_folder, required=True,
                   help="the data set's folder (created; a folder of the same run is resumed)")
    p.add_argument("--seed", type=A.seed, default=0, help="the data set's seed (default 0)")
    p.add_argument("--shard-size", type=A.positive_int, default=SHARD_SIZE,
                   help=f"configurations per shard (default {SHARD_SIZE}): at most {MAX_SHARDS} shards, and a shard "
                        "per local worker (twice its nq x 8 bytes per configuration) within the available memory")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the data set --out holds when it is another one (its manifest and shards only)")
    p.add_argument("--force", action="store_true",
                   help="take the folder's lock from another run (one on another host that is gone)")
    A.add_executor_arguments(p, "local workers (threads, one core each, or processes for a task with python "
                                "terms; default: every core), or Ray CPUs with --ray auto")


def main(args: argparse.Namespace) -> int:
    from genplan import projection as P
    from genplan.executor import executor
    from genplan.robots import load
    from genplan.samplers.data import check_data_size, executor_kind, write_dataset

    robot = load(args.robot)
    task = None if args.task is None else P.load_task(args.task, robot, allow_python=args.allow_python)
    local = 1 if args.ray is not None else (args.workers or os.cpu_count() or 1)  # shards held here at once
    check_data_size(args.data_size, robot.nq, args.shard_size, out=args.out, workers=local,
                    names=("--data-size", "--shard-size"))
    with executor(args.workers, args.ray, kind=executor_kind(task)) as ex:
        m = write_dataset(args.out, robot, args.data_size, args.seed, task, shard_size=args.shard_size, executor=ex,
                          overwrite=args.overwrite, force=args.force)
    run = m["last_run"]
    rate = ""
    if run["shards_computed"] == m["shards_total"]:  # a fresh run: its rate
        rate = f", {m['data_size'] / max(run['seconds'], 1e-9):.0f} configurations/s"
    print(f"{args.out}: {m['data_size']} configurations of {robot.name} on '{m['manifold']['name']}' in "
          f"{m['shards_total']} shards ({run['shards_computed']} computed in {run['seconds']:.1f} s on "
          f"{run['executor']} x{run['workers']}{rate})")
    print(f"sha256 {m['sha256']}")
    return 0
