"""``genplan train gan``: train the conditional ensemble GAN for a robot and task, evaluate it on
held-out targets (:mod:`genplan.samplers.evaluate`) and write the model and its card.

    genplan train gan --robot panda --seed 0 --out panda_gan.safetensors   # the paper's (as shipped)
    genplan train gan --robot my_robot.toml --task my_task.toml --out my_gan.safetensors
    genplan train gan --robot panda --data data/panda --out m.safetensors   # a `genplan data` set
    genplan train gan --robot panda --seeds 0..3 --out m.safetensors        # m_seed0 ... m_seed3
    genplan train gan --robot panda --task t.toml --allow-python --out m.safetensors  # t.toml's python terms

With ``--seeds`` one model is trained per seed (the same data set), written with the seed in its
name. They run one after the other unless ``--workers K`` asks for K processes (or ``--ray``):
on a shared 2-core machine two trainings at once were not reliably faster than one after the
other (docs/BENCHMARKS.md, "Scaling out").
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from genplan.cli import args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    A.add_robot_and_task(p, "the robot's shipped <robot>_ik")
    A.add_allow_python(p)
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (torch and numpy)")
    p.add_argument("--seeds", type=A.seed_range, default=None, metavar="A..B",
                   help="train one model per seed A..B (both included); outputs named <out>_seed<S>")
    p.add_argument("--iterations", type=A.positive_int, default=None, help="generator steps (default: the paper's 10,000)")
    p.add_argument("--n-net", type=A.positive_int, default=None,
                   help="ensemble size (default: 10 for up to 12 configuration features, else 5)")
    p.add_argument("--no-discriminator", action="store_true", help="train on the costs only (ablation)")
    p.add_argument("--loss", choices=["bce", "wgan_gp"], default=None,
                   help="adversarial loss (default bce, the paper's; wgan_gp: Wasserstein critic with gradient penalty)")
    p.add_argument("--w-diversity", type=A.non_negative_float, default=None,
                   help="weight of the mode-seeking term against noise-ignoring members (default 0: off)")
    p.add_argument("--member-init", choices=["uniform", "data"], default=None,
                   help="ensemble initialisation (default uniform; data: output biases at data points far apart)")
    p.add_argument("--data-size", type=A.positive_int, default=None, help="valid configurations (default 25,000)")
    p.add_argument("--data-in-box", type=A.share, default=None, metavar="SHARE",
                   help="share of the generated configurations drawn with the condition frame in the task's "
                        "[condition] box, where the sampler is asked (default 0.5; 0 for a shipped task: the "
                        "paper's data); the card reports the share in the box")
    p.add_argument("--data", type=A.existing_folder, default=None,
                   help="train on a data set written by `genplan data` (checked: robot, task, sha256)")
    p.add_argument("--eval-targets", type=A.eval_targets, default=500,
                   help="held-out targets of the card's evaluation (default 500, at most 100,000)")
    A.add_model_out(p)
    p.add_argument("--threads", type=A.positive_int, default=None,
                   help="torch threads (default: genplan's choice for training, one -- batches of 100 gain "
                        "little from more, and on a busy machine extra threads contend and run many times "
                        "slower; $GENPLAN_TORCH_THREADS overrides it too)")
    A.add_executor_arguments(p, "with --seeds: trainings at once, each in its own process (default 1: one after "
                                "the other)")


def seed_path(out: Path, seed: int) -> Path:
    """The model path of seed ``seed`` in a ``--seeds`` run: ``<stem>_seed<S><suffix>``."""
    return out.with_name(f"{out.stem}_seed{seed}{out.suffix}")


def train_one(job: dict[str, Any]) -> str:
    """Train, evaluate and write one model (a shard of ``--seeds``; run in a worker process too)."""
    from genplan import projection as P
    from genplan.robots import load
    from genplan.samplers.costs import default_task_name
    from genplan.samplers.evaluate import evaluate, summary_line
    from genplan.samplers.gan import default_config, train

    robot = load(job["robot"])
    task = P.load_task(job["task"] if job["task"] is not None else default_task_name(robot), robot,
                       allow_python=job["allow_python"])
    cfg = default_config(robot, task, **job["overrides"])
    t0 = time.perf_counter()
    model = train(cfg, job["data"], progress=job["progress"], robot=robot, task=task, threads=job["threads"])
    model.card["command"] = job["command"]
    if job["data_set"] is not None:
        model.card["training"]["data_set"] = job["data_set"]
    model.card["evaluation"] = evaluate(model, task, n=job["eval_targets"], progress=job["progress"])
    model.card["training"]["total_seconds_including_data"] = time.perf_counter() - t0
    weights, card = model.save(job["out"])
    return (f"seed {cfg.seed}: trained in {model.card['training']['seconds']:.0f} s "
            f"({model.card['training']['total_seconds_including_data']:.0f} s with data and evaluation); "
            + summary_line(model.card["evaluation"]) + f"\nwrote {weights} and {card}")


def main(args: argparse.Namespace) -> int:
    from genplan import projection as P
    from genplan.robots import load
    from genplan.samplers.base import models_dir, train_command
    from genplan.samplers.costs import default_task_name
    from genplan.samplers.gan import default_config

    robot = load(args.robot)
    task = P.load_task(args.task if args.task is not None else default_task_name(robot), robot,
                       allow_python=args.allow_python)
    shipped = args.task is None or args.task in P.task_names()
    if args.out is None and not shipped:
        raise A.UsageError("--out: give the model's path (a task file's GAN has no shipped place)")
    out = A.model_output(args.out, models_dir() / f"{robot.name}_gan.safetensors")  # never inside the package
    if args.data is not None and args.data_size is not None:
        raise A.UsageError("--data-size: the data set given by --data fixes the size (leave --data-size out)")
    if args.data is not None and args.data_in_box is not None:
        raise A.UsageError("--data-in-box: the data set given by --data fixes its rows (leave --data-in-box out)")
    if args.seeds is None and (args.workers is not None or args.ray is not None):
        raise A.UsageError("--workers/--ray: they run the trainings of --seeds A..B in parallel; give --seeds")
    seeds = list(args.seeds) if args.seeds is not None else [args.seed]
    overrides: dict[str, Any] = {}
    if args.iterations is not None:
        overrides["iterations"] = args.iterations
    if args.n_net is not None:
        overrides["n_net"] = args.n_net
    if args.data_size is not None:
        overrides["data_size"] = args.data_size
    if args.data_in_box is not None:
        overrides["data_in_box"] = args.data_in_box
    if args.no_discriminator:
        overrides["use_discriminator"] = False
    for key in ("loss", "w_diversity", "member_init"):
        if getattr(args, key) is not None:
            overrides[key] = getattr(args, key)
    data, data_set = None, None
    if args.data is not None:
        from genplan.samplers.data import read_dataset

        data, manifest = read_dataset(args.data, robot, task)  # refuses another robot's or task's data
        overrides["data_size"] = len(data)
        overrides["data_in_box"] = 0.0  # a `genplan data` set: uniform projections
        data_set = {"folder": str(args.data), "sha256": manifest["sha256"], "data_size": len(data),
                    "seed": manifest["seed"], "shard_size": manifest["shard_size"]}
    cfg = default_config(robot, task, **overrides, seed=seeds[0])  # errors (no [condition], ...) before any work
    extra = "".join(f" --{k} {getattr(args, k.replace('-', '_'))}" for k in ("iterations", "n-net", "data-size", "data-in-box",
                                                                         "data", "loss", "w-diversity", "member-init")
                    if getattr(args, k.replace("-", "_")) is not None) + (" --no-discriminator" if args.no_discriminator else "")
    extra += " --allow-python" if task.python_terms else ""
    parallel = args.seeds is not None and (args.ray is not None or (args.workers or 1) > 1)
    outs = [out if args.seeds is None else seed_path(out, s) for s in seeds]
    A.announce_replacement(outs)
    jobs = [{"robot": args.robot, "task": args.task, "allow_python": args.allow_python,
             "overrides": {**overrides, "seed": s}, "data": data,
             "data_set": data_set, "eval_targets": args.eval_targets, "threads": args.threads,
             "progress": not parallel, "out": o, "command": train_command(args.robot, args.task, s, options=extra, out=o)}
            for s, o in zip(seeds, outs)]
    if args.seeds is None:
        print(train_one(jobs[0]))
        return 0
    if data is None:  # every training reads the same data set: made (and cached) once, here
        from genplan.samplers.data import valid_configurations

        valid_configurations(robot, cfg.data_size, cfg.data_seed, task=task)
    from genplan.executor import executor

    with executor(args.workers or 1, args.ray, kind="process" if parallel else "thread") as ex:
        lines = ex.map(train_one, jobs, desc=f"train gan ({robot.name}, seeds {seeds[0]}..{seeds[-1]})",
                       unit="model", progress=parallel)
    for line in lines:
        print(line)
    return 0
